"""Losses of the neural SDF; each returns a scalar, the trainer weights them by config."""

import torch
import torch.nn.functional as F
from jaxtyping import Float
from torch import Tensor


def rgb_l1(pred: Float[Tensor, "R 3"], target: Float[Tensor, "R 3"]) -> Tensor:
    return (pred - target).abs().mean()


def eikonal(grad: Float[Tensor, "N 3"]) -> Tensor:
    """mean (|grad s| - 1)^2."""
    return ((grad.norm(dim=-1) - 1.0) ** 2).mean()


def depth_l1(pred: Float[Tensor, "R"], target: Float[Tensor, "R"]) -> Tensor:
    """L1 on pixels with a valid (> 0) metric depth; 0 when none is valid."""
    ok = target > 0
    if not ok.any():
        return pred.sum() * 0.0
    return (pred[ok] - target[ok]).abs().mean()


def scale_shift_invariant(pred: Float[Tensor, "G P"], mono: Float[Tensor, "G P"]) -> Tensor:
    """DRAWER's monocular depth loss, per group (one image): the least-squares (w, q) with
    w * pred + q ~ mono (closed form, not detached), then mean(min(residual^2, 1))."""
    n = pred.shape[1]
    sx, sy = pred.sum(1), mono.sum(1)
    sxx, sxy = (pred * pred).sum(1), (pred * mono).sum(1)
    det = n * sxx - sx * sx
    ok = det.abs() > 1e-9 * n * n
    det = torch.where(ok, det, torch.ones_like(det))
    w = torch.where(ok, (n * sxy - sx * sy) / det, torch.zeros_like(det))
    q = torch.where(ok, (sy - w * sx) / n, sy / n)
    r = w[:, None] * pred + q[:, None] - mono
    return (r * r).clamp_max(1.0).mean()


def normal_prior(pred: Float[Tensor, "R 3"], prior: Float[Tensor, "R 3"]) -> Tensor:
    """L1 + (1 - cos) between unit rendered normals and the (world-frame) prior."""
    p, q = F.normalize(pred, dim=-1), F.normalize(prior, dim=-1)
    return (p - q).abs().sum(-1).mean() + (1.0 - (p * q).sum(-1)).mean()


def depth_sdf(s_surface: Float[Tensor, "R"], s_samples: Float[Tensor, "R S"], t: Float[Tensor, "R S"],
              z: Float[Tensor, "R"], ray_len: Float[Tensor, "R"], cos: Float[Tensor, "R S"], trunc: float) -> Tensor:
    """SDF supervision from metric depth z (rays with z > 0 only):

    - the back-projected depth point is on the surface: |s(o + z d)|;
    - samples within ``trunc`` (metres along the ray) of it: s ~ (z - t) |d| cos, the signed
      distance to the observed plane (cos = |n . ray| with the current normal, detached);
    - samples in front of that band lie in free space: s >= 0 and s <= (z - t) |d| (a point
      cannot be farther from every surface than from the one the ray hits).
    """
    ok = z > 0
    if not ok.any():
        return s_surface.sum() * 0.0
    s_surface, s_samples, t, z, ray_len, cos = s_surface[ok], s_samples[ok], t[ok], z[ok], ray_len[ok], cos[ok]
    along = (z[:, None] - t) * ray_len[:, None]  # metres in front of the observed surface (< 0 behind)
    band = along.abs() <= trunc
    front = along > trunc
    l_surf = s_surface.abs().mean()
    l_band = ((s_samples - along * cos).abs() * band).sum() / band.sum().clamp_min(1)
    l_free = ((F.relu(-s_samples) + F.relu(s_samples - along)) * front).sum() / front.sum().clamp_min(1)
    return l_surf + l_band + l_free
