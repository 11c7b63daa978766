import numpy as np
import pytest

from drawer_lib.geometry.camera import (
    Intrinsics,
    check_rigid,
    invert_rigid,
    look_at_opencv,
    opencv_to_opengl,
    opengl_to_opencv,
    project_points,
)
from drawer_lib.geometry.joints import apply_transform, joint_transform
from drawer_lib.geometry.rotations import axis_angle_to_matrix, matrix_to_quat, quat_to_matrix, rotation_angle


def random_rigid(rng, n=None):
    shape = () if n is None else (n,)
    q = rng.normal(size=shape + (4,))
    T = np.zeros(shape + (4, 4))
    T[..., :3, :3] = quat_to_matrix(q)
    T[..., :3, 3] = rng.normal(size=shape + (3,))
    T[..., 3, 3] = 1
    return T


def test_gl_cv_round_trip(rng):
    T = random_rigid(rng, 5)
    np.testing.assert_allclose(opencv_to_opengl(opengl_to_opencv(T)), T, atol=1e-12)
    # the optical axis: OpenGL looks along -z, OpenCV along +z, same world direction
    np.testing.assert_allclose(opengl_to_opencv(T)[:, :3, 2], -T[:, :3, 2])
    # centres unchanged
    np.testing.assert_allclose(opengl_to_opencv(T)[:, :3, 3], T[:, :3, 3])


def test_invert_rigid(rng):
    T = random_rigid(rng, 4)
    np.testing.assert_allclose(invert_rigid(T) @ T, np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
    np.testing.assert_allclose(invert_rigid(T[0]), np.linalg.inv(T[0]), atol=1e-12)


@pytest.mark.parametrize(
    "mutate,expect",
    [
        (lambda T: T[:3, :3].__imul__(1.01), "orthonormal"),
        (lambda T: T.__setitem__((0, 3), np.nan), "non-finite"),
        (lambda T: T.__setitem__((3, 0), 1.0), "last row"),
        (lambda T: T[:3, 0].__imul__(-1), "reflection"),
    ],
)
def test_check_rigid_rejects(rng, mutate, expect):
    T = random_rigid(rng)
    assert check_rigid(T) is None
    mutate(T)
    assert expect in check_rigid(T)
    assert "shape" in check_rigid(np.eye(3))


def test_look_at_projects_target_to_principal_point():
    intr = Intrinsics.from_fovy(np.deg2rad(60), 64, 48)
    eye, tgt = np.array([0.3, -2.0, 1.4]), np.array([0.5, 0.0, 0.8])
    c2w = look_at_opencv(eye, tgt, np.array([0, 0, 1.0]))
    assert check_rigid(c2w) is None
    uv, z = project_points(tgt[None], invert_rigid(c2w), intr)
    np.testing.assert_allclose(uv[0], [32.0, 24.0], atol=1e-9)
    assert z[0] > 0
    # image "up" (-y in OpenCV) has a positive world-z component: the camera is upright
    assert -c2w[2, 1] > 0
    # x to the right: a point to the right of the target projects to larger u
    uv2, _ = project_points((tgt + [0.1, 0, 0])[None], invert_rigid(c2w), intr)
    assert uv2[0, 0] > uv[0, 0]
    with pytest.raises(ValueError, match="parallel"):
        look_at_opencv(np.zeros(3), np.array([0, 0, 1.0]), np.array([0, 0, 1.0]))
    with pytest.raises(ValueError, match="coincide"):
        look_at_opencv(np.zeros(3), np.zeros(3), np.array([0, 0, 1.0]))


def test_intrinsics_conventions():
    it = Intrinsics.from_fovy(np.deg2rad(90), 100, 80)
    assert it.fy == pytest.approx(40.0) and it.cx == 50 and it.cy == 40
    np.testing.assert_allclose(it.K_opencv()[:2, 2], [49.5, 39.5])
    s = it.scaled(0.5)
    assert (s.width, s.height, s.cx, s.fx) == (50, 40, 25.0, it.fx / 2)


def test_quaternion_round_trip_and_angle(rng):
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        q = q if q[0] >= 0 else -q
        np.testing.assert_allclose(matrix_to_quat(quat_to_matrix(q)), q, atol=1e-10)
    # rotation_angle is accurate near 0 and near pi (where arccos of the trace is not)
    for ang in (1e-7, 1e-3, 1.0, np.pi - 1e-6, np.pi):
        R = axis_angle_to_matrix(np.array([0.3, -0.5, 0.8]), ang)
        assert rotation_angle(np.eye(3), R) == pytest.approx(ang, rel=1e-6, abs=1e-12)
    with pytest.raises(ValueError):
        axis_angle_to_matrix(np.zeros(3), 1.0)


def test_joint_transform_conventions():
    # revolute about +z through (1, 0, 0): right-hand rule moves +x to +y
    T = joint_transform("revolute", np.array([1.0, 0, 0]), np.array([0, 0, 2.0]), np.pi / 2)
    np.testing.assert_allclose(apply_transform(T, np.array([[2.0, 0, 0], [1.0, 0, 5.0]])), [[1, 1, 0], [1, 0, 5]], atol=1e-12)
    T = joint_transform("prismatic", np.zeros(3), np.array([0, -3.0, 0]), 0.25)
    np.testing.assert_allclose(T[:3, 3], [0, -0.25, 0])
    np.testing.assert_allclose(joint_transform("revolute", np.ones(3), np.array([1.0, 0, 0]), 0.0), np.eye(4))
    with pytest.raises(ValueError):
        joint_transform("revolute", np.zeros(3), np.zeros(3), 1.0)
    with pytest.raises(ValueError):
        joint_transform("screw", np.zeros(3), np.ones(3), 1.0)
