"""``render``: one stateless entry point for 3D Gaussian splatting (gsplat's ``rasterization``
shape), with a CPU backend (PyTorch projection + numba compositor) and an optional gsplat
backend for CUDA users (``backend="gsplat"``)."""

from dataclasses import dataclass

import torch
from jaxtyping import Float
from torch import Tensor

from drawer_lib.errors import ConfigError
from drawer_lib.splat.project import project_gaussians, project_gaussians_fused, quat_scale_to_covar
from drawer_lib.splat.rasterize import composite
from drawer_lib.splat.sh import sh_to_color, sh_to_color_fused


@dataclass
class Gaussians:
    """Activated Gaussian parameters: means [N, 3] (m), quats [N, 4] wxyz (any norm), scales
    [N, 3] standard deviations (m), opacities [N] in [0, 1], sh [N, K, 3] colour coefficients."""

    means: Tensor
    quats: Tensor
    scales: Tensor
    opacities: Tensor
    sh: Tensor

    def __post_init__(self):
        n = self.means.shape[0]
        for name, shape in (("means", (n, 3)), ("quats", (n, 4)), ("scales", (n, 3)), ("opacities", (n,))):
            if tuple(getattr(self, name).shape) != shape:
                raise ValueError(f"Gaussians.{name}: shape {tuple(getattr(self, name).shape)}, expected {shape}")
        if self.sh.ndim != 3 or self.sh.shape[0] != n or self.sh.shape[2] != 3:
            raise ValueError(f"Gaussians.sh: shape {tuple(self.sh.shape)}, expected ({n}, K, 3)")


@dataclass(frozen=True)
class Camera:
    viewmat: Tensor  # [4, 4] OpenCV world-to-camera
    K: tuple[float, float, float, float]  # fx, fy, cx, cy (pixel centres at integer + 0.5)
    width: int
    height: int

    @property
    def center(self) -> Tensor:
        R, t = self.viewmat[:3, :3], self.viewmat[:3, 3]
        return -R.T @ t


@dataclass
class RenderOutput:
    rgb: Tensor  # [H, W, 3] with the background composited
    depth: Tensor  # [H, W] expected depth (sum w z / alpha; 0 where alpha = 0)
    alpha: Tensor  # [H, W]
    radii: Tensor  # [N] int, 0 = not rendered
    means2d: Tensor  # [N, 2] (retains grad: its .grad after backward is the 2D-mean gradient)
    absgrad: Tensor  # [N, 2] sum over pixels of |dL/dmeans2d| (filled by backward)


def render(g: Gaussians, cam: Camera, sh_degree: int, background: Float[Tensor, "3"] | None = None,
           near: float = 0.01, far: float = 1e10, eps2d: float = 0.3, tile: int = 16,
           backend: str = "cpu", fused: bool = True) -> RenderOutput:
    """Render Gaussians ``g`` from ``cam``; colours from SH of degree ``sh_degree`` evaluated
    at the direction camera -> Gaussian. ``fused``: projection and SH in numba kernels (default);
    False uses their PyTorch references (slower; also gives a gradient to ``cam.viewmat``)."""
    if backend == "gsplat":
        return _render_gsplat(g, cam, sh_degree, background, near, far, eps2d, tile)
    if backend != "cpu":
        raise ConfigError(f"splat backend {backend!r} must be cpu or gsplat")
    dirs = g.means - cam.center.to(g.means.dtype)
    if fused and not cam.viewmat.requires_grad:
        p = project_gaussians_fused(g.means, g.quats, g.scales, cam.viewmat, cam.K, cam.width, cam.height, near, far,
                                    eps2d)
        colors = sh_to_color_fused(g.sh, dirs, sh_degree)
    else:
        covars = quat_scale_to_covar(g.quats, g.scales)
        p = project_gaussians(g.means, covars, cam.viewmat, cam.K, cam.width, cam.height, near, far, eps2d)
        colors = sh_to_color(g.sh, dirs, sh_degree)
    means2d = p.means2d
    if means2d.requires_grad:
        means2d.retain_grad()
    absgrad = torch.zeros(means2d.shape, dtype=means2d.dtype)
    c = composite(means2d, p.conics, g.opacities, colors, p.depths, p.radii, cam.width, cam.height, tile, absgrad)
    rgb = c.rgb
    if background is not None:
        rgb = rgb + (1 - c.alpha)[..., None] * background.to(rgb.dtype)
    depth = torch.where(c.alpha > 0, c.depth / c.alpha.clamp_min(1e-10), torch.zeros_like(c.depth))
    return RenderOutput(rgb, depth, c.alpha, p.radii, means2d, absgrad)


def _render_gsplat(g, cam, sh_degree, background, near, far, eps2d, tile) -> RenderOutput:
    if not torch.cuda.is_available():
        raise ConfigError("splat backend gsplat needs CUDA, which this machine does not have; use backend: cpu")
    try:
        import gsplat
    except ImportError as e:
        raise ConfigError("splat backend gsplat: the gsplat package is not installed (pip install gsplat==1.5.3)") from e
    fx, fy, cx, cy = cam.K
    dev = torch.device("cuda")
    Ks = torch.tensor([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=torch.float32, device=dev)[None]
    bg = background.to(dev)[None] if background is not None else None
    colors, alphas, meta = gsplat.rasterization(
        g.means.to(dev), g.quats.to(dev), g.scales.to(dev), g.opacities.to(dev), g.sh.to(dev),
        cam.viewmat.to(dev)[None].float(), Ks, cam.width, cam.height, near_plane=near, far_plane=far, eps2d=eps2d,
        sh_degree=sh_degree, tile_size=tile, backgrounds=bg, render_mode="RGB+ED", rasterize_mode="classic",
        absgrad=True, packed=False)
    means2d = meta["means2d"]
    return RenderOutput(colors[0, ..., :3], colors[0, ..., 3], alphas[0, ..., 0], meta["radii"][0].amax(-1),
                        means2d[0] if means2d.dim() == 3 else means2d, torch.zeros(g.means.shape[0], 2, device=dev))
