"""Differentiable tile-based alpha compositing of projected 2D Gaussians on the CPU.

``composite`` takes what :func:`drawer_lib.splat.project.project_gaussians` returns plus colours
and opacities, sorts by depth, bins into tiles and composites front to back with early
termination (numba kernels in ``_raster_kernels``). Gradients flow to the 2D means, conics,
opacities, colours and depths; the summed absolute 2D-mean gradients (gsplat's ``absgrad``)
are written to ``absgrad`` when a buffer is passed, for density control.
"""

from dataclasses import dataclass

import numba
import numpy as np
import torch
from jaxtyping import Float
from torch import Tensor

from drawer_lib.splat import _raster_kernels as K


@dataclass
class Composite:
    rgb: Tensor  # [H, W, 3], not including the background
    depth: Tensor  # [H, W] sum of w z (divide by alpha for the expected depth)
    alpha: Tensor  # [H, W]


class _CompositeFn(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, conics, opacities, colors, depths, radii, width, height, tile, absgrad):
        dt = means2d.dtype
        m, co, op, cl, dp = (t.detach().contiguous().numpy() for t in (means2d, conics, opacities, colors, depths))
        r = footprint_radius(conics.detach(), opacities.detach(), radii).numpy()
        order = torch.argsort(depths.detach(), stable=True).numpy().astype(np.int64)
        offsets, ids = K.bin_gaussians(m, r, order, width, height, tile)
        rgb = np.zeros((height, width, 3), m.dtype)
        dep = np.zeros((height, width), m.dtype)
        alpha = np.zeros((height, width), m.dtype)
        last = np.full((height, width), -1, np.int64)
        K.composite_forward(m, co, op, cl, dp, r, offsets, ids, width, height, tile, rgb, dep, alpha, last)
        ctx.np_inputs = (m, co, op, cl, dp, r, offsets, ids, alpha, last)
        ctx.meta = (width, height, tile, dt)
        ctx.absgrad = absgrad
        return torch.from_numpy(rgb), torch.from_numpy(dep), torch.from_numpy(alpha)

    @staticmethod
    def backward(ctx, g_rgb, g_depth, g_alpha):
        m, co, op, cl, dp, r, offsets, ids, alpha, last = ctx.np_inputs
        width, height, tile, dt = ctx.meta
        n_chunks = numba.get_num_threads()
        grads = np.zeros((n_chunks, m.shape[0], K.N_GRAD), m.dtype)
        f = lambda g: g.detach().to(dt).contiguous().numpy()  # noqa: E731
        K.composite_backward(m, co, op, cl, dp, r, offsets, ids, width, height, tile, alpha, last,
                             f(g_rgb), f(g_depth), f(g_alpha), n_chunks, grads)
        G = torch.from_numpy(grads.sum(0))
        if ctx.absgrad is not None:
            ctx.absgrad += G[:, [K.G_AX, K.G_AY]].to(ctx.absgrad.dtype)
        return (G[:, [K.G_MX, K.G_MY]], G[:, [K.G_A, K.G_B, K.G_C]], G[:, K.G_OP], G[:, [K.G_R, K.G_G, K.G_BL]],
                G[:, K.G_Z], None, None, None, None, None)


def footprint_radius(conics: Tensor, opacities: Tensor, radii: Tensor) -> Tensor:
    """Half-size (pixels, int64) of the square outside which a Gaussian's alpha is below 1/255:
    alpha = o exp(-d^2 / 2) >= 1/255 needs the Mahalanobis distance d <= sqrt(2 ln(255 o)), and
    that ellipse fits in a square of half-size d sqrt(lambda_max(cov2d)). 0 where ``radii`` <= 0
    or o < 1/255. With it, no contribution the compositing rules keep is ever cut off, so the
    image does not depend on tiles or bounding boxes."""
    a, b, c = conics.unbind(-1)
    mid = 0.5 * (a + c)
    lam_min = mid - torch.sqrt((mid * mid - (a * c - b * b)).clamp_min(0.0))  # of the conic = 1 / lambda_max(cov)
    k2 = 2.0 * torch.log((255.0 * opacities).clamp_min(1.0))
    reach = torch.ceil(torch.sqrt(k2 / lam_min.clamp_min(1e-30)))
    ok = (radii > 0) & (opacities >= 1.0 / 255.0) & torch.isfinite(reach) & (lam_min > 0)
    return torch.where(ok, reach.clamp_max(1e6), torch.zeros_like(reach)).to(torch.int64).contiguous()


def composite(means2d: Float[Tensor, "N 2"], conics: Float[Tensor, "N 3"], opacities: Float[Tensor, "N"],
              colors: Float[Tensor, "N 3"], depths: Float[Tensor, "N"], radii: Tensor, width: int, height: int,
              tile: int = 16, absgrad: Tensor | None = None) -> Composite:
    """Alpha-composite N projected Gaussians front to back into an H x W image.

    means2d: pixel coordinates (pixel centres at integer + 0.5); conics: (a, b, c) of the inverse
    2D covariance [[a, b], [b, c]]; radii [N] (int): <= 0 culls (the pixels a Gaussian reaches
    are set by :func:`footprint_radius`, exactly those where its alpha can pass 1/255);
    colors may exceed [0, 1]
    (no clamping here). float32 or float64 (all inputs the same dtype).
    """
    n = means2d.shape[0]
    for name, t, shape in (("conics", conics, (n, 3)), ("opacities", opacities, (n,)), ("colors", colors, (n, 3)),
                           ("depths", depths, (n,)), ("radii", radii, (n,))):
        if tuple(t.shape) != shape:
            raise ValueError(f"composite: {name} has shape {tuple(t.shape)}, expected {shape}")
    if width < 1 or height < 1 or tile < 1:
        raise ValueError(f"composite: bad image size {width}x{height} or tile {tile}")
    if means2d.device.type != "cpu":
        raise ValueError("composite: the numba compositor runs on CPU tensors (use the gsplat backend on CUDA)")
    dt = means2d.dtype
    if any(t.dtype != dt for t in (conics, opacities, colors, depths)):
        raise TypeError("composite: means2d, conics, opacities, colors and depths must share a dtype")
    rgb, depth, alpha = _CompositeFn.apply(means2d, conics, opacities, colors, depths, radii, width, height, tile,
                                           absgrad)
    return Composite(rgb, depth, alpha)
