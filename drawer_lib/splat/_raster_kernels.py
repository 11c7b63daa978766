"""Numba kernels of the tile-based Gaussian compositor (binning, forward, backward).

Conventions (gsplat's "classic" rasteriser): pixel (i, j) has its centre at (j + 0.5, i + 0.5);
a Gaussian with 2D mean m, conic (a, b, c) = inverse 2D covariance and opacity o contributes
alpha = min(0.999, o exp(p)), p = -0.5 (a dx^2 + c dy^2) - b dx dy, dx = m_x - x, dy = m_y - y;
contributions with p > 0 or alpha < 1/255 are skipped; compositing runs front to back and
stops before the Gaussian that would bring the transmittance to <= 1e-4.

A Gaussian is visited only at the pixels whose centres lie in its footprint square (2D mean +-
``reach``, outside which its alpha is below 1/255; see ``rasterize.footprint_radius``), so the
image is the plain front-to-back definition, independent of tiles.

Forward runs in parallel over tiles. Backward walks each pixel's contributors back to front (as
3DGS does) and accumulates per-Gaussian gradients into one buffer per worker chunk (chunks own
interleaved tiles), summed at the end: no atomics, no races. Per-pixel state is float64.
"""

from typing import no_type_check

import numba
import numpy as np
from numba import njit, prange

if numba.config.THREADING_LAYER == "default":
    numba.config.THREADING_LAYER = "workqueue"

ALPHA_MIN = 1.0 / 255.0
ALPHA_MAX = 0.999
T_MIN = 1e-4

# columns of the per-Gaussian gradient buffer
G_MX, G_MY, G_A, G_B, G_C, G_OP, G_R, G_G, G_BL, G_Z, G_AX, G_AY = range(12)
N_GRAD = 12


@njit(cache=True)
@no_type_check  # keep the test-suite type-check hook away from numba
def bin_gaussians(means2d, radii, order, width, height, tile):
    """Tile lists: (offsets [n_tiles + 1], ids [total]) with each tile's Gaussians in ``order``
    (front to back). ``radii`` <= 0 marks culled Gaussians."""
    tx = (width + tile - 1) // tile
    ty = (height + tile - 1) // tile
    n_tiles = tx * ty
    counts = np.zeros(n_tiles + 1, np.int64)
    rect = np.empty((order.shape[0], 4), np.int64)
    for k in range(order.shape[0]):
        g = order[k]
        r = radii[g]
        if r <= 0:
            rect[k, 0] = 1
            rect[k, 1] = 0
            continue
        x0 = max(int(np.floor((means2d[g, 0] - r) / tile)), 0)
        x1 = min(int(np.floor((means2d[g, 0] + r) / tile)), tx - 1)
        y0 = max(int(np.floor((means2d[g, 1] - r) / tile)), 0)
        y1 = min(int(np.floor((means2d[g, 1] + r) / tile)), ty - 1)
        rect[k, 0], rect[k, 1], rect[k, 2], rect[k, 3] = x0, x1, y0, y1
        for yy in range(y0, y1 + 1):
            for xx in range(x0, x1 + 1):
                counts[yy * tx + xx + 1] += 1
    for t in range(n_tiles):
        counts[t + 1] += counts[t]
    fill = counts[:-1].copy()
    ids = np.empty(counts[n_tiles], np.int64)
    for k in range(order.shape[0]):
        if rect[k, 0] > rect[k, 1]:
            continue
        for yy in range(rect[k, 2], rect[k, 3] + 1):
            for xx in range(rect[k, 0], rect[k, 1] + 1):
                t = yy * tx + xx
                ids[fill[t]] = order[k]
                fill[t] += 1
    return counts, ids


@njit(cache=True, inline="always")
@no_type_check
def _span(m, r, lo, n):
    """Pixels p in [lo, lo + n) whose centre p + 0.5 lies in [m - r, m + r]: [a, b)."""
    a = max(lo, int(np.ceil(m - r - 0.5)))
    b = min(lo + n, int(np.floor(m + r - 0.5)) + 1)
    return a, b


@njit(cache=True, inline="always")
@no_type_check
def _p_min(op):
    """A bound below which op exp(p) < ALPHA_MIN for sure (a margin of 1e-6 under the exact
    log(ALPHA_MIN / op)): such pixels are skipped without an exp; the exact test after the exp
    still decides at the boundary, so the result is unchanged."""
    if op <= 0.0:
        return np.inf
    return np.log(ALPHA_MIN / op) - 1e-6


