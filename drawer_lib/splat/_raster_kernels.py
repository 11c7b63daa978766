"""Numba kernels of the tile-based Gaussian compositor (preparation, binning, forward, backward).

Conventions (gsplat's "classic" rasteriser): pixel (i, j) has its centre at (j + 0.5, i + 0.5);
a Gaussian with 2D mean m, conic (a, b, c) = inverse 2D covariance and opacity o contributes
alpha = min(0.999, o exp(p)), p = -0.5 (a dx^2 + c dy^2) - b dx dy, dx = m_x - x, dy = m_y - y;
contributions with p > 0 or alpha < 1/255 are skipped; compositing runs front to back and
stops before the Gaussian that would bring the transmittance to <= 1e-4.

Footprints: alpha >= 1/255 needs p >= p_min = log(1 / (255 o)) (taken 1e-6 lower), i.e. the
pixel centre inside the ellipse Q = a dx^2 + 2 b dx dy + c dy^2 <= K = -2 p_min. A Gaussian is
binned to the tiles its ellipse's bounding box touches, and in each row of a tile it visits only
the pixels whose centres lie in the ellipse's chord (solved from the quadratic, widened by a
relative 1e-6 of K); the exact per-pixel test after the exp still decides, so the image is the
plain front-to-back definition, independent of tiles and footprints.

Per-pixel state and arithmetic are float64 (inputs float32 or float64). Every Gaussian is copied
once, in depth order, into a packed float64 row (``P``) so that a tile list walks contiguous
memory. Tiles are dealt to the workers by longest-processing-time first (forward: by footprint
area; backward: by the pixel visits the forward pass counted), a deterministic assignment.
Backward writes one gradient row per (tile, Gaussian) list entry and a second pass sums each
Gaussian's entries in tile order: no atomics, no races, and the result does not depend on the
number of threads or on timing.
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

# columns of the packed per-Gaussian rows P [M, N_P] (M visible Gaussians in depth order)
P_MX, P_MY, P_A, P_B, P_C, P_OP, P_R, P_G, P_BL, P_Z, P_PMIN, P_K, P_RX, P_RY, P_ELL = range(15)
N_P = 15
# columns of the per-entry gradient rows
G_MX, G_MY, G_A, G_B, G_C, G_OP, G_R, G_G, G_BL, G_Z, G_AX, G_AY = range(12)
N_GRAD = 12
EPS_PX = 1e-9  # pixels: widening of the footprint spans against rounding (the exact test decides)


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
def footprints(means2d, conics, opacities, radii, ext):
    """Per Gaussian: ext [N, 4] float64 = (K, rx, ry, ellipse flag); rx = ry = 0 marks a Gaussian
    that cannot pass alpha >= 1/255 anywhere (culled: ``radii`` <= 0, o < 1/255, non-finite).
    rx, ry (pixels) are the half-sizes of the bounding box of the ellipse Q <= K (widened);
    where the conic is not positive definite (flag 0) the box is the old square bound
    sqrt(K / lambda_min(conic)) and rows are not cut to the ellipse."""
    for n in prange(means2d.shape[0]):
        ext[n, 0] = 0.0
        ext[n, 1] = 0.0
        ext[n, 2] = 0.0
        ext[n, 3] = 0.0
        op = float(opacities[n])
        if radii[n] <= 0 or not (op >= ALPHA_MIN):
            continue
        a, b, c = float(conics[n, 0]), float(conics[n, 1]), float(conics[n, 2])
        mx, my = float(means2d[n, 0]), float(means2d[n, 1])
        if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(c) and np.isfinite(mx) and np.isfinite(my)):
            continue
        K = -2.0 * _p_min(op)
        Kw = K + 1e-6 * (1.0 + K)
        det = a * c - b * b
        if a > 0.0 and c > 0.0 and det > 0.0:
            rx = np.sqrt(Kw * c / det) * (1.0 + 1e-9) + EPS_PX
            ry = np.sqrt(Kw * a / det) * (1.0 + 1e-9) + EPS_PX
            flag = 1.0
        else:
            mid = 0.5 * (a + c)
            lam = mid - np.sqrt(max(mid * mid - det, 0.0))
            if not (lam > 0.0):
                continue
            rx = np.sqrt(Kw / lam) * (1.0 + 1e-9) + EPS_PX
            ry = rx
            flag = 0.0
        if not (rx < 1e7 and ry < 1e7):
            rx = min(rx, 1e7)
            ry = min(ry, 1e7)
        ext[n, 0] = K
        ext[n, 1] = rx
        ext[n, 2] = ry
        ext[n, 3] = flag


@njit(cache=True, inline="always")
@no_type_check
def _pix_range(m, r, lo, n):
    """Pixels p in [lo, lo + n) whose centre p + 0.5 lies in [m - r, m + r] (m, r float64): [a, b)."""
    fa = max(float(lo), np.ceil(m - r - 0.5))
    fb = min(float(lo + n), np.floor(m + r - 0.5) + 1.0)
    return int(fa), int(max(fb, fa))


@njit(cache=True, inline="always")
@no_type_check
def _row_range(P, k, dy, px0, tw):
    """Pixels [a, b) of the row at offset dy = m_y - (y + 0.5) within [px0, px0 + tw) whose centres
    lie in the (widened) ellipse chord of packed Gaussian k."""
    mx = P[k, P_MX]
    if P[k, P_ELL] == 0.0:
        return _pix_range(mx, P[k, P_RX], px0, tw)
    a, b, c = P[k, P_A], P[k, P_B], P[k, P_C]
    Kw = P[k, P_K] + 1e-6 * (1.0 + P[k, P_K])
    disc = dy * dy * (b * b - a * c) + a * Kw
    if disc < 0.0:
        return px0, px0
    s = np.sqrt(disc)
    lo = (-b * dy - s) / a  # dx range
    hi = (-b * dy + s) / a
    w = EPS_PX + 1e-12 * (abs(mx) + abs(lo) + abs(hi))
    fa = max(float(px0), np.ceil(mx - hi - 0.5 - w))
    fb = min(float(px0 + tw), np.floor(mx - lo - 0.5 + w) + 1.0)
    return int(fa), int(max(fb, fa))


@njit(parallel=True, cache=True)
@no_type_check
def pack(order, means2d, conics, opacities, colors, depths, ext, P):
    """P [M, N_P] float64: the Gaussians ``order`` [M] (visible, front to back) packed."""
    for k in prange(order.shape[0]):
        g = order[k]
        P[k, P_MX] = means2d[g, 0]
        P[k, P_MY] = means2d[g, 1]
        P[k, P_A] = conics[g, 0]
        P[k, P_B] = conics[g, 1]
        P[k, P_C] = conics[g, 2]
        P[k, P_OP] = opacities[g]
        P[k, P_R] = colors[g, 0]
        P[k, P_G] = colors[g, 1]
        P[k, P_BL] = colors[g, 2]
        P[k, P_Z] = depths[g]
        P[k, P_PMIN] = _p_min(float(opacities[g]))
        P[k, P_K] = ext[g, 0]
        P[k, P_RX] = ext[g, 1]
        P[k, P_RY] = ext[g, 2]
        P[k, P_ELL] = ext[g, 3]


@njit(cache=True)
@no_type_check
def bin_gaussians(P, width, height, tile):
    """Tile lists of the packed Gaussians P [M, N_P] (front to back): (offsets [n_tiles + 1],
    ids [E] indices into P, g_offsets [M + 1] and g_entries [E]: each Gaussian's list entries in
    tile order, cost [n_tiles] float64: summed footprint-box areas, pixels)."""
    tx = (width + tile - 1) // tile
    ty = (height + tile - 1) // tile
    n_tiles = tx * ty
    M = P.shape[0]
    counts = np.zeros(n_tiles + 1, np.int64)
    cost = np.zeros(n_tiles)
    rect = np.empty((M, 4), np.int64)  # pixel box [x0, x1) x [y0, y1)
    g_off = np.zeros(M + 1, np.int64)
    for k in range(M):
        x0, x1 = _pix_range(P[k, P_MX], P[k, P_RX], 0, width)
        y0, y1 = _pix_range(P[k, P_MY], P[k, P_RY], 0, height)
        if x0 >= x1 or y0 >= y1:
            x1 = x0
        rect[k, 0], rect[k, 1], rect[k, 2], rect[k, 3] = x0, x1, y0, y1
        n = 0
        if x0 < x1:
            for yy in range(y0 // tile, (y1 - 1) // tile + 1):
                ya, yb = max(y0, yy * tile), min(y1, (yy + 1) * tile)
                for xx in range(x0 // tile, (x1 - 1) // tile + 1):
                    xa, xb = max(x0, xx * tile), min(x1, (xx + 1) * tile)
                    counts[yy * tx + xx + 1] += 1
                    cost[yy * tx + xx] += (xb - xa) * (yb - ya)
                    n += 1
        g_off[k + 1] = g_off[k] + n
    for t in range(n_tiles):
        counts[t + 1] += counts[t]
    fill = counts[:-1].copy()
    ids = np.empty(counts[n_tiles], np.int64)
    g_ent = np.empty(g_off[M], np.int64)
    for k in range(M):
        x0, x1, y0, y1 = rect[k, 0], rect[k, 1], rect[k, 2], rect[k, 3]
        if x0 >= x1:
            continue
        i = g_off[k]
        for yy in range(y0 // tile, (y1 - 1) // tile + 1):
            for xx in range(x0 // tile, (x1 - 1) // tile + 1):
                t = yy * tx + xx
                ids[fill[t]] = k
                g_ent[i] = fill[t]
                i += 1
                fill[t] += 1
    return counts, ids, g_off, g_ent, cost


@njit(cache=True)
@no_type_check
def assign_tiles(cost, n_workers):
    """Longest processing time first: tiles sorted by ``cost`` (descending, ties by index), each
    given to the least loaded worker (ties: the lowest). Returns (w_offsets [n_workers + 1],
    w_tiles [n_tiles]): worker w runs w_tiles[w_offsets[w]:w_offsets[w + 1]] in that order."""
    n = cost.shape[0]
    order = np.argsort(-cost, kind="mergesort")
    load = np.zeros(n_workers)
    owner = np.empty(n, np.int64)
    cnt = np.zeros(n_workers + 1, np.int64)
    for i in range(n):
        w = 0
        for v in range(1, n_workers):
            if load[v] < load[w]:
                w = v
        owner[i] = w
        load[w] += cost[order[i]] + 1.0
        cnt[w + 1] += 1
    for w in range(n_workers):
        cnt[w + 1] += cnt[w]
    fill = cnt[:-1].copy()
    tiles = np.empty(n, np.int64)
    for i in range(n):
        tiles[fill[owner[i]]] = order[i]
        fill[owner[i]] += 1
    return cnt, tiles


@njit(parallel=True, cache=True)
@no_type_check
def composite_forward(P, offsets, ids, w_off, w_tiles, width, height, tile,
                      out_rgb, out_depth, out_alpha, T_final, last, work):
    """Fill out_rgb [H, W, 3], out_depth [H, W] (sum of w z), out_alpha [H, W], T_final [H, W]
    (float64 final transmittance), last [H, W] (index into ``ids`` of the last contributor, -1
    if none) and work [n_tiles] (pixel visits, the backward pass's cost estimate).

    Gaussian-outer order within a tile: each Gaussian (front to back) visits only the tile's
    pixels inside its footprint ellipse; per-pixel state lives in small tile-local arrays."""
    tx = (width + tile - 1) // tile
    for w in prange(w_off.shape[0] - 1):
        T = np.empty((tile, tile))
        acc = np.empty((tile, tile, 4))
        lst = np.empty((tile, tile), np.int64)
        done = np.empty((tile, tile), np.bool_)
        for it in range(w_off[w], w_off[w + 1]):
            t = w_tiles[it]
            t0, t1 = offsets[t], offsets[t + 1]
            px0 = (t % tx) * tile
            py0 = (t // tx) * tile
            tw = min(tile, width - px0)
            th = min(tile, height - py0)
            T[:] = 1.0
            acc[:] = 0.0
            lst[:] = -1
            done[:] = False
            n_done = 0
            visits = 0
            for j in range(t0, t1):
                if n_done == th * tw:
                    break
                k = ids[j]
                mx, my = P[k, P_MX], P[k, P_MY]
                ya, yb = _pix_range(my, P[k, P_RY], py0, th)
                if ya >= yb:
                    continue
                ca, cb, cc, op = P[k, P_A], P[k, P_B], P[k, P_C], P[k, P_OP]
                c0, c1, c2, z = P[k, P_R], P[k, P_G], P[k, P_BL], P[k, P_Z]
                p_min = P[k, P_PMIN]
                for py in range(ya, yb):
                    dy = my - (py + 0.5)
                    xa, xb = _row_range(P, k, dy, px0, tw)
                    iy = py - py0
                    visits += xb - xa
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
                        wt = a * Tp
                        acc[iy, ix, 0] += wt * c0
                        acc[iy, ix, 1] += wt * c1
                        acc[iy, ix, 2] += wt * c2
                        acc[iy, ix, 3] += wt * z
                        T[iy, ix] = nT
                        lst[iy, ix] = j
            work[t] = visits
            for iy in range(th):
                for ix in range(tw):
                    out_rgb[py0 + iy, px0 + ix, 0] = acc[iy, ix, 0]
                    out_rgb[py0 + iy, px0 + ix, 1] = acc[iy, ix, 1]
                    out_rgb[py0 + iy, px0 + ix, 2] = acc[iy, ix, 2]
                    out_depth[py0 + iy, px0 + ix] = acc[iy, ix, 3]
                    out_alpha[py0 + iy, px0 + ix] = 1.0 - T[iy, ix]
                    T_final[py0 + iy, px0 + ix] = T[iy, ix]
                    last[py0 + iy, px0 + ix] = lst[iy, ix]


@njit(parallel=True, cache=True)
@no_type_check
def composite_backward(P, offsets, ids, w_off, w_tiles, width, height, tile, T_final, last, g_rgb, g_depth, g_alpha,
                       gbuf):
    """Per list entry j gradients into ``gbuf`` [E, N_GRAD] (float64; rows of entries behind a
    tile's last contributor are zero). Walks each tile's list back to front from its last
    contributor (3DGS's backward), each Gaussian over its footprint, accumulating its gradient
    locally before one write."""
    tx = (width + tile - 1) // tile
    for w in prange(w_off.shape[0] - 1):
        Tt = np.empty((tile, tile))  # transmittance behind the current Gaussian
        U = np.empty((tile, tile))  # sum over the Gaussians behind it of w (dL/dout . (r, g, b, z))
        Gp = np.empty((tile, tile, 5))  # the pixel's dL/d(r, g, b, depth) and dL/dalpha T_final
        for it in range(w_off[w], w_off[w + 1]):
            t = w_tiles[it]
            t0, t1 = offsets[t], offsets[t + 1]
            px0 = (t % tx) * tile
            py0 = (t // tx) * tile
            tw = min(tile, width - px0)
            th = min(tile, height - py0)
            jmax = -1
            for iy in range(th):
                for ix in range(tw):
                    jmax = max(jmax, last[py0 + iy, px0 + ix])
                    Tt[iy, ix] = T_final[py0 + iy, px0 + ix]
                    U[iy, ix] = 0.0
                    Gp[iy, ix, 0] = g_rgb[py0 + iy, px0 + ix, 0]
                    Gp[iy, ix, 1] = g_rgb[py0 + iy, px0 + ix, 1]
                    Gp[iy, ix, 2] = g_rgb[py0 + iy, px0 + ix, 2]
                    Gp[iy, ix, 3] = g_depth[py0 + iy, px0 + ix]
                    Gp[iy, ix, 4] = g_alpha[py0 + iy, px0 + ix] * T_final[py0 + iy, px0 + ix]
            for j in range(max(jmax + 1, t0), t1):
                for q in range(N_GRAD):
                    gbuf[j, q] = 0.0
            for j in range(jmax, t0 - 1, -1):
                k = ids[j]
                for q in range(N_GRAD):
                    gbuf[j, q] = 0.0
                mx, my = P[k, P_MX], P[k, P_MY]
                ya, yb = _pix_range(my, P[k, P_RY], py0, th)
                if ya >= yb:
                    continue
                ca, cb, cc, op = P[k, P_A], P[k, P_B], P[k, P_C], P[k, P_OP]
                cr, cg, cbl, z = P[k, P_R], P[k, P_G], P[k, P_BL], P[k, P_Z]
                p_min = P[k, P_PMIN]
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
                for py in range(ya, yb):
                    dy = my - (py + 0.5)
                    xa, xb = _row_range(P, k, dy, px0, tw)
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
                        inv = 1.0 / (1.0 - a)
                        Tj = Tt[iy, ix] * inv
                        wt = a * Tj
                        gr, ggr, gbl, gd = Gp[iy, ix, 0], Gp[iy, ix, 1], Gp[iy, ix, 2], Gp[iy, ix, 3]
                        a_r += gr * wt
                        a_g += ggr * wt
                        a_bl += gbl * wt
                        a_z += gd * wt
                        gc = gr * cr + ggr * cg + gbl * cbl + gd * z
                        # d out / d alpha_j = T_j c_j - (sum behind of w c) / (1 - alpha_j), dotted with dL/dout
                        dl_da = gc * Tj + (Gp[iy, ix, 4] - U[iy, ix]) * inv
                        U[iy, ix] += gc * wt
                        Tt[iy, ix] = Tj
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
                gbuf[j, G_MX] = a_mx
                gbuf[j, G_MY] = a_my
                gbuf[j, G_A] = a_a
                gbuf[j, G_B] = a_b
                gbuf[j, G_C] = a_c
                gbuf[j, G_OP] = a_op
                gbuf[j, G_R] = a_r
                gbuf[j, G_G] = a_g
                gbuf[j, G_BL] = a_bl
                gbuf[j, G_Z] = a_z
                gbuf[j, G_AX] = a_ax
                gbuf[j, G_AY] = a_ay


@njit(parallel=True, cache=True)
@no_type_check
def reduce_gradients(order, g_off, g_ent, gbuf, g_means2d, g_conics, g_opac, g_colors, g_depths, absgrad):
    """Sum each packed Gaussian's entry rows (in tile order) into the per-Gaussian outputs
    g_means2d [N, 2], g_conics [N, 3], g_opac [N], g_colors [N, 3], g_depths [N] (all zeroed
    first, so Gaussians not in ``order`` get 0) and add |.| sums to absgrad [N, 2] (if N > 0 rows)."""
    N = g_means2d.shape[0]
    for g in prange(N):
        g_means2d[g, 0] = 0.0
        g_means2d[g, 1] = 0.0
        g_conics[g, 0] = 0.0
        g_conics[g, 1] = 0.0
        g_conics[g, 2] = 0.0
        g_opac[g] = 0.0
        g_colors[g, 0] = 0.0
        g_colors[g, 1] = 0.0
        g_colors[g, 2] = 0.0
        g_depths[g] = 0.0
    has_abs = absgrad.shape[0] == N
    for k in prange(order.shape[0]):
        s = np.zeros(N_GRAD)
        for i in range(g_off[k], g_off[k + 1]):
            e = g_ent[i]
            for q in range(N_GRAD):
                s[q] += gbuf[e, q]
        g = order[k]
        g_means2d[g, 0] = s[G_MX]
        g_means2d[g, 1] = s[G_MY]
        g_conics[g, 0] = s[G_A]
        g_conics[g, 1] = s[G_B]
        g_conics[g, 2] = s[G_C]
        g_opac[g] = s[G_OP]
        g_colors[g, 0] = s[G_R]
        g_colors[g, 1] = s[G_G]
        g_colors[g, 2] = s[G_BL]
        g_depths[g] = s[G_Z]
        if has_abs:
            absgrad[g, 0] += s[G_AX]
            absgrad[g, 1] += s[G_AY]
