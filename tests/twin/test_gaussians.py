"""Twin Gaussians: PLY round trip, rigid motion with the SH colour rotated exactly, joint motions."""

import numpy as np
import pytest
import torch
from helpers import quat_to_rot

from drawer_lib.errors import InputError
from drawer_lib.geometry.rotations import matrix_to_quat as rotmat_to_quat
from drawer_lib.geometry.rotations import quat_mul
from drawer_lib.io.parts import Axis, Front, Part, joint_motion
from drawer_lib.splat.gaussians import sh_rotation, transform
from drawer_lib.splat.ply import read_gaussian_ply, write_gaussian_ply
from drawer_lib.splat.render import Gaussians
from drawer_lib.splat.sh import sh_to_color


def random_rotation(rng):
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def gaussians(n=50, degree=3, seed=0):
    g = torch.Generator().manual_seed(seed)
    return Gaussians(torch.randn(n, 3, generator=g, dtype=torch.float64), torch.randn(n, 4, generator=g, dtype=torch.float64),
                     torch.rand(n, 3, generator=g, dtype=torch.float64) * 0.05 + 1e-3,
                     torch.rand(n, generator=g, dtype=torch.float64),
                     torch.randn(n, (degree + 1) ** 2, 3, generator=g, dtype=torch.float64) * 0.3)


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_sh_rotation_is_the_rotated_colour_function(degree):
    rng = np.random.default_rng(degree)
    for _ in range(3):
        R = random_rotation(rng)
        g = gaussians(degree=degree)
        moved = transform(g, R, np.zeros(3))
        d = torch.from_numpy(rng.standard_normal((50, 3)))
        # the moved Gaussian seen from R d has the colour the original had from d
        torch.testing.assert_close(sh_to_color(moved.sh, d @ torch.from_numpy(R).T, degree), sh_to_color(g.sh, d, degree),
                                   atol=1e-9, rtol=0)
        D = sh_rotation(R, degree)
        np.testing.assert_allclose(D @ D.T, np.eye(len(D)), atol=1e-9)  # orthogonal per band


def test_transform_moves_means_and_orientations():
    rng = np.random.default_rng(1)
    R, t = random_rotation(rng), rng.standard_normal(3)
    g = gaussians()
    m = transform(g, R, t)
    np.testing.assert_allclose(m.means.numpy(), g.means.numpy() @ R.T + t, atol=1e-12)
    for i in range(5):
        np.testing.assert_allclose(quat_to_rot(m.quats[i].numpy()), R @ quat_to_rot(g.quats[i].numpy()), atol=1e-9)
    for _ in range(20):
        Q = random_rotation(rng)
        np.testing.assert_allclose(quat_to_rot(rotmat_to_quat(Q)), Q, atol=1e-12)
    np.testing.assert_allclose(rotmat_to_quat(np.diag([1.0, -1.0, -1.0])), [0, 1, 0, 0], atol=1e-12)  # 180 deg
    e = torch.tensor([1.0, 0, 0, 0], dtype=torch.float64)
    torch.testing.assert_close(quat_mul(e.expand_as(g.quats), g.quats), g.quats)


def test_ply_round_trip(tmp_path):
    g = gaussians(degree=3)
    g = Gaussians(*(x.float() for x in (g.means, g.quats / g.quats.norm(dim=-1, keepdim=True), g.scales,
                                         g.opacities.clamp(0.01, 0.99), g.sh)))
    write_gaussian_ply(tmp_path / "g.ply", g)
    r = read_gaussian_ply(tmp_path / "g.ply")
    for k in ("means", "quats", "scales", "opacities", "sh"):
        torch.testing.assert_close(getattr(r, k), getattr(g, k), atol=2e-6, rtol=1e-5)
    (tmp_path / "bad.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nend_header\n")
    with pytest.raises(InputError, match="bad.ply"):
        read_gaussian_ply(tmp_path / "bad.ply")


def test_joint_motion_of_a_door_and_a_drawer():
    fr = Front((0.25, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.5, 0.7))
    door = Part("door_0", "revolute", Axis((0.0, -0.6, 0.5), (0.0, 0.0, -1.0)), (0.0, 1.57), fr)
    R, t = joint_motion(door, np.pi / 2)
    free_edge = np.array([0.5, -0.6, 0.5])
    np.testing.assert_allclose(R @ free_edge + t, [0.0, -1.1, 0.5], atol=1e-12)  # swung outward (-y)
    np.testing.assert_allclose(R @ np.array([0.0, -0.6, 0.9]) + t, [0.0, -0.6, 0.9], atol=1e-12)  # on the axis
    drawer = Part("drawer_0", "prismatic", Axis((0.25, -0.6, 0.5), (0.0, -2.0, 0.0)), (0.0, 0.4), fr)
    R, t = joint_motion(drawer, 0.3)
    np.testing.assert_allclose(R, np.eye(3))
    np.testing.assert_allclose(t, [0, -0.3, 0], atol=1e-12)  # a non-unit axis is normalised
    bad = Part("door_1", "revolute", Axis((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)), (0.0, 1.0), fr)
    with pytest.raises(InputError, match="door_1"):
        joint_motion(bad, 0.5)
    with pytest.raises(InputError, match="door_0"):
        joint_motion(door, float("nan"))
