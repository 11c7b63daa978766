"""Depth points: cheap SDF supervision from metric depth (no colour, no volume rendering)."""

import numpy as np
import torch

from drawer_lib.io.capture import load_capture
from drawer_lib.io.mesh import load_mesh
from drawer_lib.metrics.geometry import SurfaceDistance
from drawer_lib.paths import capture_name
from drawer_lib.sdf.config import SamplingConfig
from drawer_lib.sdf.rays import RayBank
from drawer_lib.sdf.sampling import depth_ray_samples
from drawer_lib.sdf.field import SDFField
from drawer_lib.sdf.train import depth_points_loss, init_axis


def test_depth_ray_samples_lie_in_the_band_and_in_free_space():
    g = torch.Generator().manual_seed(0)
    z = torch.tensor([0.5, 1.0, 2.0, 3.0])
    ray_len = torch.tensor([1.0, 1.2, 1.0, 1.5])  # metres per unit t
    t = depth_ray_samples(z, ray_len, 0.05, 3, 2, band=0.1, behind=0.02, gen=g)
    assert t.shape == (4, 5)
    band, free = t[:, :3], t[:, 3:]
    along = (z[:, None] - band) * ray_len[:, None]  # metres in front of the depth point
    assert torch.all(along <= 0.1 + 1e-6) and torch.all(along >= -0.02 - 1e-6)
    along_f = (z[:, None] - free) * ray_len[:, None]
    assert torch.all(free >= 0.05) and torch.all(along_f >= 0.1 - 1e-6)
    # stratified: one sample per stratum
    u = (band - (z - 0.1 / ray_len)[:, None]) / ((0.12 / ray_len)[:, None])
    assert torch.all((u * 3).floor() == torch.arange(3.0))


class _Plane:
    """s(x) = c - x_z: the plane z = c, positive towards the cameras (which look along +z)."""

    def __init__(self, c):
        self.c = c

    def __call__(self, x, dirs=None, with_grad=True):
        g = torch.tensor([0.0, 0.0, -1.0]).expand(len(x), 3)
        return self.c - x[:, 2], g if with_grad else None, None


def plane_rays(n, gen):
    """Rays from random camera centres looking along +z (camera z = world z) towards the plane
    z = 2, with their exact z-depths."""
    o = torch.rand(n, 3, generator=gen) * torch.tensor([1.0, 1.0, 0.5])
    d = torch.cat([torch.rand(n, 2, generator=gen) - 0.5, torch.ones(n, 1)], -1)
    return o, d, 2.0 - o[:, 2]


def test_depth_points_of_a_plane_give_zero_at_the_plane_and_penalise_a_shift():
    sc = SamplingConfig(depth_points=256, depth_band=3, depth_free=2)
    g = torch.Generator().manual_seed(0)
    grads = []
    rays = plane_rays(256, g)
    assert depth_points_loss(_Plane(2.0), *rays, sc, 0.06, g, grads).item() < 1e-5
    assert len(grads) == 1 and grads[0].shape == (256 * 6, 3)
    assert depth_points_loss(_Plane(2.03), *rays, sc, 0.06, g, []).item() > 0.03
    assert depth_points_loss(_Plane(1.97), *rays, sc, 0.06, g, []).item() > 0.03


def test_back_projected_depth_points_of_an_exact_capture_are_on_the_gt_surface(exact_capture):
    cap = load_capture(exact_capture[0], check_files=False)
    bank = RayBank(cap, cap.train, True, None, False, False)
    o, d, z = bank.sample_depth(2000, torch.Generator().manual_seed(0))
    assert len(z) > 1500 and torch.all(z > 0)
    gt = load_mesh(cap.root / capture_name("gt_mesh"))
    dist, _ = SurfaceDistance(gt)((o + d * z[:, None]).double().numpy())
    assert np.median(dist) < 1e-3 and np.mean(dist < 5e-3) > 0.98


def test_capsule_init_is_an_exact_distance_that_keeps_every_camera_in_free_space():
    """Cameras along a 5 m run: the capsule around their path is positive at every camera and
    |grad s0| = 1 (an exact SDF); one sphere of the same radius leaves the run's ends inside."""
    rng = np.random.default_rng(0)
    C = np.stack([np.linspace(0, 5, 40), -1.6 + 0.2 * rng.standard_normal(40), 1.4 + 0.1 * rng.standard_normal(40)], -1)
    seg = init_axis(C, "capsule")
    assert seg.shape == (2, 3) and abs(np.linalg.norm(seg[1] - seg[0]) - 5.0) < 0.2
    sph = init_axis(C, "sphere")
    np.testing.assert_allclose(sph, np.stack([C.mean(0)] * 2))
    lo, hi = torch.tensor([-2.0, -3.0, -0.5]), torch.tensor([7.0, 1.0, 3.0])
    cap = SDFField(lo, hi, torch.tensor(seg), 1.8, n_levels=2, cell_coarse=0.8, cell_fine=0.4, backend="torch").double()
    sphere = SDFField(lo, hi, torch.tensor(sph), 1.8, n_levels=2, cell_coarse=0.8, cell_fine=0.4, backend="torch").double()
    Ct = torch.tensor(C)
    assert torch.all(cap(Ct)[0] > 1.0)
    assert torch.any(sphere(Ct)[0] < 0)  # the ends of the run start inside the sphere's solid
    x = lo + torch.rand(500, 3, dtype=torch.float64) * (hi - lo)
    s, g, _ = cap(x)
    torch.testing.assert_close(g.norm(dim=-1), torch.ones(500, dtype=torch.float64))
    # s0 = radius - distance to the segment, checked against a dense sampling of the segment
    a, b = torch.tensor(seg[0]), torch.tensor(seg[1])
    pts = a + torch.linspace(0, 1, 20001, dtype=torch.float64)[:, None] * (b - a)
    dist = torch.cdist(x, pts).min(1).values
    torch.testing.assert_close(s, 1.8 - dist, rtol=0, atol=1e-3)
