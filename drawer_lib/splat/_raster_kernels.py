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
The forward pass records each contribution (its exp(p) and pixel), so the backward pass walks
exactly those, without the footprint rows, the tests or the exponentials (the same numbers, so
the same gradients as recomputing them, which it still does when there is no record).
Backward writes one gradient row per (tile, Gaussian) list entry, each Gaussian's rows
adjacent, and a second pass sums each Gaussian's rows in tile order: no atomics, no races, and
the result does not depend on the number of threads or on timing.
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


@njit(cache=True, inline="always")
@no_type_check
def _weight(ca, cb, cc, op, p_min, dx, dy):
    """exp(p), p = -(a dx^2 + 2 b dx dy + c dy^2) / 2, of a Gaussian (conic a, b, c, opacity op,
    ``_p_min`` bound p_min) at offset (dx, dy) of a pixel centre from its mean, when that pixel
    takes a contribution from it (p <= 0 and min(ALPHA_MAX, op exp(p)) >= ALPHA_MIN); else 0.0
    (a contribution's exp(p) is never 0: p >= p_min > -inf). The one test of the forward pass
    and of the recomputing backward, so the two agree on every contribution."""
    p = -0.5 * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
    if p > 0.0 or p < p_min:
        return 0.0
    G = np.exp(p)
    if min(ALPHA_MAX, op * G) < ALPHA_MIN:
        return 0.0
    return G


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


