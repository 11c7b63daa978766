"""Adaptive density control for mesh-anchored Gaussians (gsplat's Strategy shape; DRAWER's
``after_train`` / ``split_gaussians`` / ``dup_gaussians`` / ``cull_gaussians`` in its official code).

As in gsplat, the strategy dataclass *is* the config (``appearance.strategy``; ``null`` turns
density control off) and is never mutated: the running statistics live in the dict that
:meth:`MeshAnchoredStrategy.initialize_state` returns. The strategy edits the parameter rows
and their Adam moments together, so ``face`` (the row's face index), every parameter and every
optimizer state stay row-aligned (tested). Children of a split stay on their parent's face:
their in-face position is moved in the face plane, never by world-space noise.
"""

from dataclasses import dataclass

import torch
from torch import Tensor

from drawer_lib.errors import ConfigError
from drawer_lib.splat.anchored import AnchoredParams, FaceFrames


@dataclass(frozen=True)
class MeshAnchoredStrategy:
    """Thresholds (the official code's defaults scaled to a short CPU schedule): densify when the mean
    |2D-mean gradient| (x 0.5 max(H, W)) exceeds ``grad_thresh``; split (children with scales
    / ``split_shrink``) when the largest clipped scale > ``size_thresh`` (m), else duplicate;
    at most ``max_gaussians``; cull opacity < ``cull_alpha``, never emptying a face (face
    guard); all every ``refine_every`` steps in [``refine_start``, ``refine_stop``). Opacities
    are reset to <= ``reset_to`` every ``reset_every`` steps before ``refine_stop``."""

    refine_start: int = 200
    refine_every: int = 100
    refine_stop: int = 1200
    reset_every: int = 1000
    grad_thresh: float = 0.0008
    size_thresh: float = 0.01
    cull_alpha: float = 0.05
    reset_to: float = 0.2
    split_shrink: float = 1.6
    max_gaussians: int = 50_000

    def __post_init__(self):
        if self.refine_every < 1 or self.reset_every < 1:
            raise ConfigError("appearance.strategy: refine_every and reset_every must be >= 1")
        if not 0 < self.reset_to < 1 or not 0 <= self.cull_alpha < 1:
            raise ConfigError("appearance.strategy: need 0 < reset_to < 1 and 0 <= cull_alpha < 1")
        if self.split_shrink <= 1 or self.max_gaussians < 1:
            raise ConfigError("appearance.strategy: need split_shrink > 1 and max_gaussians >= 1")

    def initialize_state(self) -> dict[str, Tensor | None]:
        """The running statistics: per-Gaussian sums of |2D-mean gradient| and view counts."""
        return {"grad_sum": None, "count": None}

    def step_post_backward(self, state: dict, absgrad: Tensor, radii: Tensor, image_size: int) -> None:
        """Accumulate per-Gaussian 2D-mean gradient norms (pixels -> NDC-like units) of the
        Gaussians the view rendered (``radii`` > 0)."""
        n = absgrad.shape[0]
        if state["grad_sum"] is None or state["grad_sum"].shape[0] != n:
            state["grad_sum"] = torch.zeros(n, dtype=torch.float64)
            state["count"] = torch.zeros(n, dtype=torch.float64)
        vis = radii > 0  # (masked adds written as where: adding 0 elsewhere is exact, and cheaper than masking)
        g = absgrad.norm(dim=-1).double() * 0.5 * image_size
        state["grad_sum"] += torch.where(vis, g, 0.0)
        state["count"] += vis

    def step_post_optimizer(self, state: dict, step: int, p: AnchoredParams, frames: FaceFrames, scales: Tensor,
                            opt: torch.optim.Adam, gen: torch.Generator, allow_densify: bool = True,
                            allow_split: bool = True) -> dict[str, int]:
        """Run refinement at this step if due; edits ``p``, ``opt`` and ``state`` in place.
        ``scales``: the current clipped scales [N, 3]. Without ``allow_split`` (static
        Gaussians, whose positions must stay at the face centroids) every densified Gaussian is
        duplicated. Returns how many were split, duplicated and culled."""
        out = {"split": 0, "dup": 0, "culled": 0}
        if step > 0 and step % self.reset_every == 0 and step < self.refine_stop:
            self._reset_opacity(p, opt)
        if not (self.refine_start <= step < self.refine_stop and step % self.refine_every == 0):
            return out
        if state["grad_sum"] is not None and allow_densify:
            avg = state["grad_sum"] / state["count"].clamp_min(1)
            high = avg > self.grad_thresh
            big = scales.detach().amax(-1) > self.size_thresh
            if not allow_split:
                big = torch.zeros_like(big)
            room = self.max_gaussians - p.face.shape[0]
            split = high & big
            dup = high & ~big
            if room <= 0:
                split[:] = False
                dup[:] = False
            elif int(split.sum()) + int(dup.sum()) > room:  # keep the highest gradients
                idx = torch.nonzero(split | dup)[:, 0]
                keep = idx[torch.argsort(avg[idx], descending=True)[:room]]
                sel = torch.zeros_like(split)
                sel[keep] = True
                split &= sel
                dup &= sel
            out["dup"] = int(dup.sum())
            out["split"] = int(split.sum())
            self._grow(p, opt, frames, scales, split, dup, gen)
        culled = self._cull(p, opt)
        out["culled"] = culled
        state["grad_sum"] = None
        state["count"] = None
        return out

    # -- row editing ----------------------------------------------------------------------------
    @staticmethod
    def _edit(p: AnchoredParams, opt: torch.optim.Adam, fn, face_fn) -> None:
        """Replace every parameter by ``fn(name, rows, False)`` and its Adam moments by
        ``fn(name, moments, True)``, and ``p.face`` by ``face_fn(p.face)``."""
        done = set()
        for group in opt.param_groups:
            (old,) = group["params"]
            name = group["name"]
            new = torch.nn.Parameter(fn(name, old.detach(), False), requires_grad=old.requires_grad)
            st = opt.state.pop(old, None)
            if st:
                st = {k: (fn(name, v, True) if torch.is_tensor(v) and v.dim() > 0 else v) for k, v in st.items()}
                opt.state[new] = st
            group["params"] = [new]
            setattr(p, name, new)
            done.add(name)
        for name, t in p.trainable().items():  # frozen parameters (not optimised) keep their rows too
            if name not in done:
                setattr(p, name, torch.nn.Parameter(fn(name, t.detach(), False), requires_grad=t.requires_grad))
        p.face = face_fn(p.face)

    def _grow(self, p, opt, frames, scales, split, dup, gen) -> None:
        if not (split.any() or dup.any()):
            return
        si = torch.nonzero(split)[:, 0]
        di = torch.nonzero(dup)[:, 0]
        n_new = 2 * len(si) + len(di)
        # children of splits: two per parent, moved in the face plane, scales / 1.6
        s_in = scales.detach()[si, :2].amin(-1)
        rho = torch.randn(2, len(si), generator=gen, dtype=s_in.dtype).abs() * 0.5 * s_in
        t = torch.rand(2, len(si), generator=gen, dtype=s_in.dtype) * 2 * torch.pi
        base = p.means_2d.detach()[si]
        child_pos = base[None] + rho[..., None] * torch.stack([torch.cos(t), torch.sin(t)], -1)  # [2, S, 2]
        child_logs = torch.log(scales.detach()[si] / self.split_shrink)
        rows = {
            "means_2d": torch.cat([child_pos.reshape(-1, 2), p.means_2d.detach()[di]]),
            "log_scales": torch.cat([child_logs.repeat(2, 1), p.log_scales.detach()[di]]),
        }
        order = torch.cat([si, si, di])
        keep = torch.ones(p.face.shape[0], dtype=torch.bool)
        keep[si] = False  # the parents of splits are replaced by their children

        def fn(name: str, t: Tensor, is_state: bool) -> Tensor:
            if is_state:  # new rows start with zero Adam moments
                return torch.cat([t[keep], torch.zeros((n_new,) + t.shape[1:], dtype=t.dtype)])
            if name in rows:
                return torch.cat([t[keep], rows[name].to(t.dtype)])
            return torch.cat([t[keep], t[order]])

        self._edit(p, opt, fn, lambda face: torch.cat([face[keep], face[order]]))

    def _cull(self, p, opt) -> int:
        low = torch.sigmoid(p.opacity_logit.detach()) < self.cull_alpha
        if not low.any():
            return 0
        # face guard: a face whose Gaussians would all go keeps them all
        F = int(p.face.max()) + 1
        total = torch.bincount(p.face, minlength=F)
        gone = torch.bincount(p.face[low], minlength=F)
        emptied = gone == total
        drop = low & ~emptied[p.face]
        if not drop.any():
            return 0
        keep = ~drop
        self._edit(p, opt, lambda name, t, is_state: t[keep], lambda face: face[keep])
        return int(drop.sum())

    def _reset_opacity(self, p, opt) -> None:
        cap = float(torch.logit(torch.tensor(self.reset_to)))
        for group in opt.param_groups:
            if group["name"] == "opacity_logit":
                (par,) = group["params"]
                with torch.no_grad():
                    par.clamp_(max=cap)
                st = opt.state.get(par)
                if st:
                    for k in ("exp_avg", "exp_avg_sq"):
                        if k in st:
                            st[k].zero_()
