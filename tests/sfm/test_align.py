import numpy as np
import pytest

from drawer_lib.geometry.camera import look_at_opencv
from drawer_lib.geometry.rotations import axis_angle_to_matrix, rotation_angle
from drawer_lib.sfm.align import Sim3, estimate_up, gravity_frame, pose_errors, umeyama


def umeyama_reference(src, dst):
    """Slow reference: minimise sum |s R x + t - y|^2 by brute force over R (scipy) then s, t."""
    from scipy.optimize import minimize
    from scipy.spatial.transform import Rotation

    def cost(rv):
        R = Rotation.from_rotvec(rv).as_matrix()
        xs, xd = src - src.mean(0), dst - dst.mean(0)
        a = xs @ R.T
        s = (a * xd).sum() / (a * a).sum()
        return ((s * a - xd) ** 2).sum()

    best = min((minimize(cost, x0, method="BFGS") for x0 in np.random.default_rng(0).normal(size=(8, 3))), key=lambda r: r.fun)
    return Rotation.from_rotvec(best.x).as_matrix()


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e4])
def test_umeyama_recovers_similarity(rng, scale):
    X = rng.normal(size=(30, 3))
    R = axis_angle_to_matrix(rng.normal(size=3), 1.2)
    t = rng.normal(size=3) * scale
    Y = scale * X @ R.T + t
    sim = umeyama(X, Y)
    assert sim.s == pytest.approx(scale, rel=1e-9)
    np.testing.assert_allclose(sim.R, R, atol=1e-9)
    np.testing.assert_allclose(sim.apply(X), Y, atol=1e-9 * scale)


def test_umeyama_matches_slow_reference_on_noisy_points(rng):
    X = rng.normal(size=(12, 3))
    R = axis_angle_to_matrix(np.array([0.2, 1.0, -0.3]), 2.0)
    Y = 0.7 * X @ R.T + 0.05 * rng.normal(size=X.shape)
    assert float(rotation_angle(umeyama(X, Y).R, umeyama_reference(X, Y))) < 1e-4


def test_umeyama_degenerate_inputs(rng):
    with pytest.raises(ValueError, match="collinear"):
        line = np.outer(np.linspace(0, 1, 10), [1.0, 2.0, 3.0])
        umeyama(line, line + 1)
    with pytest.raises(ValueError, match="coincide"):
        umeyama(np.ones((5, 3)), rng.normal(size=(5, 3)))
    with pytest.raises(ValueError, match="N>=3"):
        umeyama(np.eye(3)[:2], np.eye(3)[:2])


def _cams(rng, roll_deg=0.0, n=20):
    out = []
    for k in range(n):
        eye = np.array([np.cos(k) * 1.5, -2.0 + 0.2 * np.sin(k), 1.3 + 0.2 * np.cos(2 * k)])
        tgt = np.array([0.3 * k / n, 0.0, 0.6 + 0.8 * k / n])
        T = look_at_opencv(eye, tgt, np.array([0, 0, 1.0]))
        T[:3, :3] = T[:3, :3] @ axis_angle_to_matrix(np.array([0, 0, 1.0]), np.deg2rad(roll_deg) * rng.normal())
        out.append(T)
    return np.stack(out)


def test_estimate_up_and_gravity_frame(rng):
    c2w = _cams(rng)
    np.testing.assert_allclose(estimate_up(c2w), [0, 0, 1], atol=1e-9)
    # in an arbitrary frame, the gravity frame recovers z-up and the assumed scale
    sim = Sim3(0.37, axis_angle_to_matrix(np.array([1.0, 2.0, 0.5]), 0.9), np.array([1.0, -2.0, 3.0]))
    c2w_b = sim.apply_c2w(c2w)
    pts = sim.apply(rng.normal(size=(100, 3)) * 0.3 + [0, 0.5, 1])
    g = gravity_frame(c2w_b, pts, np.full(20, 0.37 * 2.0), 2.0)
    back = g.apply_c2w(c2w_b)
    assert g.s * sim.s == pytest.approx(1.0)
    np.testing.assert_allclose(estimate_up(back), [0, 0, 1], atol=1e-9)
    assert (back[:, :3, 2].mean(0) @ [0, 1.0, 0]) > 0  # cameras look along +y
    # with hand roll of ~1 degree the up estimate stays within a degree
    noisy = _cams(rng, roll_deg=1.0)
    assert np.rad2deg(np.arccos(estimate_up(noisy) @ [0, 0, 1])) < 1.0
    with pytest.raises(ValueError, match="depths"):
        gravity_frame(c2w, pts, np.array([np.nan, -1.0]), 2.0)


def test_pose_errors_zero_for_a_similar_copy(rng):
    c2w = _cams(rng)
    sim = Sim3(3.0, axis_angle_to_matrix(np.array([0.0, 1.0, 1.0]), 0.4), np.array([5.0, 0, 0]))
    err = pose_errors(sim.apply_c2w(c2w), c2w)
    assert err.rot_err_deg.max() < 1e-6 and err.center_err.max() < 1e-9
    assert err.sim3.s == pytest.approx(1 / 3.0)