@njit(cache=True, inline="always")
@no_type_check
def _tile_box(t, tx, tile, width, height):
    """Tile t's pixel origin and size (tx tiles per row; the last row / column may be cut): px0, py0, tw, th."""
    px0 = (t % tx) * tile
    py0 = (t // tx) * tile
    return px0, py0, min(tile, width - px0), min(tile, height - py0)


@njit(cache=True, inline="always")
@no_type_check
def _row_spans(P, k, px0, py0, tw, th, rxa, rxb):
    """Packed Gaussian k's rows [ya, yb) in the tile, each row's pixel span [rxa, rxb)[py - py0]
    (filled first: the rows are independent, so they pipeline) and the pixels they hold in all."""
    my = P[k, P_MY]
    ya, yb = _pix_range(my, P[k, P_RY], py0, th)
    n = 0
    for py in range(ya, yb):
        rxa[py - py0], rxb[py - py0] = _row_range(P, k, my - (py + 0.5), px0, tw)
        n += rxb[py - py0] - rxa[py - py0]
    return ya, yb, n


@njit(cache=True)
@no_type_check
def depth_order(vis, depths):
    """``vis`` [M] (int64) stably sorted by ``depths[vis]`` (float32 or float64): the same order as
    ``vis[np.argsort(depths[vis], kind="stable")]``, NaNs last, -0.0 equal to 0.0, by an LSD
    radix sort on the depths' bits mapped to unsigned integers of the same order (11-bit
    digits; digits that all keys share are skipped)."""
    M = vis.shape[0]
    nbits = 8 * depths.itemsize
    key = np.empty(M, np.uint64)
    top = np.uint64(1) << np.uint64(nbits - 1)
    full = (np.uint64(1) << np.uint64(nbits)) - np.uint64(1) if nbits < 64 else ~np.uint64(0)
    for i in range(M):
        d = depths[vis[i]]
        if np.isnan(d):
            key[i] = full
            continue
        if nbits == 32:
            u = np.uint64(np.float32(d + np.float32(0.0)).view(np.uint32))
        else:
            u = np.float64(d + 0.0).view(np.uint64)
        key[i] = (full ^ u) if (u & top) != np.uint64(0) else (u | top)
    out = vis.copy()
    tmp_k = np.empty(M, np.uint64)
    tmp_o = np.empty(M, np.int64)
    cnt = np.empty(2049, np.int64)
    shift = 0
    while shift < nbits:
        cnt[:] = 0
        for i in range(M):
            cnt[((key[i] >> np.uint64(shift)) & np.uint64(2047)) + np.uint64(1)] += 1
        if cnt.max() < M:  # (a digit shared by every key leaves the order as it is)
            for b in range(2048):
                cnt[b + 1] += cnt[b]
            for i in range(M):
                b = (key[i] >> np.uint64(shift)) & np.uint64(2047)
                tmp_k[cnt[b]] = key[i]
                tmp_o[cnt[b]] = out[i]
                cnt[b] += 1
            key, tmp_k = tmp_k, key
            out, tmp_o = tmp_o, out
        shift += 11
    return out


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
    ids [E] indices into P, g_offsets [M + 1] and slot [E]: packed Gaussian k's list entries,
    in tile order, have the slots g_offsets[k] .. g_offsets[k + 1] - 1 (entry j has slot[j]),
    cost [n_tiles] float64: summed footprint-box areas, pixels)."""
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
    slot = np.empty(g_off[M], np.int64)
    for k in range(M):
        x0, x1, y0, y1 = rect[k, 0], rect[k, 1], rect[k, 2], rect[k, 3]
        if x0 >= x1:
            continue
        i = g_off[k]
        for yy in range(y0 // tile, (y1 - 1) // tile + 1):
            for xx in range(x0 // tile, (x1 - 1) // tile + 1):
                t = yy * tx + xx
                ids[fill[t]] = k
                slot[fill[t]] = i
                i += 1
                fill[t] += 1
    return counts, ids, g_off, slot, cost


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
                      out_rgb, out_depth, out_alpha, T_final, last, work, v_off, vspan, rec_g, rec_q, rec_ok):
    """Fill out_rgb [H, W, 3], out_depth [H, W] (sum of w z), out_alpha [H, W], T_final [H, W]
    (float64 final transmittance), last [H, W] (index into ``ids`` of the last contributor, -1
    if none) and work [n_tiles] (pixel visits, the backward pass's cost estimate).

    Gaussian-outer order within a tile: each Gaussian (front to back) visits only the tile's
    pixels inside its footprint ellipse; per-pixel state lives in small tile-local arrays.

    Contribution record for the backward pass (off when ``rec_g`` is empty): every visit that
    contributes (passes the tests and updates the pixel) appends exp(p) to rec_g (float64) and
    the pixel's place in the tile, iy 2^16 + ix, to rec_q (int32), in visiting order. Tile t
    writes [v_off[t], v_off[t + 1]) (v_off [n_tiles + 1]: the cumulated footprint-box areas of
    ``bin_gaussians``, a bound of its visits), entry j its [vspan[j, 0], vspan[j, 1]) (vspan
    [E, 2], set for the entries visited). rec_ok[t] ([n_tiles] bool) is False where a tile's
    visits did not fit (not expected: the ellipse chords lie in the boxes); its backward then
    recomputes."""
    tx = (width + tile - 1) // tile
    record = rec_g.shape[0] > 0
    for w in prange(w_off.shape[0] - 1):
        T = np.empty((tile, tile))
        acc = np.empty((tile, tile, 4))
        lst = np.empty((tile, tile), np.int64)
        done = np.empty((tile, tile), np.bool_)
        rxa = np.empty(tile, np.int64)  # the current Gaussian's pixel span [rxa, rxb) in each tile row
        rxb = np.empty(tile, np.int64)
        for it in range(w_off[w], w_off[w + 1]):
            t = w_tiles[it]
            t0, t1 = offsets[t], offsets[t + 1]
            px0, py0, tw, th = _tile_box(t, tx, tile, width, height)
            T[:] = 1.0
            acc[:] = 0.0
            lst[:] = -1
            done[:] = False
            n_done = 0
            visits = 0
            rec_t = record
            v = v_off[t] if record else 0
            v_end = v_off[t + 1] if record else 0
            for j in range(t0, t1):
                if n_done == th * tw:
                    break
                k = ids[j]
                if rec_t:
                    vspan[j, 0] = v
                    vspan[j, 1] = v
                mx, my = P[k, P_MX], P[k, P_MY]
                ya, yb, n_vis = _row_spans(P, k, px0, py0, tw, th, rxa, rxb)
                if ya >= yb:
                    continue
                ca, cb, cc, op = P[k, P_A], P[k, P_B], P[k, P_C], P[k, P_OP]
                c0, c1, c2, z = P[k, P_R], P[k, P_G], P[k, P_BL], P[k, P_Z]
                p_min = P[k, P_PMIN]
                visits += n_vis
                if rec_t and v + n_vis > v_end:
                    rec_t = False
                for py in range(ya, yb):
                    dy = my - (py + 0.5)
                    iy = py - py0
                    for px in range(rxa[iy], rxb[iy]):
                        ix = px - px0
                        if done[iy, ix]:
                            continue
                        G = _weight(ca, cb, cc, op, p_min, mx - (px + 0.5), dy)
                        if G == 0.0:
                            continue
                        a = min(ALPHA_MAX, op * G)
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
                        if rec_t:
                            rec_g[v] = G
                            rec_q[v] = (iy << 16) | ix
                            v += 1
                if rec_t:
                    vspan[j, 1] = v
            work[t] = visits
            if record:
                rec_ok[t] = rec_t
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
def composite_backward(P, offsets, ids, slot, w_off, w_tiles, width, height, tile, T_final, last, g_rgb, g_depth,
                       g_alpha, gbuf, vspan, rec_g, rec_q, rec_ok):
    """Per list entry j gradients into ``gbuf`` [E, N_GRAD] row slot[j] (float64; so that each
    Gaussian's rows are adjacent, ``bin_gaussians``; rows of entries behind a tile's last
    contributor are zero). Walks each tile's list back to front from its last
    contributor (3DGS's backward), each Gaussian over the pixels it contributed to (in the
    forward pass's order), accumulating its gradient locally before one write. Those pixels and
    their exp(p) come from the forward pass's record (``vspan``, ``rec_g``, ``rec_q``, ``rec_ok``
    of :func:`composite_forward`); without one (``rec_g`` empty, or a tile whose record did not
    fit) they are found again by the same tests: the same numbers either way, so the same
    gradients to the bit."""
    tx = (width + tile - 1) // tile
    use_all = rec_g.shape[0] > 0
    for w in prange(w_off.shape[0] - 1):
        Tt = np.empty((tile, tile))  # transmittance behind the current Gaussian
        U = np.empty((tile, tile))  # sum over the Gaussians behind it of w (dL/dout . (r, g, b, z))
        Gp = np.empty((tile, tile, 5))  # the pixel's dL/d(r, g, b, depth) and dL/dalpha T_final
        rxa = np.empty(tile, np.int64)  # (recomputing) the current Gaussian's pixel span in each tile row
        rxb = np.empty(tile, np.int64)
        own_g = np.empty(tile * tile)  # (recomputing) its contributions: exp(p) and pixel index
        own_q = np.empty(tile * tile, np.int32)
        for it in range(w_off[w], w_off[w + 1]):
            t = w_tiles[it]
            t0, t1 = offsets[t], offsets[t + 1]
            px0, py0, tw, th = _tile_box(t, tx, tile, width, height)
            use = use_all and rec_ok[t]
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
                    gbuf[slot[j], q] = 0.0
            for j in range(jmax, t0 - 1, -1):
                k = ids[j]
                mx, my = P[k, P_MX], P[k, P_MY]
                ca, cb, cc, op = P[k, P_A], P[k, P_B], P[k, P_C], P[k, P_OP]
                cr, cg, cbl, z = P[k, P_R], P[k, P_G], P[k, P_BL], P[k, P_Z]
                if use:
                    src_g, src_q, c_a, c_b = rec_g, rec_q, vspan[j, 0], vspan[j, 1]
                else:
                    ya, yb, _ = _row_spans(P, k, px0, py0, tw, th, rxa, rxb)
                    p_min = P[k, P_PMIN]
                    n = 0
                    for py in range(ya, yb):
                        dy = my - (py + 0.5)
                        iy = py - py0
                        for px in range(rxa[iy], rxb[iy]):
                            if j > last[py, px]:
                                continue
                            G = _weight(ca, cb, cc, op, p_min, mx - (px + 0.5), dy)
                            if G == 0.0:
                                continue
                            own_g[n] = G
                            own_q[n] = (iy << 16) | (px - px0)
                            n += 1
                    src_g, src_q, c_a, c_b = own_g, own_q, 0, n
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
                for c in range(c_a, c_b):
                    q = src_q[c]
                    iy = q >> 16
                    ix = q & 0xFFFF
                    G = src_g[c]
                    dx = mx - (px0 + ix + 0.5)
                    dy = my - (py0 + iy + 0.5)
                    a0 = op * G
                    a = min(ALPHA_MAX, a0)
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
                r = slot[j]
                gbuf[r, G_MX] = a_mx
                gbuf[r, G_MY] = a_my
                gbuf[r, G_A] = a_a
                gbuf[r, G_B] = a_b
                gbuf[r, G_C] = a_c
                gbuf[r, G_OP] = a_op
                gbuf[r, G_R] = a_r
                gbuf[r, G_G] = a_g
                gbuf[r, G_BL] = a_bl
                gbuf[r, G_Z] = a_z
                gbuf[r, G_AX] = a_ax
                gbuf[r, G_AY] = a_ay


@njit(parallel=True, cache=True)
@no_type_check
def reduce_gradients(order, g_off, gbuf, g_means2d, g_conics, g_opac, g_colors, g_depths, absgrad):
    """Sum each packed Gaussian's gradient rows (adjacent in ``gbuf``, in tile order:
    ``bin_gaussians``) into the per-Gaussian outputs g_means2d [N, 2], g_conics [N, 3], g_opac
    [N], g_colors [N, 3], g_depths [N] (all zeroed first, so Gaussians not in ``order`` get 0)
    and add |.| sums to absgrad [N, 2] (if N > 0 rows)."""
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
        s_mx = 0.0
        s_my = 0.0
        s_a = 0.0
        s_b = 0.0
        s_c = 0.0
        s_op = 0.0
        s_r = 0.0
        s_g = 0.0
        s_bl = 0.0
        s_z = 0.0
        s_ax = 0.0
        s_ay = 0.0
        for i in range(g_off[k], g_off[k + 1]):
            s_mx += gbuf[i, G_MX]
            s_my += gbuf[i, G_MY]
            s_a += gbuf[i, G_A]
            s_b += gbuf[i, G_B]
            s_c += gbuf[i, G_C]
            s_op += gbuf[i, G_OP]
            s_r += gbuf[i, G_R]
            s_g += gbuf[i, G_G]
            s_bl += gbuf[i, G_BL]
            s_z += gbuf[i, G_Z]
            s_ax += gbuf[i, G_AX]
            s_ay += gbuf[i, G_AY]
        g = order[k]
        g_means2d[g, 0] = s_mx
        g_means2d[g, 1] = s_my
        g_conics[g, 0] = s_a
        g_conics[g, 1] = s_b
        g_conics[g, 2] = s_c
        g_opac[g] = s_op
        g_colors[g, 0] = s_r
        g_colors[g, 1] = s_g
        g_colors[g, 2] = s_bl
        g_depths[g] = s_z
        if has_abs:
            absgrad[g, 0] += s_ax
            absgrad[g, 1] += s_ay
