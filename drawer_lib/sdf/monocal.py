"""Metric calibration of monocular depth by multi-view photometric consistency.

A monocular depth prior is relative: each frame has an unknown scale and shift (and, in
practice, a smooth low-frequency warp). With posed images the metric depth is observable: the
right depth map warps the frame's pixels onto its neighbours' matching colours. Per frame ``i``
the calibrated depth is

    z_i(u) = (a_i + (b_i - a_i) * m_i(u)) * (1 + c_i(u)),

with ``a_i``/``b_i`` the metric depths of the prior's 0 and 1 and ``c_i`` a bilinear correction
on a coarse ``grid`` x ``grid`` lattice. ``(a_i, b_i)`` are found by exhaustive search over a
log-spaced range scaled by the cameras' focus depth (the photometric cost is far from convex in
them), then ``a, b, c`` are refined jointly by Adam on the full-resolution cost. The cost of a
pixel is the minimum over the frame's neighbours of the L1 colour difference (the minimum
ignores neighbours where the point is occluded or out of view), clamped to be robust.

Cost: ~20 s search + ~0.1 s per refinement step for 48 frames of 200x150 on 2 cores. Why this
and not only a scale-and-shift invariant loss inside the SDF: on a CPU budget the SDF cannot
afford the thousands of steps that RGB alone needs to pin the surfaces; a metric depth target
from the first step makes it converge like the sensor-depth regime (measured in the README).
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from drawer_lib.errors import ConfigError, InputError, NonFiniteError
from drawer_lib.geometry.camera import Intrinsics


@dataclass(frozen=True)
class MonoCalConfig:
    """``neighbours`` per frame, chosen closest among those with a baseline in
    [``min_baseline``, ``max_baseline``] x focus depth and optical axes within ``max_angle_deg``.
    Search: ``search_levels`` log-spaced values of a in [``near_lo``, ``near_hi``] and of b in
    [``far_lo``, ``far_hi``] x focus depth, at 1/``search_downsample`` resolution. Refinement: ``refine_steps`` Adam steps
    of ``refine_frames`` frames, learning rate ``lr`` (relative), correction lattice ``grid``
    with L2 weight ``grid_weight``; colour differences clamped at ``clamp``."""

    neighbours: int = 4
    min_baseline: float = 0.05
    max_baseline: float = 0.6
    max_angle_deg: float = 35.0
    search_levels: int = 24
    near_lo: float = 0.25
    near_hi: float = 1.4
    far_lo: float = 0.6
    far_hi: float = 2.6
    search_downsample: int = 2
    refine_steps: int = 300
    refine_frames: int = 8
    lr: float = 0.01
    grid: int = 4
    grid_weight: float = 1e-3
    clamp: float = 0.2

    def __post_init__(self):
        if self.neighbours < 1 or self.search_levels < 2 or self.refine_steps < 0 or self.grid < 1:
            raise ConfigError("monocal: need neighbours >= 1, search_levels >= 2, refine_steps >= 0, grid >= 1")
        if not (0 < self.near_lo < self.near_hi and 0 < self.far_lo < self.far_hi):
            raise ConfigError("monocal: need 0 < near_lo < near_hi and 0 < far_lo < far_hi")
        if not (0 < self.min_baseline < self.max_baseline):
            raise ConfigError("monocal: need 0 < min_baseline < max_baseline")


@dataclass
class MonoCalResult:
    depth: Tensor  # [N, H, W] metric z-depth
    a: Tensor  # [N]
    b: Tensor  # [N]
    corr: Tensor  # [N, grid + 1, grid + 1]
    cost_search: float  # mean clamped photometric cost after the search
    cost_final: float  # ... after refinement
    neighbours: list[list[int]]


def choose_neighbours(c2w: Tensor, focus: float, cfg: MonoCalConfig) -> list[list[int]]:
    """For each camera the ``cfg.neighbours`` closest others within the baseline/angle window."""
    C, D = c2w[:, :3, 3], c2w[:, :3, 2]
    out = []
    for i in range(len(c2w)):
        dist = (C - C[i]).norm(dim=1)
        ang = torch.rad2deg(torch.arccos((D @ D[i]).clamp(-1, 1)))
        ok = (dist > cfg.min_baseline * focus) & (dist < cfg.max_baseline * focus) & (ang < cfg.max_angle_deg)
        idx = torch.nonzero(ok)[:, 0]
        out.append(idx[torch.argsort(dist[idx])][: cfg.neighbours].tolist())
    return out


class PhotoCost:
    """Per-pixel min-over-neighbours photometric cost of candidate depth maps of one frame."""

    def __init__(self, images: Tensor, intr: Intrinsics, c2w: Tensor, neighbours: list[list[int]]):
        self.img = images  # [N, 3, H, W] in [0, 1]
        self.intr, self.c2w, self.nbrs = intr, c2w, neighbours
        self.w2c = torch.linalg.inv(c2w)

    def __call__(self, i: int, z: Tensor, scale: int = 1) -> tuple[Tensor, Tensor]:
        """``z`` [B, h, w] candidate depths at 1/scale resolution -> (cost [B, h, w], valid)."""
        it, B, (h, w) = self.intr, z.shape[0], z.shape[1:]
        ref = self.img[i : i + 1]
        if scale > 1:
            ref = F.avg_pool2d(ref, scale)
        u0 = (torch.arange(w, dtype=torch.float32) + 0.5) * scale
        v0 = (torch.arange(h, dtype=torch.float32) + 0.5) * scale
        x = ((u0 - it.cx) / it.fx)[None, :].expand(h, w)
        y = ((v0 - it.cy) / it.fy)[:, None].expand(h, w)
        P = torch.stack([x * z, y * z, z], -1)  # [B, h, w, 3] camera i
        Pw = P @ self.c2w[i, :3, :3].T + self.c2w[i, :3, 3]
        best = torch.full((B, h, w), float("inf"))
        for j in self.nbrs[i]:
            Pj = Pw @ self.w2c[j, :3, :3].T + self.w2c[j, :3, 3]
            zj = Pj[..., 2]
            zs = torch.where(zj > 1e-3, zj, torch.ones_like(zj))
            g = torch.stack([(it.fx * Pj[..., 0] / zs + it.cx) / it.width * 2 - 1,
                             (it.fy * Pj[..., 1] / zs + it.cy) / it.height * 2 - 1], -1)
            tgt = self.img[j : j + 1].expand(B, -1, -1, -1)
            samp = F.grid_sample(tgt, g, align_corners=False, padding_mode="border")
            e = (samp - ref).abs().mean(1)
            inside = (g.abs() < 1).all(-1) & (zj > 1e-3)
            best = torch.minimum(best, torch.where(inside, e, torch.full_like(e, float("inf"))))
        valid = torch.isfinite(best)
        return torch.where(valid, best, torch.zeros_like(best)), valid


def _upsample(corr: Tensor, H: int, W: int) -> Tensor:
    return F.interpolate(corr[:, None], size=(H, W), mode="bilinear", align_corners=True)[:, 0]


def calibrate_mono_depth(images: Tensor, mono: Tensor, intr: Intrinsics, c2w: Tensor, focus: float,
                         cfg: MonoCalConfig, progress: Callable = lambda it, **kw: it) -> MonoCalResult:
    """Metric depth maps from relative ones.

    images: [N, H, W, 3] in [0, 1]; mono: [N, H, W] relative depth (larger = farther);
    c2w: [N, 4, 4] OpenCV camera-to-world (metres); focus: typical viewing depth (metres).
    """
    N, H, W = mono.shape
    if not (torch.isfinite(mono).all() and torch.isfinite(images).all()):
        raise InputError("monocular calibration: images or monocular depth contain non-finite values")
    nbrs = choose_neighbours(c2w, focus, cfg)
    if sum(len(n) > 0 for n in nbrs) == 0:
        raise InputError(f"monocular calibration: no frame has a neighbour with a baseline in "
                         f"[{cfg.min_baseline}, {cfg.max_baseline}] x {focus:.3g} m within {cfg.max_angle_deg} deg")
    cost = PhotoCost(images.permute(0, 3, 1, 2).contiguous(), intr, c2w, nbrs)
    # m -> z is only meaningful up to the prior's range: normalise each frame to [0, 1]
    lo = mono.flatten(1).min(1)[0][:, None, None]
    hi = mono.flatten(1).max(1)[0][:, None, None]
    m = (mono - lo) / (hi - lo).clamp_min(1e-9)
    A = focus * torch.logspace(np.log10(cfg.near_lo), np.log10(cfg.near_hi), cfg.search_levels)
    Bv = focus * torch.logspace(np.log10(cfg.far_lo), np.log10(cfg.far_hi), cfg.search_levels)
    cand = torch.cartesian_prod(A, Bv)
    cand = cand[cand[:, 1] > 1.05 * cand[:, 0]]
    a = torch.full((N,), float(focus))
    b = torch.full((N,), float(focus))
    s = cfg.search_downsample
    search_cost = []
    for i in progress(range(N), desc="monocal search", total=N):
        if not nbrs[i]:  # no neighbour: keep the prior's shape around the focus depth
            a[i], b[i] = 0.7 * focus, 1.5 * focus
            continue
        ms = F.avg_pool2d(m[i][None, None], s)[0, 0] if s > 1 else m[i]
        costs = []
        for cc in cand.split(64):
            z = cc[:, 0, None, None] + (cc[:, 1] - cc[:, 0])[:, None, None] * ms[None]
            e, ok = cost(i, z, s)
            costs.append(torch.where(ok, e.clamp_max(cfg.clamp), torch.full_like(e, cfg.clamp)).mean((1, 2)))
        costs = torch.cat(costs)
        k = int(costs.argmin())
        a[i], b[i] = cand[k]
        search_cost.append(float(costs[k]))
    G = cfg.grid
    pa, pb = a.log().clone().requires_grad_(True), b.log().clone().requires_grad_(True)
    corr = torch.zeros(N, G + 1, G + 1, requires_grad=True)
    opt = torch.optim.Adam([pa, pb, corr], lr=cfg.lr)
    gen = torch.Generator().manual_seed(0)
    have = [i for i in range(N) if nbrs[i]]

    def depth_of(idx: list[int]) -> Tensor:
        ea, eb = pa[idx].exp(), pb[idx].exp()
        z = ea[:, None, None] + (eb - ea)[:, None, None] * m[idx]
        return z * (1 + _upsample(corr[idx], H, W))

    for _ in progress(range(cfg.refine_steps), desc="monocal refine", total=cfg.refine_steps):
        pick = torch.randperm(len(have), generator=gen)[: cfg.refine_frames].tolist()
        idx = [have[k] for k in pick]
        z = depth_of(idx)
        loss = 0.0
        for k, i in enumerate(idx):
            e, ok = cost(i, z[k : k + 1])
            loss = loss + torch.where(ok, e.clamp_max(cfg.clamp), torch.zeros_like(e)).mean()
        loss = loss / len(idx) + cfg.grid_weight * (corr[idx] ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        z = depth_of(list(range(N)))
        final = []
        for i in have:
            e, ok = cost(i, z[i : i + 1])
            final.append(float(torch.where(ok, e.clamp_max(cfg.clamp), torch.full_like(e, cfg.clamp)).mean()))
    if not torch.isfinite(z).all() or (z <= 0).any():
        raise NonFiniteError("monocular calibration produced non-positive or non-finite depth")
    return MonoCalResult(z.detach(), pa.detach().exp(), pb.detach().exp(), corr.detach(),
                         float(np.mean(search_cost)) if search_cost else float("nan"),
                         float(np.mean(final)) if final else float("nan"), nbrs)
