"""Sample placement along rays for a CPU: a cached coarse SDF grid instead of proposal networks.

Every ``cache_every`` steps the field is evaluated (no gradient) on a coarse grid over the box;
each training ray then marches this cache (trilinear lookups, cheap) to its first outside ->
inside crossing and gets ``fine`` samples within +- band around it, plus a few stratified
samples over the whole ray. Per ray this costs one small grid lookup per coarse step instead of
the 256 + 96 proposal-network samples of BakedSDF.
"""

import torch
import torch.nn.functional as F
from jaxtyping import Float
from torch import Tensor

from drawer_lib.sdf.render import ray_box


class SdfCache:
    """The field's SDF on a regular grid of cell ``cell`` over [lo, hi] (vertices inclusive)."""

    def __init__(self, lo: Tensor, hi: Tensor, cell: float):
        self.lo, self.hi, self.cell = lo.float(), hi.float(), float(cell)
        self.shape = tuple(int(n) for n in (torch.ceil((self.hi - self.lo) / cell) + 1).long().tolist())
        self.values: Tensor | None = None  # [1, 1, Z, Y, X] for grid_sample

    def points(self) -> Tensor:
        axes = [self.lo[a] + self.cell * torch.arange(self.shape[a], dtype=torch.float32) for a in range(3)]
        return torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)

    @torch.no_grad()
    def refresh(self, sdf_fn, chunk: int = 1 << 16) -> None:
        p = self.points()
        v = torch.cat([sdf_fn(c) for c in p.split(chunk)]).reshape(self.shape)  # [X, Y, Z]
        self.values = v.permute(2, 1, 0)[None, None].contiguous()

    @torch.no_grad()
    def query(self, x: Float[Tensor, "N 3"]) -> Float[Tensor, "N"]:
        if self.values is None:
            raise RuntimeError("SdfCache.query before refresh")
        ext = (torch.tensor(self.shape, dtype=torch.float32) - 1) * self.cell
        g = ((x - self.lo) / ext) * 2 - 1
        return F.grid_sample(self.values, g[None, :, None, None, :], align_corners=True, padding_mode="border").reshape(-1)


def first_crossing(t: Float[Tensor, "R K"], s: Float[Tensor, "R K"]) -> tuple[Tensor, Tensor]:
    """(t of the first + to - sign change, linearly interpolated [R]; bool [R] whether it exists)."""
    change = (s[:, :-1] > 0) & (s[:, 1:] <= 0)  # [R, K-1]
    has = change.any(-1)
    k = torch.where(has, change.float().argmax(-1), torch.zeros_like(has, dtype=torch.long))
    s0, s1 = s.gather(1, k[:, None])[:, 0], s.gather(1, k[:, None] + 1)[:, 0]
    t0, t1 = t.gather(1, k[:, None])[:, 0], t.gather(1, k[:, None] + 1)[:, 0]
    frac = s0 / (s0 - s1).clamp_min(1e-12)
    return t0 + frac * (t1 - t0), has


def place_samples(cache: SdfCache, origins: Tensor, dirs: Tensor, lo: Tensor, hi: Tensor, near: float,
                  n_fine: int, n_uniform: int, half_band: float, gen: torch.Generator | None = None,
                  march_step: float | None = None) -> tuple[Tensor, Tensor, Tensor]:
    """Sorted sample parameters t [R, n_fine + n_uniform] (z-depths), and the rays' near/far [R]
    inside the box. Rays without a crossing in the cache get all their samples stratified."""
    tn, tf = ray_box(origins, dirs, lo, hi, near)
    tf = torch.maximum(tf, tn + 1e-3)
    R = origins.shape[0]
    step = march_step or cache.cell
    length = (tf - tn) * dirs.norm(dim=-1)
    K = int(min(max(torch.ceil(length.max() / step).item(), 2), 512))
    u = (torch.arange(K, dtype=torch.float32) + 0.5) / K
    tc = tn[:, None] + (tf - tn)[:, None] * u[None]
    sc = cache.query((origins[:, None] + dirs[:, None] * tc[..., None]).reshape(-1, 3)).view(R, K)
    tstar, has = first_crossing(tc, sc)
    half_t = half_band / dirs.norm(dim=-1)  # band in metres -> in t
    j = (torch.arange(n_fine, dtype=torch.float32) + torch.rand(R, n_fine, generator=gen)) / n_fine * 2 - 1
    t_fine = tstar[:, None] + half_t[:, None] * j
    strat = (torch.arange(n_fine, dtype=torch.float32) + torch.rand(R, n_fine, generator=gen)) / n_fine
    t_fine = torch.where(has[:, None], t_fine, tn[:, None] + (tf - tn)[:, None] * strat)
    t_uni = tn[:, None] + (tf - tn)[:, None] * (torch.arange(n_uniform, dtype=torch.float32)
                                                + torch.rand(R, n_uniform, generator=gen)) / max(n_uniform, 1)
    t = torch.cat([t_fine, t_uni], -1).clamp(tn[:, None], tf[:, None])
    return torch.sort(t, -1)[0], tn, tf


def depth_ray_samples(z: Float[Tensor, "P"], ray_len: Float[Tensor, "P"], near: float, n_band: int, n_free: int,
                      band: float, behind: float, gen: torch.Generator | None = None) -> Float[Tensor, "P K"]:
    """Sample parameters t [P, n_band + n_free] (z-depths) along rays with observed depth ``z``:
    ``n_band`` stratified over [z - band, z + behind] and ``n_free`` stratified over the free
    space [near, z - band] in front of it (``band``, ``behind`` in metres along the ray; rays of
    length ``ray_len`` per unit t). These need SDF values only: no colour, no volume rendering."""
    P = z.shape[0]
    to_t = 1.0 / ray_len
    out = []
    if n_band:
        u = (torch.arange(n_band, dtype=torch.float32) + torch.rand(P, n_band, generator=gen)) / n_band
        a, b = z - band * to_t, z + behind * to_t
        out.append(a[:, None] + (b - a)[:, None] * u)
    if n_free:
        u = (torch.arange(n_free, dtype=torch.float32) + torch.rand(P, n_free, generator=gen)) / n_free
        a = torch.full_like(z, near)
        b = torch.maximum(z - band * to_t, a)
        out.append(a[:, None] + (b - a)[:, None] * u)
    return torch.cat(out, -1).clamp_min(near) if out else torch.zeros(P, 0)
