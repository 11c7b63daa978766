"""The optional gsplat backend (``appearance.backend: gsplat``). Where CUDA is absent: a clear
error, and the adapter's device plumbing checked against a stand-in with gsplat 1.5's
``rasterization`` interface (built on the CPU renderer): outputs come back to the Gaussians'
device with their gradients, ``absgrad`` is read from ``means2d`` after backward as gsplat
stores it, per-axis radii collapse to one. With CUDA (``gpu`` marker): it matches the CPU
renderer and trains."""

import sys
import types

import numpy as np
import pytest
import torch

from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Camera, Intrinsics
from drawer_lib.splat.render import Gaussians, render

W, H = 24, 18
CAM = Camera(Intrinsics(20.0, 20.0, 12.0, 9.0, W, H), np.eye(4))


def scene(n=60, seed=0) -> Gaussians:
    g = torch.Generator().manual_seed(seed)
    means = torch.stack([torch.rand(n, generator=g) * 2 - 1, torch.rand(n, generator=g) * 1.5 - 0.75,
                         torch.rand(n, generator=g) * 3 + 2], -1)
    return Gaussians(means, torch.randn(n, 4, generator=g), torch.rand(n, 3, generator=g) * 0.3 + 0.05,
                     torch.rand(n, generator=g) * 0.9 + 0.05, torch.rand(n, 4, 3, generator=g) - 0.5)


def fake_gsplat() -> types.ModuleType:
    """gsplat 1.5's ``rasterization`` for one camera, computed by the CPU renderer; like gsplat
    it returns ``means2d`` [C, N, 2] whose ``.absgrad`` backward fills, and radii [C, N, 2]."""

    def rasterization(means, quats, scales, opacities, colors, viewmats, Ks, width, height, *, near_plane, far_plane,
                      eps2d, sh_degree, tile_size, backgrounds, render_mode, rasterize_mode, absgrad, packed):
        assert render_mode == "RGB+ED" and rasterize_mode == "classic" and absgrad and not packed
        # gsplat 1.5.3 appends the depth channel to the colours and a zero to the backgrounds
        # itself, and asserts backgrounds [C, 4] afterwards: the caller passes [C, 3]
        assert viewmats.shape == (1, 4, 4) and Ks.shape == (1, 3, 3) and backgrounds.shape == (1, 3)
        K = Ks[0].double()
        cam = Camera(Intrinsics(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), width, height),
                     viewmats[0].double().numpy())
        out = render(Gaussians(means, quats, scales, opacities, colors), cam, sh_degree, backgrounds[0, :3],
                     near_plane, far_plane, eps2d, tile_size)
        m2d = out.means2d[None]
        out.means2d.register_hook(lambda grad: setattr(m2d, "absgrad", out.absgrad[None].clone()))
        rgbd = torch.cat([out.rgb, out.depth[..., None]], -1)[None]
        return rgbd, out.alpha[None, ..., None], {"means2d": m2d, "radii": torch.stack([out.radii, out.radii], -1)[None]}

    mod = types.ModuleType("gsplat")
    mod.rasterization = rasterization
    return mod


def test_refuses_clearly_without_cuda():
    if torch.cuda.is_available():
        pytest.skip("CUDA present: see the gpu tests")
    with pytest.raises(ConfigError, match="CUDA"):
        render(scene(5), CAM, 0, backend="gsplat")


def test_adapter_plumbing_against_the_interface(monkeypatch):
    monkeypatch.setitem(sys.modules, "gsplat", fake_gsplat())
    bg = torch.tensor([0.1, 0.2, 0.3])
    sc = scene()
    leaves = [getattr(sc, k).clone().requires_grad_(True) for k in ("means", "quats", "scales", "opacities", "sh")]
    ref_leaves = [t.detach().clone().requires_grad_(True) for t in leaves]
    out = render(Gaussians(*leaves), CAM, 1, bg, backend="gsplat", device="cpu")
    ref = render(Gaussians(*ref_leaves), CAM, 1, bg)
    for a, b in ((out.rgb, ref.rgb), (out.depth, ref.depth), (out.alpha, ref.alpha)):
        assert a.device == leaves[0].device
        torch.testing.assert_close(a, b)
    assert out.radii.shape == (60,) and torch.equal(out.radii, ref.radii)
    with pytest.raises(RuntimeError, match="after backward"):
        out.absgrad_cpu()
    (out.rgb.sum() + out.depth.sum()).backward()
    (ref.rgb.sum() + ref.depth.sum()).backward()
    for a, b in zip(leaves, ref_leaves):  # gradients reach the Gaussians through the copies
        torch.testing.assert_close(a.grad, b.grad)
    assert out.absgrad_cpu().shape == (60, 2) and out.absgrad_cpu().abs().sum() > 0
    torch.testing.assert_close(out.absgrad_cpu(), ref.absgrad_cpu())


@pytest.mark.gpu
def test_gsplat_matches_the_cpu_renderer():
    pytest.importorskip("gsplat")
    g = scene(200)
    g = Gaussians(g.means, g.quats, g.scales, g.opacities, torch.rand(200, 16, 3) - 0.5)
    for bg in (None, torch.tensor([0.1, 0.2, 0.3])):
        a, b = render(g, CAM, 3, bg), render(g, CAM, 3, bg, backend="gsplat")
        assert b.rgb.device == g.means.device
        torch.testing.assert_close(b.rgb, a.rgb, rtol=1e-3, atol=1e-3)
        torch.testing.assert_close(b.depth, a.depth, rtol=1e-3, atol=1e-3)


@pytest.mark.gpu
def test_gsplat_trains_a_few_steps(exact_capture):
    pytest.importorskip("gsplat")
    import trimesh

    from drawer_lib.io.capture import load_capture
    from drawer_lib.splat.config import AppearanceConfig
    from drawer_lib.splat.strategy import MeshAnchoredStrategy
    from drawer_lib.splat.train import prepare, train_gaussians

    cap = load_capture(exact_capture[0])
    mesh = trimesh.load(exact_capture[0] / "gt" / "mesh.ply", process=False)
    cfg = AppearanceConfig(steps=6, max_faces=2000, backend="gsplat",
                           strategy=MeshAnchoredStrategy(refine_start=2, refine_every=2, refine_stop=6))
    st = train_gaussians(cap, prepare(cap, mesh, cfg), cfg, 0)
    assert st.steps == 6 and st.counts["split"] + st.counts["dup"] > 0  # absgrad reached the strategy
