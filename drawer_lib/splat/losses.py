"""The appearance losses as a named dict (nerfstudio's ``get_loss_dict``): each term's weight is a
config key (``appearance.losses``), so turning a term off is a one-line experiment."""

import numpy as np
import torch
import torch.nn.functional as F
from jaxtyping import Float
from torch import Tensor

from drawer_lib.metrics.image import ssim
from drawer_lib.splat.config import LossConfig
from drawer_lib.splat.render import RenderOutput


class _SsimFn(torch.autograd.Function):
    """SSIM (mean over channels and valid window positions) of x [H, W, C] against y [H, W, C]
    with y's statistics ``stats`` [1, 2C, h, w] (:func:`drawer_lib.metrics.image.ssim_target_stats`),
    in the numba kernels of ``_ssim_kernels`` (float64 inside; equal to ``ssim`` up to float
    rounding, tested); gradient to x only."""

    @staticmethod
    def forward(ctx, x, y, stats, size, sigma):
        from drawer_lib.splat import _ssim_kernels as SK

        xs, ys = (t.detach().permute(2, 0, 1).contiguous().numpy() for t in (x, y))
        st = stats.detach()[0].contiguous().numpy()
        r = np.arange(size, dtype=np.float64) - (size - 1) / 2
        win = np.exp(-(r**2) / (2 * sigma**2))
        win /= win.sum()
        C, H, W = xs.shape
        parts = np.empty((C, 3, H - size + 1, W - size + 1))
        val = SK.ssim_forward(xs, ys, st, win, parts)
        ctx.state = (xs, ys, win, parts)
        return torch.tensor(val, dtype=x.dtype)

    @staticmethod
    def backward(ctx, g):
        from drawer_lib.splat import _ssim_kernels as SK

        xs, ys, win, parts = ctx.state
        C, H, W = xs.shape
        n = C * parts.shape[2] * parts.shape[3]
        gx = np.empty_like(xs)
        SK.ssim_backward(xs, ys, win, parts, float(g) / n, gx)
        return torch.from_numpy(gx).permute(1, 2, 0), None, None, None, None


def fused_ssim(x: Float[Tensor, "H W C"], y: Float[Tensor, "H W C"], y_stats: Tensor, size: int = 11,
               sigma: float = 1.5) -> Tensor:
    """:func:`drawer_lib.metrics.image.ssim` of one channels-last image pair (a scalar) with the
    target's precomputed statistics, in numba (forward and backward)."""
    return _SsimFn.apply(x, y, y_stats, size, sigma)


def appearance_losses(out: RenderOutput, gt: Tensor, scales: Tensor, step: int, w: LossConfig,
                      gt_stats: tuple | None = None, mesh_depth: Tensor | None = None) -> dict[str, Tensor]:
    """The unweighted terms with a positive weight: ``l1`` and ``dssim`` of the render against
    ``gt`` [H, W, 3] (``gt_stats``: its precomputed SSIM statistics), ``alpha`` (coverage below
    0.95), ``mesh_depth`` (|D_mesh - D_gs| where ``mesh_depth`` [H, W] > 0), ``aniso`` (in-plane
    scale ratio of ``scales`` [N, 3] above ``w.aniso_ratio``, every ``w.aniso_every`` steps)."""
    if gt_stats is not None and out.rgb.device.type == "cpu" and out.rgb.shape[0] >= 11 and out.rgb.shape[1] >= 11:
        s = fused_ssim(out.rgb, gt, gt_stats)
    else:
        s = ssim(out.rgb.permute(2, 0, 1)[None], gt.permute(2, 0, 1)[None], y_stats=gt_stats)[0]
    terms: dict[str, Tensor] = {"l1": (out.rgb - gt).abs().mean(), "dssim": 1 - s}
    if w.alpha > 0:
        terms["alpha"] = F.relu(0.95 - out.alpha).mean()
    if w.mesh_depth > 0 and mesh_depth is not None:
        seen = mesh_depth > 0
        terms["mesh_depth"] = (mesh_depth[seen] - out.depth[seen]).abs().mean()
    if w.aniso > 0 and step % w.aniso_every == 0:
        s2 = scales[:, :2]
        terms["aniso"] = F.relu(s2.amax(-1) / s2.amin(-1).clamp_min(1e-12) - w.aniso_ratio).mean()
    return terms


def total_loss(terms: dict[str, Tensor], w: LossConfig) -> Tensor:
    """sum_k weight_k term_k, in the order of ``terms``."""
    return sum(getattr(w, k) * v for k, v in terms.items())  # type: ignore[return-value]