@njit(parallel=True, cache=True)
@no_type_check
def composite_forward(means2d, conics, opacities, colors, depths, radii, offsets, ids, width, height, tile,
                      out_rgb, out_depth, out_alpha, last):
    """Fill out_rgb [H, W, 3], out_depth [H, W] (sum of w z), out_alpha [H, W] and last [H, W]
    (index into ``ids`` of the last contributor, -1 if none).

    Gaussian-outer order within a tile: each Gaussian (front to back) visits only the tile's
    pixels inside its bounding square, so the work is the Gaussians' footprints, not
    pixels x list length; per-pixel state lives in small tile-local arrays."""
    tx = (width + tile - 1) // tile
    ty = (height + tile - 1) // tile
    for t in prange(tx * ty):
        t0, t1 = offsets[t], offsets[t + 1]
        px0 = (t % tx) * tile
        py0 = (t // tx) * tile
        tw = min(tile, width - px0)
        th = min(tile, height - py0)
        T = np.ones((th, tw))
        acc = np.zeros((th, tw, 4))
        lst = np.full((th, tw), -1, np.int64)
        done = np.zeros((th, tw), np.bool_)
        n_done = 0
        for j in range(t0, t1):
            if n_done == th * tw:
                break
            g = ids[j]
            mx, my, r = means2d[g, 0], means2d[g, 1], radii[g]
            xa, xb = _span(mx, r, px0, tw)
            ya, yb = _span(my, r, py0, th)
            if xa >= xb or ya >= yb:
                continue
            ca, cb, cc, op = conics[g, 0], conics[g, 1], conics[g, 2], opacities[g]
            c0, c1, c2, z = colors[g, 0], colors[g, 1], colors[g, 2], depths[g]
            p_min = _p_min(op)
            for py in range(ya, yb):
                dy = my - (py + 0.5)
                iy = py - py0
                for px in range(xa, xb):
                    ix = px - px0
                    if done[iy, ix]:
                        continue
                    dx = mx - (px + 0.5)
                    p = -0.5 * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
                    if p > 0.0 or p < p_min:
                        continue
                    a = min(ALPHA_MAX, op * np.exp(p))
                    if a < ALPHA_MIN:
                        continue
                    Tp = T[iy, ix]
                    nT = Tp * (1.0 - a)
                    if nT <= T_MIN:
                        done[iy, ix] = True
                        n_done += 1
                        continue
                    w = a * Tp
                    acc[iy, ix, 0] += w * c0
                    acc[iy, ix, 1] += w * c1
                    acc[iy, ix, 2] += w * c2
                    acc[iy, ix, 3] += w * z
                    T[iy, ix] = nT
                    lst[iy, ix] = j
        for iy in range(th):
            for ix in range(tw):
                out_rgb[py0 + iy, px0 + ix, 0] = acc[iy, ix, 0]
                out_rgb[py0 + iy, px0 + ix, 1] = acc[iy, ix, 1]
                out_rgb[py0 + iy, px0 + ix, 2] = acc[iy, ix, 2]
                out_depth[py0 + iy, px0 + ix] = acc[iy, ix, 3]
                out_alpha[py0 + iy, px0 + ix] = 1.0 - T[iy, ix]
                last[py0 + iy, px0 + ix] = lst[iy, ix]


@njit(parallel=True, cache=True)
@no_type_check
def composite_backward(means2d, conics, opacities, colors, depths, radii, offsets, ids, width, height, tile,
                       out_alpha, last, g_rgb, g_depth, g_alpha, n_chunks, grads):
    """Per-Gaussian gradients into ``grads`` [n_chunks, N, N_GRAD] (summed by the caller).
    Walks each tile's list back to front from its last contributor (3DGS's backward), each
    Gaussian over its footprint, accumulating its gradient locally before one write."""
    tx = (width + tile - 1) // tile
    ty = (height + tile - 1) // tile
    n_tiles = tx * ty
    for c in prange(n_chunks):
        buf = grads[c]
        for t in range(c, n_tiles, n_chunks):
            t0 = offsets[t]
            px0 = (t % tx) * tile
            py0 = (t // tx) * tile
            tw = min(tile, width - px0)
            th = min(tile, height - py0)
            jmax = -1
            for iy in range(th):
                for ix in range(tw):
                    jmax = max(jmax, last[py0 + iy, px0 + ix])
            if jmax < 0:
                continue
            T = np.empty((th, tw))  # transmittance behind the current Gaussian
            S = np.zeros((th, tw, 4))  # sums of w (r, g, b, z) of the Gaussians behind it
            for iy in range(th):
                for ix in range(tw):
                    T[iy, ix] = 1.0 - out_alpha[py0 + iy, px0 + ix]
            for j in range(jmax, t0 - 1, -1):
                g = ids[j]
                mx, my, r = means2d[g, 0], means2d[g, 1], radii[g]
                xa, xb = _span(mx, r, px0, tw)
                ya, yb = _span(my, r, py0, th)
                if xa >= xb or ya >= yb:
                    continue
                ca, cb, cc, op = conics[g, 0], conics[g, 1], conics[g, 2], opacities[g]
                cr, cg, cbl, z = colors[g, 0], colors[g, 1], colors[g, 2], depths[g]
                p_min = _p_min(op)
                a_mx = 0.0
                a_my = 0.0
                a_a = 0.0
                a_b = 0.0
                a_c = 0.0
                a_op = 0.0
                a_r = 0.0
                a_g = 0.0
                a_bl = 0.0
                a_z = 0.0
                a_ax = 0.0
                a_ay = 0.0
                hit = False
                for py in range(ya, yb):
                    dy = my - (py + 0.5)
                    iy = py - py0
                    for px in range(xa, xb):
                        if j > last[py, px]:
                            continue
                        ix = px - px0
                        dx = mx - (px + 0.5)
                        p = -0.5 * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
                        if p > 0.0 or p < p_min:
                            continue
                        G = np.exp(p)
                        a0 = op * G
                        a = min(ALPHA_MAX, a0)
                        if a < ALPHA_MIN:
                            continue
                        hit = True
                        Tf = 1.0 - out_alpha[py, px]
                        inv = 1.0 / (1.0 - a)
                        Tj = T[iy, ix] * inv
                        w = a * Tj
                        gr, ggr, gbl = g_rgb[py, px, 0], g_rgb[py, px, 1], g_rgb[py, px, 2]
                        gd, ga = g_depth[py, px], g_alpha[py, px]
                        a_r += gr * w
                        a_g += ggr * w
                        a_bl += gbl * w
                        a_z += gd * w
                        dl_da = (gr * (cr * Tj - S[iy, ix, 0] * inv) + ggr * (cg * Tj - S[iy, ix, 1] * inv)
                                 + gbl * (cbl * Tj - S[iy, ix, 2] * inv) + gd * (z * Tj - S[iy, ix, 3] * inv)
                                 + ga * Tf * inv)
                        S[iy, ix, 0] += cr * w
                        S[iy, ix, 1] += cg * w
                        S[iy, ix, 2] += cbl * w
                        S[iy, ix, 3] += z * w
                        T[iy, ix] = Tj
                        if a0 >= ALPHA_MAX:
                            continue  # clamped: no gradient to opacity or shape
                        a_op += dl_da * G
                        dl_dp = dl_da * a
                        gmx = -dl_dp * (ca * dx + cb * dy)
                        gmy = -dl_dp * (cc * dy + cb * dx)
                        a_mx += gmx
                        a_my += gmy
                        a_ax += abs(gmx)
                        a_ay += abs(gmy)
                        a_a += -0.5 * dl_dp * dx * dx
                        a_b += -dl_dp * dx * dy
                        a_c += -0.5 * dl_dp * dy * dy
                if hit:
                    buf[g, G_MX] += a_mx
                    buf[g, G_MY] += a_my
                    buf[g, G_A] += a_a
                    buf[g, G_B] += a_b
                    buf[g, G_C] += a_c
                    buf[g, G_OP] += a_op
                    buf[g, G_R] += a_r
                    buf[g, G_G] += a_g
                    buf[g, G_BL] += a_bl
                    buf[g, G_Z] += a_z
                    buf[g, G_AX] += a_ax
                    buf[g, G_AY] += a_ay
