"""The grid encoding (numba kernels vs the torch reference), the field's exact gradient, the
geometric initialisation, and the losses on analytic fields."""

import numpy as np
import pytest
import torch

from drawer_lib.errors import ConfigError
from drawer_lib.io.capture import load_capture
from drawer_lib.sdf import losses as L
from drawer_lib.sdf.encoding import MultiResGrid
from drawer_lib.sdf.field import SDFField
from drawer_lib.sdf.priors import make_estimator


def grid(backend, hashed=False, seed=0):
    torch.manual_seed(seed)
    g = MultiResGrid(torch.tensor([-1.0, -0.5, 0.0]), torch.tensor([1.0, 0.7, 0.9]), n_levels=4, n_features=2,
                     cell_coarse=0.5, cell_fine=0.05, log2_table=10 if hashed else 19, init_std=0.5, backend=backend)
    return g


@pytest.mark.parametrize("hashed", [False, True])
def test_numba_encoding_equals_torch_reference(hashed):
    a, b = grid("numba", hashed), grid("torch", hashed)
    b.load_state_dict(a.state_dict())
    assert bool(a.hashed.any()) == hashed
    x = torch.rand(500, 3) * torch.tensor([2.4, 1.6, 1.1]) + torch.tensor([-1.2, -0.7, -0.1])  # some outside
    fa, da = a(x, with_grad=True)
    fb, db = b(x, with_grad=True)
    torch.testing.assert_close(fa, fb, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(da, db, rtol=1e-4, atol=1e-4)
    w = torch.randn_like(fa)
    wd = torch.randn_like(da)
    ((fa * w).sum() + (da * wd).sum()).backward()
    ((fb * w).sum() + (db * wd).sum()).backward()
    # float32 sums in a different order: compare relative to the gradient's scale
    scale = float(b.table.grad.abs().max())
    torch.testing.assert_close(a.table.grad, b.table.grad, rtol=1e-4, atol=1e-5 * scale)


@pytest.mark.parametrize("size", [1024, 1000])
def test_hashed_index_is_the_hash_modulo_the_table_size(size):
    """The kernel masks power-of-two tables instead of dividing: the same index as h mod size
    (checked in Python integers), for a non-power-of-two table too."""
    from drawer_lib.sdf import _grid_kernels as K

    rng = np.random.default_rng(0)
    for cx, cy, cz in rng.integers(0, 5000, size=(200, 3)):
        h = int(cx) ^ (int(cy) * 2654435761) ^ (int(cz) * 805459861)
        assert K._index(int(cx), int(cy), int(cz), 10, 10, size, True, 7) == 7 + h % size


def test_encoding_spatial_derivative_matches_finite_differences():
    g = grid("torch").double()
    x = torch.rand(50, 3, dtype=torch.float64) * torch.tensor([1.8, 1.0, 0.8], dtype=torch.float64) + torch.tensor(
        [-0.9, -0.4, 0.05], dtype=torch.float64)
    _, d = g(x, with_grad=True)
    h = 1e-6
    for k in range(3):
        e = torch.zeros(3, dtype=torch.float64)
        e[k] = h
        fd = (g(x + e)[0] - g(x - e)[0]) / (2 * h)
        torch.testing.assert_close(d[..., k], fd, rtol=1e-5, atol=1e-5)


def test_field_gradient_is_exact_and_init_is_a_distance_field():
    torch.manual_seed(0)
    f = SDFField(torch.tensor([-2.0, -2.0, -2.0]), torch.tensor([2.0, 2.0, 2.0]), torch.zeros(3), 1.5, n_levels=3,
                 cell_coarse=0.8, cell_fine=0.2, backend="torch").double()
    x = (torch.rand(64, 3, dtype=torch.float64) - 0.5) * 3
    s, g, _ = f(x)
    # geometric init: exactly the inside-out sphere, |grad| = 1
    torch.testing.assert_close(s, 1.5 - x.norm(dim=-1), rtol=1e-9, atol=1e-12)
    torch.testing.assert_close(g.norm(dim=-1), torch.ones(64, dtype=torch.float64))
    # after perturbing every weight, the manual Jacobian still equals autograd's
    with torch.no_grad():
        for p in f.parameters():
            p.add_(torch.randn_like(p) * 0.3)
    xr = x.clone().requires_grad_(True)
    s, g, _ = f(xr)
    (auto,) = torch.autograd.grad(s.sum(), xr)
    torch.testing.assert_close(g, auto, rtol=1e-6, atol=1e-8)


def test_eikonal_is_zero_on_the_analytic_sphere_and_positive_off_it():
    x = (torch.rand(1000, 3) - 0.5) * 4
    x.requires_grad_(True)
    s = x.norm(dim=-1) - 0.7
    (g,) = torch.autograd.grad(s.sum(), x)
    assert L.eikonal(g).item() < 1e-10
    (g2,) = torch.autograd.grad((2 * (x.norm(dim=-1) - 0.7)).sum(), x)
    assert L.eikonal(g2).item() == pytest.approx(1.0, rel=1e-4)


def test_scale_shift_invariant_loss_ignores_affine_and_sees_shape():
    g = torch.Generator().manual_seed(0)
    pred = torch.rand(3, 100, generator=g) * 3 + 1
    mono = 0.3 * pred + torch.tensor([[0.1], [-2.0], [5.0]])
    assert L.scale_shift_invariant(pred, mono).item() < 1e-8
    assert L.scale_shift_invariant(pred, (pred - 2.5) ** 2).item() > 1e-3
    # a constant prediction (degenerate fit) stays finite
    assert torch.isfinite(L.scale_shift_invariant(torch.ones(2, 50), torch.rand(2, 50, generator=g)))


def test_depth_losses_without_valid_depth_are_zero_with_gradient():
    pred = torch.rand(10, requires_grad=True)
    loss = L.depth_l1(pred, torch.zeros(10))
    loss.backward()
    assert loss.item() == 0.0 and torch.all(pred.grad == 0)


def test_depth_sdf_is_zero_for_the_exact_plane_sdf():
    # rays along +z hitting the plane z = 2; s(x) = 2 - z (positive in front)
    t = torch.linspace(0.5, 2.5, 40)[None].repeat(4, 1)
    s_samples = 2.0 - t
    z = torch.full((4,), 2.0)
    loss = L.depth_sdf(torch.zeros(4), s_samples, t, z, torch.ones(4), torch.ones(4, 40), trunc=0.1)
    assert loss.item() < 1e-6
    assert L.depth_sdf(torch.zeros(4), s_samples + 0.05, t, z, torch.ones(4), torch.ones(4, 40), trunc=0.1) > 0.01


def test_model_slots_are_named_and_refuse_to_pretend(exact_capture):
    cap = load_capture(exact_capture[0], check_files=False)
    est = make_estimator("capture", cap)
    assert est.depth(0).shape == (cap.intrinsics.height, cap.intrinsics.width)
    with pytest.raises(ConfigError, match="marigold.*not available"):
        make_estimator("marigold", cap)
    with pytest.raises(ConfigError, match="unknown"):
        make_estimator("nonexistent", cap)


def test_sfm_points_become_rays_that_reach_them(exact_capture):
    """Video captures supervise depth at SfM points: each point seen by a train frame becomes a
    pixel ray whose z-depth target puts the ray's point at that pixel's line of sight."""
    from drawer_lib.sdf.rays import RayBank

    cap = load_capture(exact_capture[0], check_files=False)
    c = cap.frames[cap.train[0]].c2w[:3, 3]
    fwd = cap.frames[cap.train[0]].c2w[:3, 2]
    X = c + 1.5 * fwd + np.random.default_rng(0).normal(scale=0.2, size=(50, 3))
    bank = RayBank(cap, cap.train, False, None, False, False, X)
    o, d, z = bank.sample_sfm(200, torch.Generator().manual_seed(0))
    P = (o + d * z[:, None]).numpy()
    dist = np.min(np.linalg.norm(P[:, None] - X[None], axis=-1), axis=1)
    # pixel quantisation: the ray goes through the pixel centre, so within ~a pixel's footprint
    pix = 1.5 * 1.5 / cap.intrinsics.fx
    assert np.all(dist < 1.5 * pix), dist.max()
