"""Volume rendering of an SDF with VolSDF's Laplace density (Yariv et al. 2021), in stable form.

    sigma(s) = (1 / beta) * Psi_beta(-s),   Psi_beta = CDF of a zero-mean Laplace of scale beta

written with exponentials of non-positive arguments only, so beta -> 1e-5 and |s| -> 1e3 give
finite values and gradients. Opacity alpha_i = 1 - exp(-sigma_i delta_i) (expm1), transmittance
T_i = exp(-sum_{j<i} sigma_j delta_j) (a cumulative sum in log space), weights w_i = T_i alpha_i.
"""

import torch
from jaxtyping import Float
from torch import Tensor


def laplace_density(s: Tensor, beta: float | Tensor) -> Tensor:
    """sigma(s) = (1/beta) * (0.5 exp(-s/beta) if s >= 0 else 1 - 0.5 exp(s/beta)); any shape."""
    e = 0.5 * torch.exp(-s.abs() / beta)  # in (0, 0.5], never overflows
    return torch.where(s >= 0, e, 1.0 - e) / beta


def render_weights(sigma: Float[Tensor, "R S"], deltas: Float[Tensor, "R S"]) -> Float[Tensor, "R S"]:
    """Alpha-compositing weights w_i = T_i (1 - exp(-sigma_i delta_i))."""
    tau = sigma * deltas  # optical thickness of each interval, >= 0
    alpha = -torch.expm1(-tau)
    trans = torch.exp(-torch.cumsum(tau, dim=-1) + tau)  # exclusive cumulative sum
    return trans * alpha


def beta_schedule(step: int, total: int, beta0: float, beta1: float, power: float = 0.8) -> float:
    """DRAWER's annealing beta0 -> beta1: beta0 / (1 + ((beta0 - beta1) / beta1) t^power), t in [0, 1]."""
    t = min(max(step / max(total, 1), 0.0), 1.0)
    return beta0 / (1.0 + ((beta0 - beta1) / beta1) * t**power)


def ray_box(origins: Float[Tensor, "R 3"], dirs: Float[Tensor, "R 3"], lo: Tensor, hi: Tensor,
            near: float) -> tuple[Tensor, Tensor]:
    """Entry and exit parameters of rays in an axis-aligned box (slab method); near clamps the
    entry; rays that miss get far <= near."""
    inv = 1.0 / torch.where(dirs.abs() < 1e-12, torch.full_like(dirs, 1e-12), dirs)
    t0, t1 = (lo - origins) * inv, (hi - origins) * inv
    tmin = torch.minimum(t0, t1).amax(-1).clamp_min(near)
    tmax = torch.maximum(t0, t1).amin(-1)
    return tmin, tmax


def sample_pdf(bins: Float[Tensor, "R K1"], weights: Float[Tensor, "R K"], n: int, det: bool = False) -> Tensor:
    """Inverse-CDF samples [R, n] from a piecewise-constant density on the intervals ``bins``."""
    w = weights + 1e-6
    pdf = w / w.sum(-1, keepdim=True)
    cdf = torch.cat([torch.zeros_like(pdf[:, :1]), torch.cumsum(pdf, -1)], -1)  # [R, K+1]
    if det:
        u = torch.linspace(0.0, 1.0, n, device=bins.device).expand(bins.shape[0], n).contiguous()
    else:
        u = torch.rand(bins.shape[0], n, device=bins.device)
    idx = torch.searchsorted(cdf, u, right=True).clamp(1, cdf.shape[-1] - 1)
    c0, c1 = cdf.gather(-1, idx - 1), cdf.gather(-1, idx)
    b0, b1 = bins.gather(-1, idx - 1), bins.gather(-1, idx)
    frac = (u - c0) / (c1 - c0).clamp_min(1e-12)
    return b0 + frac * (b1 - b0)
