"""The speed-oriented kernels against their slow references: the compositor's ellipse footprints on
thin, rotated Gaussians, its independence of the thread count, its backward from the forward
pass's contribution record, its depth sort, and the fused D-SSIM."""

import numba
import numpy as np
import pytest
import torch
from reference import composite_reference

from drawer_lib.metrics.image import ssim, ssim_target_stats
from drawer_lib.splat._raster_kernels import depth_order
from drawer_lib.splat.losses import fused_ssim
from drawer_lib.splat.rasterize import composite

W, H = 26, 19


def thin_scene(n=30, dtype=torch.float64, seed=0):
    """2D Gaussians with axis ratios up to 30 at random angles, some near the image border."""
    g = torch.Generator().manual_seed(seed)
    m = torch.stack([torch.rand(n, generator=g) * (W + 6) - 3, torch.rand(n, generator=g) * (H + 6) - 3], -1)
    s1 = torch.rand(n, generator=g) * 4 + 0.4
    s2 = s1 / (torch.rand(n, generator=g) * 29 + 1)
    th = torch.rand(n, generator=g) * 3.2
    c, s = torch.cos(th), torch.sin(th)
    R = torch.stack([torch.stack([c, -s], -1), torch.stack([s, c], -1)], -2)
    cov = R @ torch.diag_embed(torch.stack([s1, s2], -1) ** 2 + 0.3) @ R.transpose(1, 2)
    inv = torch.linalg.inv(cov)
    conics = torch.stack([inv[:, 0, 0], inv[:, 0, 1], inv[:, 1, 1]], -1)
    opac = torch.rand(n, generator=g) * 0.95 + 0.04
    colors = torch.rand(n, 3, generator=g)
    depths = torch.rand(n, generator=g) * 3 + 1
    radii = torch.full((n,), 50, dtype=torch.int32)
    return [t.to(dtype) for t in (m, conics, opac, colors, depths)], radii


@pytest.mark.parametrize("tile", [16, 7])
def test_ellipse_footprints_match_the_reference_on_thin_gaussians(tile):
    xs, radii = thin_scene()
    a = [x.clone().requires_grad_(True) for x in xs]
    b = [x.clone().requires_grad_(True) for x in xs]
    out = composite(*a, radii, W, H, tile=tile)
    ref = composite_reference(*b, radii, W, H)
    for o, r in zip((out.rgb, out.depth, out.alpha), ref):
        torch.testing.assert_close(o, r, rtol=1e-9, atol=1e-9)
    g = torch.Generator().manual_seed(1)
    v = [torch.randn(t.shape, generator=g, dtype=torch.float64) for t in ref]
    ga = torch.autograd.grad(sum((o * w).sum() for o, w in zip((out.rgb, out.depth, out.alpha), v)), a)
    gb = torch.autograd.grad(sum((o * w).sum() for o, w in zip(ref, v)), b)
    for name, x, y in zip(("means2d", "conics", "opacities", "colors", "depths"), ga, gb):
        torch.testing.assert_close(x, y, rtol=1e-8, atol=1e-8 * (float(y.abs().max()) + 1e-12), msg=name)


def test_compositor_is_bit_identical_for_any_thread_count():
    xs, radii = thin_scene(200, torch.float32, seed=2)
    res = []
    n0 = numba.get_num_threads()
    try:
        for n in sorted({1, n0}):
            numba.set_num_threads(n)
            a = [x.clone().requires_grad_(True) for x in xs]
            ab = torch.zeros(200, 2)
            out = composite(*a, radii, W, H, tile=8, absgrad=ab)
            (out.rgb.sum() + out.depth.sum() * 0.1 + out.alpha.sum()).backward()
            res.append([out.rgb, out.depth, out.alpha, ab] + [x.grad for x in a])
    finally:
        numba.set_num_threads(n0)
    for x, y in zip(res[0], res[-1]):
        assert torch.equal(x, y)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_backward_from_the_visit_record_equals_the_recomputing_backward_to_the_bit(dtype):
    """The first backward reads the forward pass's recorded exp(p) per pixel visit; a second one
    (retain_graph: the record has gone back to the pool) recomputes them: the same bits. A
    render under no_grad records nothing and gives the same image."""
    xs, radii = thin_scene(300, dtype, seed=3)
    a = [x.clone().requires_grad_(True) for x in xs]
    out = composite(*a, radii, W, H, tile=8)
    g = torch.Generator().manual_seed(4)
    v = [torch.randn(t.shape, generator=g, dtype=dtype) for t in (out.rgb, out.depth, out.alpha)]
    loss = sum((o * w).sum() for o, w in zip((out.rgb, out.depth, out.alpha), v))
    g_rec = torch.autograd.grad(loss, a, retain_graph=True)
    g_again = torch.autograd.grad(loss, a)
    for x, y in zip(g_rec, g_again):
        assert torch.equal(x, y)
    with torch.no_grad():
        out2 = composite(*a, radii, W, H, tile=8)
    for x, y in zip((out.rgb, out.depth, out.alpha), (out2.rgb, out2.depth, out2.alpha)):
        assert torch.equal(x, y)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_depth_order_is_numpys_stable_argsort(dtype):
    """The compositor's radix sort against ``np.argsort(kind="stable")``: ties, signed zeros,
    infinities, NaNs of either sign, wide and narrow ranges, empty and single inputs."""
    rng = np.random.default_rng(0)
    for n, make in ((0, None), (1, None), (5000, "narrow"), (5000, "wide"), (3000, "special")):
        if make == "narrow":
            d = (rng.random(n) * 3 + 1).astype(dtype)
        elif make == "wide":
            d = (rng.standard_normal(n) * 1e30).astype(dtype)
            d[:50] = 0.0
        elif make == "special":
            d = rng.integers(-3, 4, n).astype(dtype)
            d[::7], d[::11], d[::13], d[5], d[6] = -0.0, np.nan, -np.nan, np.inf, -np.inf
        else:
            d = rng.random(n).astype(dtype)
        vis = np.flatnonzero(rng.random(n) > 0.2)
        assert np.array_equal(depth_order(vis, d), vis[np.argsort(d[vis], kind="stable")]), (n, make)


@pytest.mark.parametrize("dtype,tol", [(torch.float64, 1e-10), (torch.float32, 1e-5)])
def test_fused_ssim_equals_the_metric(dtype, tol):
    g = torch.Generator().manual_seed(0)
    y = torch.rand(23, 31, 3, generator=g, dtype=torch.float64).to(dtype)
    x0 = (y + 0.2 * torch.randn(23, 31, 3, generator=g, dtype=torch.float64).to(dtype)).clamp(0, 1)
    stats = ssim_target_stats(y.permute(2, 0, 1)[None])
    a, b = x0.clone().requires_grad_(True), x0.clone().requires_grad_(True)
    sa = fused_ssim(a, y, stats)
    sb = ssim(b.permute(2, 0, 1)[None], y.permute(2, 0, 1)[None], y_stats=stats)[0]
    torch.testing.assert_close(sa, sb, rtol=tol, atol=tol)
    (ga,) = torch.autograd.grad(3.0 * sa, a)
    (gb,) = torch.autograd.grad(3.0 * sb, b)
    torch.testing.assert_close(ga, gb, rtol=tol * 10, atol=tol * 10 * float(gb.abs().max()))
