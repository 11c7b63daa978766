"""The appearance losses as a named dict (nerfstudio's ``get_loss_dict``): each term's weight is a
config key (``appearance.losses``), so turning a term off is a one-line experiment."""

import torch.nn.functional as F
from torch import Tensor

from drawer_lib.metrics.image import ssim
from drawer_lib.splat.config import LossConfig
from drawer_lib.splat.render import RenderOutput


def appearance_losses(out: RenderOutput, gt: Tensor, scales: Tensor, step: int, w: LossConfig,
                      gt_stats: tuple | None = None, mesh_depth: Tensor | None = None) -> dict[str, Tensor]:
    """The unweighted terms with a positive weight: ``l1`` and ``dssim`` of the render against
    ``gt`` [H, W, 3] (``gt_stats``: its precomputed SSIM statistics), ``alpha`` (coverage below
    0.95), ``mesh_depth`` (|D_mesh - D_gs| where ``mesh_depth`` [H, W] > 0), ``aniso`` (in-plane
    scale ratio of ``scales`` [N, 3] above ``w.aniso_ratio``, every ``w.aniso_every`` steps)."""
    x, y = out.rgb.permute(2, 0, 1)[None], gt.permute(2, 0, 1)[None]
    terms: dict[str, Tensor] = {"l1": (out.rgb - gt).abs().mean(), "dssim": 1 - ssim(x, y, y_stats=gt_stats)[0]}
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
