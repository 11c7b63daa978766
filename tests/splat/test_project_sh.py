"""Fused numba projection and SH kernels against their PyTorch references (forward, VJP under
random cotangents, gradcheck), including culled and clamped cases."""

import pytest
import torch

from drawer_lib.geometry.camera import Intrinsics
from drawer_lib.splat.project import project_gaussians, project_gaussians_fused, quat_scale_to_covar
from drawer_lib.splat.sh import sh_to_color, sh_to_color_fused


def scene(n, dtype, seed=0):
    g = torch.Generator().manual_seed(seed)
    z = torch.rand(n, generator=g) * 4 - 0.5  # some behind the camera / near plane
    x = (torch.rand(n, generator=g) * 2 - 1) * 2.0  # some off-screen (Jacobian clamped)
    y = (torch.rand(n, generator=g) * 2 - 1) * 1.5
    means = torch.stack([x, y, z], -1).to(dtype)
    quats = torch.randn(n, 4, generator=g).to(dtype)
    scales = torch.exp(torch.rand(n, 3, generator=g) * 4 - 5).to(dtype)
    return means, quats, scales


def viewmat(dtype):
    a = 0.3
    V = torch.eye(4, dtype=dtype)
    V[:3, :3] = torch.tensor([[1, 0, 0], [0, torch.cos(torch.tensor(a)), -torch.sin(torch.tensor(a))],
                              [0, torch.sin(torch.tensor(a)), torch.cos(torch.tensor(a))]], dtype=dtype)
    V[:3, 3] = torch.tensor([0.1, -0.2, 0.5], dtype=dtype)
    return V


K = Intrinsics(60.0, 64.0, 33.0, 23.5, 64, 48)


@pytest.mark.parametrize("dtype,tol", [(torch.float64, 1e-9), (torch.float32, 2e-4)])
def test_fused_projection_equals_reference(dtype, tol):
    means, quats, scales = scene(400, dtype)
    V = viewmat(dtype)
    a = [t.clone().requires_grad_(True) for t in (means, quats, scales)]
    b = [t.clone().requires_grad_(True) for t in (means, quats, scales)]
    pf = project_gaussians_fused(*a, V, K)
    pr = project_gaussians(b[0], quat_scale_to_covar(b[1], b[2]), V, K)
    assert torch.equal(pf.radii, pr.radii)
    n_vis = int((pr.radii > 0).sum())
    assert 50 < n_vis < 400  # the scene has culled and visible Gaussians
    for x, y in ((pf.means2d, pr.means2d), (pf.conics, pr.conics), (pf.depths, pr.depths)):
        torch.testing.assert_close(x, y, rtol=tol, atol=tol * float(y.detach().abs().max()))
    g = torch.Generator().manual_seed(1)
    v = [torch.randn(t.shape, generator=g, dtype=dtype) for t in (pr.means2d, pr.conics, pr.depths)]
    ga = torch.autograd.grad(sum((o * w).sum() for o, w in zip((pf.means2d, pf.conics, pf.depths), v)), a)
    gb = torch.autograd.grad(sum((o * w).sum() for o, w in zip((pr.means2d, pr.conics, pr.depths), v)), b)
    for name, x, y in zip(("means", "quats", "scales"), ga, gb):
        torch.testing.assert_close(x, y, rtol=tol * 10, atol=tol * 10 * float(y.abs().max()), msg=name)


def test_fused_projection_gradcheck():
    means, quats, scales = scene(12, torch.float64, seed=4)
    means[:, 2] = means[:, 2].abs() + 1.0
    V = viewmat(torch.float64)
    args = tuple(t.clone().requires_grad_(True) for t in (means, quats, scales))
    fn = lambda m, q, s: (lambda p: (p.means2d, p.conics, p.depths))(project_gaussians_fused(m, q, s, V, K))  # noqa: E731
    assert torch.autograd.gradcheck(fn, args, eps=1e-7, atol=1e-5, rtol=1e-4)


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("dtype,tol", [(torch.float64, 1e-10), (torch.float32, 1e-5)])
def test_fused_sh_equals_reference(degree, dtype, tol):
    g = torch.Generator().manual_seed(degree)
    coeffs = (torch.randn(300, 16, 3, generator=g) * 1.5).to(dtype)  # some colours clamp at 0
    dirs = torch.randn(300, 3, generator=g).to(dtype) * 3
    a = [coeffs.clone().requires_grad_(True), dirs.clone().requires_grad_(True)]
    b = [coeffs.clone().requires_grad_(True), dirs.clone().requires_grad_(True)]
    cf, cr = sh_to_color_fused(*a, degree), sh_to_color(*b, degree)
    assert (cr == 0).any()
    torch.testing.assert_close(cf, cr, rtol=tol, atol=tol)
    v = torch.randn(cr.shape, generator=g, dtype=dtype)
    ga = torch.autograd.grad((cf * v).sum(), a)
    gb = torch.autograd.grad((cr * v).sum(), b, allow_unused=True)  # degree 0 does not use dirs
    gb = [torch.zeros_like(t) if gr is None else gr for gr, t in zip(gb, b)]
    for x, y in zip(ga, gb):
        torch.testing.assert_close(x, y, rtol=tol * 10, atol=tol * 10)


def test_fused_sh_gradcheck():
    g = torch.Generator().manual_seed(0)
    coeffs = (torch.randn(5, 16, 3, generator=g, dtype=torch.float64) * 0.1).requires_grad_(True)
    dirs = torch.randn(5, 3, generator=g, dtype=torch.float64).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda c, d: sh_to_color_fused(c, d, 3), (coeffs, dirs), eps=1e-7, atol=1e-6)


@pytest.mark.parametrize("degree", [0, 2, 3])
def test_fused_sh_of_two_parts_equals_their_concatenation(degree):
    """dc [N, 1, 3] and rest [N, K - 1, 3] given apart (mesh-anchored training's two parameter
    groups): the same colours and gradients to the bit as of torch.cat([dc, rest], 1)."""
    g = torch.Generator().manual_seed(degree)
    dc = torch.randn(200, 1, 3, generator=g)
    rest = torch.randn(200, 15, 3, generator=g) * 0.5
    dirs = torch.randn(200, 3, generator=g)
    a = [t.clone().requires_grad_(True) for t in (dc, rest, dirs)]
    b = [t.clone().requires_grad_(True) for t in (dc, rest, dirs)]
    ca = sh_to_color_fused(a[0], a[2], degree, rest=a[1])
    cb = sh_to_color_fused(torch.cat([b[0], b[1]], 1), b[2], degree)
    assert torch.equal(ca, cb)
    v = torch.randn(ca.shape, generator=g)
    (ca * v).sum().backward()
    (cb * v).sum().backward()
    for x, y in zip(a, b):
        assert x.grad.is_contiguous() and torch.equal(x.grad, y.grad)
