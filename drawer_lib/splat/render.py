"""``render``: one stateless entry point for 3D Gaussian splatting (gsplat's ``rasterization``
shape), with a CPU backend (PyTorch projection + numba compositor) and an optional gsplat
backend for CUDA users (``backend="gsplat"``: the Gaussians are rasterized on the device and
the outputs come back to the Gaussians' device, differentiably)."""

from dataclasses import dataclass, field

import torch
from jaxtyping import Float
from torch import Tensor

from drawer_lib.devices import torch_device
from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Camera
from drawer_lib.splat.project import project_gaussians, project_gaussians_fused, quat_scale_to_covar
from drawer_lib.splat.rasterize import composite
from drawer_lib.splat.sh import sh_to_color, sh_to_color_fused

BACKENDS = ("cpu", "gsplat")


@dataclass
class Gaussians:
    """Activated Gaussian parameters: means [N, 3] (m), quats [N, 4] wxyz (any norm), scales
    [N, 3] standard deviations (m), opacities [N] in [0, 1], sh [N, K, 3] colour coefficients.
    ``sh_parts`` (optional): the tensors (dc [N, 1, 3], rest [N, K - 1, 3]) that ``sh`` is the
    concatenation of; the CPU backend's fused SH then reads them and sends their gradients to
    them directly (without forming the [N, K, 3] gradient of ``sh``)."""

    means: Tensor
    quats: Tensor
    scales: Tensor
    opacities: Tensor
    sh: Tensor
    sh_parts: tuple[Tensor, Tensor] | None = field(default=None, repr=False)

    def __post_init__(self):
        n = self.means.shape[0]
        for name, shape in (("means", (n, 3)), ("quats", (n, 4)), ("scales", (n, 3)), ("opacities", (n,))):
            if tuple(getattr(self, name).shape) != shape:
                raise ValueError(f"Gaussians.{name}: shape {tuple(getattr(self, name).shape)}, expected {shape}")
        if self.sh.ndim != 3 or self.sh.shape[0] != n or self.sh.shape[2] != 3:
            raise ValueError(f"Gaussians.sh: shape {tuple(self.sh.shape)}, expected ({n}, K, 3)")


@dataclass
class RenderOutput:
    rgb: Tensor  # [H, W, 3] with the background composited
    depth: Tensor  # [H, W] expected depth (sum w z / alpha; 0 where alpha = 0)
    alpha: Tensor  # [H, W]
    radii: Tensor  # [N] int, 0 = not rendered
    means2d: Tensor  # [N, 2] pixels (retains grad: its .grad after backward is the 2D-mean gradient)
    absgrad: Tensor | None  # [N, 2] sum over pixels of |dL/dmeans2d|, filled by backward (CPU backend)

    def absgrad_cpu(self) -> Tensor:
        """[N, 2] sum over pixels of |dL/dmeans2d| on the CPU, once backward has run (the CPU
        backend fills ``absgrad``; gsplat sets ``means2d.absgrad``)."""
        if self.absgrad is not None:
            return self.absgrad
        g = getattr(self.means2d, "absgrad", None)
        if g is None:
            raise RuntimeError("RenderOutput.absgrad_cpu: call it after backward (gsplat sets means2d.absgrad then)")
        return g.detach().reshape(-1, 2).cpu()


def render(g: Gaussians, cam: Camera, sh_degree: int, background: Float[Tensor, "3"] | None = None,
           near: float = 0.01, far: float = 1e10, eps2d: float = 0.3, tile: int = 16,
           backend: str = "cpu", fused: bool = True, device: str = "cuda") -> RenderOutput:
    """Render Gaussians ``g`` from ``cam``; colours from SH of degree ``sh_degree`` evaluated
    at the direction camera -> Gaussian. ``fused``: projection and SH in numba kernels (default);
    False uses their PyTorch references (slower, for tests). ``device``: where the gsplat
    backend rasterizes."""
    if backend == "gsplat":
        return _render_gsplat(g, cam, sh_degree, background, near, far, eps2d, tile, device)
    if backend != "cpu":
        raise ConfigError(f"splat backend {backend!r} must be one of {BACKENDS}")
    viewmat = torch.as_tensor(cam.w2c, dtype=g.means.dtype)
    intr = cam.intrinsics
    dirs = g.means - (-viewmat[:3, :3].T @ viewmat[:3, 3])  # camera centre -> Gaussian
    if fused:
        p = project_gaussians_fused(g.means, g.quats, g.scales, viewmat, intr, near, far, eps2d)
        colors = sh_to_color_fused(g.sh, dirs, sh_degree) if g.sh_parts is None else \
            sh_to_color_fused(g.sh_parts[0], dirs, sh_degree, rest=g.sh_parts[1])
    else:
        covars = quat_scale_to_covar(g.quats, g.scales)
        p = project_gaussians(g.means, covars, viewmat, intr, near, far, eps2d)
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


def _render_gsplat(g: Gaussians, cam: Camera, sh_degree: int, background: Tensor | None, near: float, far: float,
                   eps2d: float, tile: int, device: str) -> RenderOutput:
    """gsplat 1.5's ``rasterization`` (classic mode, RGB + expected depth, absgrad) on
    ``device``; the outputs are moved back to the Gaussians' device (gradients flow through
    the copies), ``radii`` is the larger of gsplat's two per-axis radii."""
    dev = torch_device(device, "the gsplat backend's device", "the gsplat backend needs CUDA; use appearance.backend: cpu")
    try:
        import gsplat
    except ImportError as e:
        raise ConfigError("splat backend gsplat: the gsplat package is not installed (pip install gsplat==1.5.3)") from e
    home = g.means.device
    fx, fy, cx, cy = cam.intrinsics.params
    Ks = torch.tensor([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=torch.float32, device=dev)[None]
    viewmats = torch.as_tensor(cam.w2c, dtype=torch.float32, device=dev)[None]
    bg = None
    if background is not None:  # [1, 3]: in RGB+ED mode gsplat appends the depth channel's zero itself
        bg = background.to(dev, torch.float32)[None]
    colors, alphas, meta = gsplat.rasterization(
        g.means.to(dev), g.quats.to(dev), g.scales.to(dev), g.opacities.to(dev), g.sh.to(dev), viewmats, Ks,
        cam.width, cam.height, near_plane=near, far_plane=far, eps2d=eps2d, sh_degree=sh_degree, tile_size=tile,
        backgrounds=bg, render_mode="RGB+ED", rasterize_mode="classic", absgrad=True, packed=False)
    means2d = meta["means2d"]  # [1, N, 2]; gsplat fills means2d.absgrad in backward
    radii = meta["radii"][0]
    radii = radii.amax(-1) if radii.dim() == 2 else radii
    return RenderOutput(colors[0, ..., :3].to(home), colors[0, ..., 3].to(home), alphas[0, ..., 0].to(home),
                        radii.to(home), means2d, None)
