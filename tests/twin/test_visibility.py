"""Blend weights of Gaussians in a view (drawer_lib.twin.gaussians.blend_weights) against a slow
reference (one render per Gaussian with only its colour on), and the culling of interior
Gaussians the closed scene would show (drawer_lib.complete.pipeline.cull_visible_interiors)."""

import numpy as np
import torch

from drawer_lib.complete.pipeline import cull_visible_interiors
from drawer_lib.geometry.camera import Camera, Intrinsics
from drawer_lib.splat.render import Gaussians, render
from drawer_lib.splat.sh import C0
from drawer_lib.splat.gaussians import blend_weights, subset

W, H = 32, 24
CAM = Camera(Intrinsics(30.0, 30.0, W / 2, H / 2, W, H), np.eye(4))  # OpenCV: looks down +z


def _gaussians(means, scales, opacities, flat_z=False) -> Gaussians:
    means = torch.as_tensor(np.asarray(means, np.float64))
    n = len(means)
    s = torch.as_tensor(np.broadcast_to(np.asarray(scales, np.float64).reshape(-1, 1), (n, 3)).copy())
    if flat_z:
        s[:, 2] = 1e-4
    return Gaussians(means, torch.tensor([[1.0, 0, 0, 0]], dtype=torch.float64).repeat(n, 1), s,
                     torch.as_tensor(np.asarray(opacities, np.float64)),
                     torch.zeros(n, 1, 3, dtype=torch.float64))


def _wall(z: float, opacity: float, spacing: float = 0.05) -> Gaussians:
    """A square of flat Gaussians facing the camera at depth z, wider than the view."""
    xs = np.arange(-0.5, 0.5 + 1e-9, spacing) * z
    X, Y = np.meshgrid(xs, xs)
    means = np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], 1)
    return _gaussians(means, spacing * z * 0.8, np.full(len(means), opacity), flat_z=True)


def _concat(*gs: Gaussians) -> Gaussians:
    return Gaussians(*(torch.cat([getattr(g, k) for g in gs]) for k in ("means", "quats", "scales", "opacities", "sh")))


def _reference(g: Gaussians, i: int) -> float:
    """Gaussian i's summed weight: the red channel of a render where only it has colour 1."""
    sh = torch.full_like(g.sh, -0.5 / C0)  # colour 0
    sh[i, 0] = 0.5 / C0  # colour 1
    gi = Gaussians(g.means, g.quats, g.scales, g.opacities, sh)
    return float(render(gi, CAM, 0, None).rgb[..., 0].sum())


def test_blend_weights_match_one_render_per_gaussian():
    rng = np.random.default_rng(0)
    n = 25
    means = np.stack([rng.uniform(-0.3, 0.3, n), rng.uniform(-0.2, 0.2, n), rng.uniform(0.8, 2.0, n)], 1)
    g = _gaussians(means, rng.uniform(0.01, 0.08, n), rng.uniform(0.1, 0.99, n))
    w = blend_weights(g, CAM).numpy()
    ref = np.array([_reference(g, i) for i in range(n)])
    np.testing.assert_allclose(w, ref, rtol=1e-6, atol=1e-9)
    assert (w > 0).all()


def test_hidden_and_outside_gaussians_weigh_nothing():
    wall = _wall(1.0, 0.999)
    behind = _gaussians([[0.0, 0.0, 1.5]], 0.02, [0.9])
    beside = _gaussians([[5.0, 0.0, 1.0]], 0.02, [0.9])  # out of the view
    before = _gaussians([[0.0, 0.0, 0.6]], 0.02, [0.9])
    g = _concat(wall, behind, beside, before)
    w = blend_weights(g, CAM).numpy()[-3:]
    assert w[0] < 1e-3 and w[1] == 0.0  # the wall lets ~1e-4 through its seams
    assert w[2] > 1.0  # a few pixels' worth


def test_cull_drops_only_visible_interior_gaussians():
    wall = _wall(1.0, 0.999)
    inside = _gaussians([[0.0, 0.0, 1.3], [0.05, 0.0, 1.4]], 0.02, [0.95, 0.95])  # behind the wall: kept
    poking = _gaussians([[0.0, 0.05, 0.7]], 0.02, [0.95])  # in front of it: seen when closed
    front_like = _gaussians([[0.02, 0.0, 0.9]], 0.02, [0.95])  # visible but not an interior one: kept
    part = _concat(inside, poking)
    gauss = {"static": _concat(wall, front_like), "door_0": part}
    interior = {"static": np.zeros(len(gauss["static"].means), bool), "door_0": np.ones(3, bool)}
    kept, n = cull_visible_interiors(gauss, interior, [CAM], 0.02)
    assert n == 1
    assert len(kept["static"].means) == len(gauss["static"].means)
    torch.testing.assert_close(kept["door_0"].means, subset(part, torch.tensor([0, 1])).means)
    # no view: nothing is seen, nothing dropped
    kept, n = cull_visible_interiors(gauss, interior, [], 0.02)
    assert n == 0 and len(kept["door_0"].means) == 3
