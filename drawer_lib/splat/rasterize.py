"""Differentiable tile-based alpha compositing of projected 2D Gaussians on the CPU.

``composite`` takes what :func:`drawer_lib.splat.project.project_gaussians` returns plus colours
and opacities, sorts by depth, bins into tiles and composites front to back with early
termination (numba kernels in ``_raster_kernels``). Gradients flow to the 2D means, conics,
opacities, colours and depths; the summed absolute 2D-mean gradients (gsplat's ``absgrad``)
are written to ``absgrad`` when a buffer is passed, for density control.
"""

import threading
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


class _ScratchPool:
    """Reusable 1-D scratch arrays for the compositor's large per-step buffers (its contribution
    record, ~15-20 MB at 50k Gaussians, and the per-entry gradient rows): a fresh ``np.empty``
    of that size may pay its page faults again on every training step. :meth:`take` hands out
    an array of ``dtype`` with at least ``n`` elements (removed from the pool, so two renders
    awaiting their backward never share one); :meth:`give` returns it. At most ``keep`` arrays
    are kept."""

    def __init__(self, keep: int = 6):
        self.keep = keep
        self._free: list[np.ndarray] = []
        self._lock = threading.Lock()  # renders may run in several Python threads (the viewer's server)

    def take(self, n: int, dtype=np.float64) -> np.ndarray:
        with self._lock:
            fits = [i for i, b in enumerate(self._free) if b.dtype == dtype and b.shape[0] >= n]
            if fits:
                return self._free.pop(min(fits, key=lambda i: self._free[i].shape[0]))
        return np.empty(n + n // 8 + 1024, dtype)  # some headroom: the counts drift from step to step

    def give(self, *bufs: np.ndarray) -> None:
        with self._lock:
            self._free.extend(bufs)
            while len(self._free) > self.keep:
                self._free.pop(min(range(len(self._free)), key=lambda i: self._free[i].shape[0]))


_POOL = _ScratchPool()


def _no_record() -> tuple:
    """The compositor kernels' record arguments when there is none: (v_off, vspan, rec_g, rec_q,
    rec_ok) empty."""
    return (np.zeros(1, np.int64), np.empty((0, 2), np.int64), np.empty(0), np.empty(0, np.int32),
            np.zeros(0, np.bool_))


class _CompositeFn(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, conics, opacities, colors, depths, radii, width, height, tile, absgrad, record):
        m, co, op, cl, dp = (t.detach().contiguous().numpy() for t in (means2d, conics, opacities, colors, depths))
        r = radii.detach().contiguous().numpy()
        n = m.shape[0]
        ext = np.empty((n, 4))
        K.footprints(m, co, op, r, ext)
        vis = np.flatnonzero(ext[:, 1] > 0.0)
        # front to back (= the stable sort of all, culled removed); the radix sort takes float32 / float64
        if dp.dtype in (np.float32, np.float64):
            order = K.depth_order(vis, dp)
        else:
            order = vis[np.argsort(dp[vis], kind="stable")]
        P = np.empty((order.shape[0], K.N_P))
        K.pack(order, m, co, op, cl, dp, ext, P)
        offsets, ids, g_off, slot, cost = K.bin_gaussians(P, width, height, tile)
        n_workers = numba.get_num_threads()
        w_off, w_tiles = K.assign_tiles(cost, n_workers)
        rgb = np.empty((height, width, 3), m.dtype)
        dep = np.empty((height, width), m.dtype)
        alpha = np.empty((height, width), m.dtype)
        T_final = np.empty((height, width))
        last = np.empty((height, width), np.int64)
        work = np.zeros(cost.shape[0])
        if record:  # the contribution record for the backward pass (tile t's room: its footprint-box areas)
            v_off = np.zeros(cost.shape[0] + 1, np.int64)
            np.cumsum(cost.astype(np.int64), out=v_off[1:])
            bufs = (_POOL.take(int(v_off[-1])), _POOL.take(int(v_off[-1]), np.int32))
            rec = (v_off, np.empty((ids.shape[0], 2), np.int64), bufs[0][: v_off[-1]], bufs[1][: v_off[-1]],
                   np.zeros(cost.shape[0], np.bool_))
        else:
            bufs, rec = (), _no_record()
        K.composite_forward(P, offsets, ids, w_off, w_tiles, width, height, tile, rgb, dep, alpha, T_final, last, work,
                            *rec)
        ctx.np_inputs = (P, order, offsets, ids, g_off, slot, work, T_final, last)
        ctx.record = (bufs, rec)
        ctx.meta = (width, height, tile, m.dtype, n, n_workers)
        ctx.absgrad = absgrad
        return torch.from_numpy(rgb), torch.from_numpy(dep), torch.from_numpy(alpha)

    @staticmethod
    def backward(ctx, g_rgb, g_depth, g_alpha):
        P, order, offsets, ids, g_off, slot, work, T_final, last = ctx.np_inputs
        width, height, tile, dt, n, n_workers = ctx.meta
        tdt = torch.from_numpy(np.empty(0, dt)).dtype
        w_off, w_tiles = K.assign_tiles(work, n_workers)
        f = lambda g: g.detach().to(tdt).contiguous().numpy()  # noqa: E731
        # the record goes back to the pool after one use; a second backward (retain_graph) recomputes
        bufs, rec = ctx.record or ((), _no_record())
        ctx.record = None
        E = ids.shape[0]
        g_buf = _POOL.take(E * K.N_GRAD)
        gbuf = g_buf[: E * K.N_GRAD].reshape(E, K.N_GRAD)
        K.composite_backward(P, offsets, ids, slot, w_off, w_tiles, width, height, tile, T_final, last, f(g_rgb),
                             f(g_depth), f(g_alpha), gbuf, *rec[1:])
        _POOL.give(*bufs)
        gm, gc, go, gcl, gd = (np.empty(s, dt) for s in ((n, 2), (n, 3), (n,), (n, 3), (n,)))
        ab = ctx.absgrad
        direct = ab is not None and ab.dtype == tdt and ab.is_contiguous() and tuple(ab.shape) == (n, 2)
        ab_np = ab.detach().numpy() if direct else np.zeros((0 if ab is None else n, 2), dt)
        K.reduce_gradients(order, g_off, gbuf, gm, gc, go, gcl, gd, ab_np)
        _POOL.give(g_buf)
        if ab is not None and not direct:
            ab += torch.from_numpy(ab_np).to(ab.dtype)
        return (torch.from_numpy(gm), torch.from_numpy(gc), torch.from_numpy(go), torch.from_numpy(gcl),
                torch.from_numpy(gd), None, None, None, None, None, None)


def footprint_radius(conics: Tensor, opacities: Tensor, radii: Tensor) -> Tensor:
    """Half-size (pixels, int64) of the square outside which a Gaussian's alpha is below 1/255:
    alpha = o exp(-d^2 / 2) >= 1/255 needs the Mahalanobis distance d <= sqrt(2 ln(255 o)), and
    that ellipse fits in a square of half-size d sqrt(lambda_max(cov2d)) (the compositor now
    uses the ellipse itself, ``_raster_kernels.footprints``; this square stays as its bound). 0 where ``radii`` <= 0
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
    2D covariance [[a, b], [b, c]]; radii [N] (int): <= 0 culls (the pixels a Gaussian visits
    are those of its ellipse where alpha can pass 1/255, ``_raster_kernels.footprints``; a
    subset of :func:`footprint_radius`'s square); colors may exceed [0, 1] (no clamping here).
    float32 or float64 (all inputs the same dtype). Outputs and gradients are deterministic and
    do not depend on the number of numba threads.
    """
    n = means2d.shape[0]
    for name, t, shape in (("conics", conics, (n, 3)), ("opacities", opacities, (n,)), ("colors", colors, (n, 3)),
                           ("depths", depths, (n,)), ("radii", radii, (n,))):
        if tuple(t.shape) != shape:
            raise ValueError(f"composite: {name} has shape {tuple(t.shape)}, expected {shape}")
    if width < 1 or height < 1 or not 1 <= tile <= 32767:  # (the record packs a pixel's tile row and column in 16 bits)
        raise ValueError(f"composite: bad image size {width}x{height} or tile {tile}")
    if means2d.device.type != "cpu":
        raise ValueError("composite: the numba compositor runs on CPU tensors (use the gsplat backend on CUDA)")
    dt = means2d.dtype
    if any(t.dtype != dt for t in (conics, opacities, colors, depths)):
        raise TypeError("composite: means2d, conics, opacities, colors and depths must share a dtype")
    # the forward pass records its contributions for the backward pass only when there will be one
    record = torch.is_grad_enabled() and any(t.requires_grad for t in (means2d, conics, opacities, colors, depths))
    rgb, depth, alpha = _CompositeFn.apply(means2d, conics, opacities, colors, depths, radii, width, height, tile,
                                           absgrad, record)
    return Composite(rgb, depth, alpha)
