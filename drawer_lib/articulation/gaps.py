"""Split a front that holds several: the gap lines of the rectified front.

A detector that merges touching fronts in most views (a drawer stack as one mask, a double door,
a whole base run) leaves one segment, hence one rectangle, over several fronts; multi-view
voting cannot undo it. Two kinds of evidence on the front rectified from every view
(:mod:`~drawer_lib.articulation.rectify`, a few millimetres per cell) still show where one front
ends and the next begins:

- the instance masks: in the views where the detector did not merge them, a mask boundary runs
  along the gap (a cell pair in different masks, each handle counted as its front's, in at least
  ``boundary_rate`` of the views that saw both: strong; in ``boundary_rate_handles`` of them:
  weak; give or take ``slack`` cells, since masks are ragged by a pixel or two);
- the image: a gap is a straight line lighter or darker than the panels on both sides (a cell
  whose grey level differs from the mean of the cells ``step`` to either side by more than
  max(``contrast``, ``texture_k`` x the median such difference over the front: its texture),
  give or take one cell); it cuts only between two handles (the detector merged the pair in
  every view: the gap and the two handles show it).

:func:`xy_cuts` cuts the rectangle recursively (an XY-cut): a cut is the row or column of the
current piece whose strong boundary cells cover at least ``coverage`` of each third of the
piece's span (or, with handle cells on both sides of it, whose weak boundary or image line
cells cover ``coverage_handles``),
at least ``min_piece`` from the piece's edges and crossing no handle cell; the best-covered one wins, and both sides are cut again (up
to ``max_depth``). A tile joint or a wood grain has no mask along it and no handle either side,
nor has the end of a false detection that happens to cross a thin drawer in a few views;
a shaker frame lies within ``min_piece`` of an edge; a handle does not span a front. A front
wider than ``max_width`` is several (no kitchen front is that wide): there a vertical line needs
no handles either side, and one is cut at its best line all the same; one with no line at all is
cut into pieces of equal width near ``wide_even`` (a run of modules of one width).
Shapes: grids are [Gv, Gu], v bottom -> top, u left -> right.
"""

from typing import NamedTuple

import numpy as np

from drawer_lib.articulation.config import SplitConfig
from drawer_lib.articulation.fronts import sub_front
from drawer_lib.articulation.interaction import front_coords
from drawer_lib.articulation.rectify import RectifiedFront
from drawer_lib.io.parts import Front

Piece = tuple[int, int, int, int]  # (u0, u1, v0, v1): cell ranges, end exclusive


class Clearance(NamedTuple):
    """How far a piece's best gap line is from being cut or left (:func:`_best_cut`)."""

    at: int  # the column (cell) of the best-cleared line
    margin: float  # its coverage clearance, a share of a third of the span (>= 0: cut)
    band: float  # one cell's share of the shortest third

    def near(self) -> bool:
        """One cell seen the other way could turn it: cut by less than a band, or short by one at most."""
        return -1 - 1e-6 <= self.margin / self.band < 1 - 1e-6


def line_cells(gray: np.ndarray, step: int, contrast: float, texture_k: float) -> tuple[np.ndarray, np.ndarray]:
    """(across_u, across_v) bool [Gv, Gu]: cells whose grey level differs from the mean of the
    cells ``step`` away on either side (along u, along v) by more than the threshold (module
    docstring); cells within ``step`` of the border are never line cells. ``gray`` [Gv, Gu] in
    [0, 1], finite."""
    gv, gu = gray.shape
    du = np.zeros_like(gray)
    dv = np.zeros_like(gray)
    if gu > 2 * step:
        du[:, step:-step] = np.abs(gray[:, step:-step] - 0.5 * (gray[:, :-2 * step] + gray[:, 2 * step:]))
    if gv > 2 * step:
        dv[step:-step, :] = np.abs(gray[step:-step, :] - 0.5 * (gray[:-2 * step, :] + gray[2 * step:, :]))
    inner_u, inner_v = du[:, step:gu - step], dv[step:gv - step, :]
    tu = max(contrast, texture_k * float(np.median(inner_u))) if inner_u.size else np.inf
    tv = max(contrast, texture_k * float(np.median(inner_v))) if inner_v.size else np.inf
    return du > tu, dv > tv


def boundary_cells(rf: RectifiedFront, rate: float, min_views: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(across_u, across_v) bool [Gv, Gu]: cell pairs in different instance masks in at least
    ``rate`` of the >= ``min_views`` views that saw both, and in at least two (:class:`RectifiedFront` ``edge_u`` /
    ``edge_v``), on the first cell of the pair; None without instance masks."""
    if rf.edge_u is None:
        return None
    bu = (rf.pair_u >= min_views) & (rf.edge_u >= np.maximum(2, rate * rf.pair_u))
    bv = (rf.pair_v >= min_views) & (rf.edge_v >= np.maximum(2, rate * rf.pair_v))
    return bu, bv


def _widen(a: np.ndarray, cells: int, axis: int) -> np.ndarray:
    """``a`` (bool) dilated by ``cells`` along ``axis``."""
    if cells <= 0:
        return a
    from scipy.ndimage import maximum_filter1d

    return maximum_filter1d(a.astype(np.uint8), 2 * cells + 1, axis=axis).astype(bool)


def _span_coverage(lines: np.ndarray, parts: int = 3) -> np.ndarray:
    """Per column of ``lines`` [A, B] (bool), the least fraction of line cells over ``parts``
    equal stretches of its A rows: a gap runs across the whole piece, a line along part of it
    (the gap of a drawer stack beside a door) is not a cut of the piece yet."""
    chunks = np.array_split(lines, min(parts, len(lines)), axis=0)
    return np.min([c.mean(0) for c in chunks], axis=0)


def _best_cut(lines: tuple[np.ndarray, np.ndarray, np.ndarray], handle: np.ndarray, lo: int, hi: int, a0: int,
              a1: int, min_cells: int, coverage: float, coverage_handles: float,
              several: bool = False) -> tuple[int, float, Clearance | None]:
    """The best cut along axis 1 of the line maps [A, B] ``lines`` = (strong mask boundaries,
    weak ones, image lines) between columns lo + ``min_cells`` and hi - ``min_cells``, over rows
    a0..a1: (column, coverage, clearance) or (-1, 0, clearance). A column qualifies when its strong boundary cells
    cover ``coverage`` of each third of the rows (:func:`_span_coverage`), or, with handle cells
    on both sides of it, its weak boundary or image line cells cover ``coverage_handles`` (a
    tile joint, a grain line or the end of a false detection has no handle on either side); no
    column through a handle. ``several``: the piece is known to hold several fronts (too wide
    to be one), so the weak kinds need no handles either side; with ``coverage_handles`` 0 any
    column with a line cell in each third qualifies (the best-covered wins).

    The :class:`Clearance` (column, margin, band), with ``coverage_handles`` > 0: ``margin`` is the
    largest clearance of the coverage tests over the columns a cut may take (a share of a third
    of the rows; >= 0 exactly when some column qualifies), at that column; ``band`` is one
    cell of the shortest third, so a cut with a margin under one band, or missing by one band
    at most, is one that a cell seen the other way could undo or make. None when no column may
    take a cut, or with ``coverage_handles`` 0."""
    if hi - lo < 2 * min_cells or a1 <= a0:
        return -1, 0.0, None
    strong, weak, img = (_span_coverage(x[a0:a1, lo:hi]) for x in lines)
    h = handle[a0:a1, lo:hi].any(0)
    left = np.concatenate([[False], np.cumsum(h)[:-1] > 0])  # a handle column before this one
    right = np.concatenate([(np.cumsum(h[::-1])[::-1] > 0)[1:], [False]])  # ... after it
    if several:
        left[:], right[:] = True, True
    aided = np.maximum(weak, img)
    # each column's clearance of its tests (>= 0: it qualifies); with coverage_handles 0 any weak cell will do
    weak_clear = aided - coverage_handles if coverage_handles > 0 else np.where(aided > 0, 0.0, -1.0)
    c = np.maximum(strong - coverage, np.where(left & right, weak_clear, -1.0))
    free = ~h
    free[:min_cells] = False
    free[len(free) - min_cells:] = False
    ok = (c >= 0) & free
    clear = None
    if coverage_handles > 0 and free.any():
        c = np.where(free, c, -np.inf)
        i = k = int(np.argmax(c))
        while k + 1 < len(c) and c[k + 1] == c[i]:  # the middle of a plateau, as for the cut
            k += 1
        band = 1.0 / min(len(x) for x in np.array_split(np.arange(a1 - a0), min(3, a1 - a0)))
        clear = Clearance(lo + (i + k) // 2, float(c[i]), band)
    if not ok.any():
        return -1, 0.0, clear
    score = np.where(ok, np.maximum(strong, aided), -1.0)
    j = int(np.argmax(score))
    k = j  # the middle of the run of equal scores (a line widened by the slack is a plateau)
    while k + 1 < len(score) and score[k + 1] == score[j]:
        k += 1
    return lo + (j + k) // 2, float(score[j]), clear


def even_cuts(u0: int, u1: int, n: int, blocked: np.ndarray | None = None) -> list[tuple[int, int]]:
    """[u0, u1) cut into ``n`` >= 1 column ranges of equal width (give or take a cell), the
    column of each cut dropped as a gap is: [(a, b)], b exclusive, left to right. ``blocked``
    [u1 - u0] (bool): columns no cut may take (a handle's): a cut there moves to the nearest
    free column less than half a piece away, or is not made."""
    step = (u1 - u0) / n
    at = []
    for k in range(1, n):
        c = int(round(k * step))
        if blocked is not None and blocked[c]:
            free = np.flatnonzero(~blocked)
            free = free[np.abs(free - c) < step / 2]
            if not len(free):
                continue
            c = int(free[np.argmin(np.abs(free - c))])
        at.append(u0 + c)
    edges = [u0 - 1, *at, u1]
    return [(edges[k] + 1, edges[k + 1]) for k in range(len(edges) - 1)]


def xy_cuts(lines_u: tuple[np.ndarray, ...], lines_v: tuple[np.ndarray, ...], handle: np.ndarray,
            piece: Piece, coverage: float, coverage_handles: float, min_cells: int, max_depth: int,
            wide_cells: int = 0, wide_min_cells: int = 1, even_cells: float = 0.0,
            log: list[tuple[int, int]] | None = None, near: list[dict] | None = None) -> list[Piece]:
    """The leaves of the recursive cut of ``piece`` (cells) at full-span gap lines (module
    docstring). ``lines_u`` = (strong mask boundaries, weak ones, image lines) across u
    (vertical lines), ``lines_v`` the same across v (horizontal lines), each bool [Gv, Gu];
    ``handle`` [Gv, Gu]: handle cells (no cut crosses one; with one on each side a cut needs only
    ``coverage_handles`` of the weak kinds). ``wide_cells`` (> 0): a piece wider than this
    holds several fronts: its vertical cuts need no handles either side, and without such a
    cut it is cut at its best-covered column with any line cell in each third of its height, at
    least ``wide_min_cells`` from its ends (until no piece is wider, or no column has one).
    ``even_cells`` (> 0, with ``wide_cells``): a piece still too wide with no such column is cut
    into max(2, round(width / ``even_cells``)) pieces of equal width (a run of modules of one
    width; a cut on a handle moves off it, :func:`even_cuts`), each cut again; ``log`` gets
    (pieces, width in cells) for each. ``near`` (a list) gets each decision of a piece that one
    cell seen the other way would turn: ``{"cut": "gap_line", "axis": "u" | "v", "made", "at"
    (cell), "margin", "band"}`` (the coverage clearance of :func:`_best_cut` within its band;
    not the vertical lines of a piece too wide to be one, which is cut with or without one)
    and ``{"cut": "too_wide", "made", "cells"}`` (a piece one cell from ``wide_cells``)."""
    u0, u1, v0, v1 = piece
    if max_depth <= 0:
        return [piece]
    wide = 0 < wide_cells < u1 - u0
    ju, cu, clear_u = _best_cut(lines_u, handle, u0, u1, v0, v1, min_cells, coverage, coverage_handles, several=wide)
    iv, cv, clear_v = _best_cut(tuple(x.T for x in lines_v), handle.T, v0, v1, u0, u1, min_cells, coverage,
                                coverage_handles)
    if near is not None:
        if wide_cells > 0 and abs(u1 - u0 - wide_cells - 0.5) < 1:
            near.append({"cut": "too_wide", "made": wide, "cells": u1 - u0})
        for axis, clear in (("u", None if wide else clear_u), ("v", clear_v)):  # a wide piece is cut either way
            if clear is not None and clear.near():
                near.append({"cut": "gap_line", "axis": axis, "made": clear.margin >= 0, "at": clear.at,
                             "margin": round(clear.margin, 4), "band": round(clear.band, 4)})
    if wide and ju < 0:  # too wide to be one front, and no line good enough: the best line there is
        ju, cu, _ = _best_cut(lines_u, handle, u0, u1, v0, v1, wide_min_cells, coverage, 0.0, several=True)
        if ju >= 0:
            iv, cv = -1, 0.0
        elif even_cells > 0:  # no line at all: equal pieces
            n = max(2, int(round((u1 - u0) / even_cells)))
            halves = [(a, b, v0, v1) for a, b in even_cuts(u0, u1, n, handle[v0:v1, u0:u1].any(0))]
            if len(halves) == 1:
                return [piece]
            if log is not None:
                log.append((len(halves), u1 - u0))
            return [leaf for h in halves
                    for leaf in xy_cuts(lines_u, lines_v, handle, h, coverage, coverage_handles, min_cells,
                                        max_depth - 1, wide_cells, wide_min_cells, even_cells, log, near)]
    if ju < 0 and iv < 0:
        return [piece]
    if cu >= cv:
        halves = [(u0, ju, v0, v1), (ju + 1, u1, v0, v1)]
    else:
        halves = [(u0, u1, v0, iv), (u0, u1, iv + 1, v1)]
    return [leaf for h in halves
            for leaf in xy_cuts(lines_u, lines_v, handle, h, coverage, coverage_handles, min_cells, max_depth - 1,
                                wide_cells, wide_min_cells, even_cells, log, near)]


def split_front(front: Front, rf: RectifiedFront, cfg: SplitConfig, handle_min_rate: float, handle_min_views: int,
                log: list[dict] | None = None, near: list[dict] | None = None) -> list[Front]:
    """``front`` cut at its gap lines (:func:`xy_cuts` on the rectified front ``rf``'s instance
    boundaries and mean colour inside the rectangle; cells no view saw take the front's median
    grey; handle cells: rate >= ``handle_min_rate`` over >= ``handle_min_views`` views, also
    the least views a boundary needs); ``[front]`` when no line qualifies or nothing was seen.
    Pieces keep the front's plane and axes. ``log`` gets {"even_pieces": n, "width": m} for each
    piece too wide and without a line that was cut into ``n`` equal pieces (``cfg.wide_even``).
    ``near`` (a list) gets each cut made or not that one cell of the rectified front seen the
    other way would turn (:func:`xy_cuts`): ``{"cut": "gap_line", "axis": "u" | "v", "made",
    "at_u" | "at_v" (m, from the front's centre), "margin", "band"}`` (the coverage clearance
    and one cell's share of a third of the span) or ``{"cut": "too_wide", "made", "width"}``
    (m, within one cell of ``cfg.max_width``)."""
    uu, vv = rf.uv()
    w, h = front.size
    cols = np.flatnonzero(np.abs(uu[0]) <= w / 2)
    rows = np.flatnonzero(np.abs(vv[:, 0]) <= h / 2)
    if len(cols) < 3 or len(rows) < 3:
        return [front]
    gray = rf.rgb.mean(axis=2)[np.ix_(rows, cols)]  # NaN where no view saw the cell
    if not np.isfinite(gray).any():
        return [front]
    gray = np.where(np.isfinite(gray), gray, np.nanmedian(gray))
    hmap = (rf.handle_rate(handle_min_views) >= handle_min_rate)[np.ix_(rows, cols)]
    iu, iv = line_cells(gray, cfg.step, cfg.contrast, cfg.texture_k)
    iu, iv = _widen(iu, 1, 1), _widen(iv, 1, 0)
    maps_u, maps_v = [], []
    for rate in (cfg.boundary_rate, cfg.boundary_rate_handles):
        bd = boundary_cells(rf, rate, handle_min_views)
        maps_u.append(np.zeros_like(iu) if bd is None else _widen(bd[0][np.ix_(rows, cols)], cfg.slack, 1))
        maps_v.append(np.zeros_like(iv) if bd is None else _widen(bd[1][np.ix_(rows, cols)], cfg.slack, 0))
    min_cells = max(1, int(np.ceil(cfg.min_piece / rf.res)))
    wide_cells = int(np.floor(cfg.max_width / rf.res)) if cfg.max_width else 0
    even: list[tuple[int, int]] = []
    flips: list[dict] = []
    pieces = xy_cuts((*maps_u, iu), (*maps_v, iv), hmap, (0, len(cols), 0, len(rows)), cfg.coverage,
                     cfg.coverage_handles, min_cells, cfg.max_depth, wide_cells,
                     max(1, int(np.ceil(cfg.wide_min_piece / rf.res))), cfg.wide_even / rf.res, even, flips)
    res = rf.res
    u_lo, v_lo = uu[0, cols[0]] - res / 2, vv[rows[0], 0] - res / 2
    if log is not None:
        log.extend({"even_pieces": n, "width": round(cells * rf.res, 4)} for n, cells in even)
    if near is not None:
        for f in flips:
            if f["cut"] == "too_wide":
                near.append({"cut": "too_wide", "made": f["made"], "width": round(f["cells"] * res, 4)})
            else:
                at = float((u_lo if f["axis"] == "u" else v_lo) + (f["at"] + 0.5) * res)
                near.append({"cut": "gap_line", "axis": f["axis"], "made": f["made"], f"at_{f['axis']}": round(at, 4),
                             "margin": f["margin"], "band": f["band"]})
    if len(pieces) == 1:
        return [front]
    return [sub_front(front, max(u_lo + a0 * res, -w / 2), min(u_lo + a1 * res, w / 2),
                      max(v_lo + b0 * res, -h / 2), min(v_lo + b1 * res, h / 2)) for a0, a1, b0, b1 in pieces]


def _binned(x: np.ndarray, values: np.ndarray, a: float, b: float, bin_m: float, min_count: int,
            stats) -> tuple[np.ndarray, np.ndarray]:
    """``values`` [N] grouped by ``x`` [N] in bins of ``bin_m`` from ``a`` to ``b``: (centres [J],
    [J, S] the ``stats`` (S functions of a bin's values) of every bin holding >= ``min_count``)."""
    edges = np.arange(a, b + 0.5 * bin_m, bin_m)
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    xs, rows = [], []
    for j in range(len(edges) - 1):
        vj = values[idx == j]
        if len(vj) >= min_count:
            xs.append(0.5 * (edges[j] + edges[j + 1]))
            rows.append([float(f(vj)) for f in stats])
    return np.asarray(xs), np.asarray(rows).reshape(len(xs), len(stats))


def _step_fit(x: np.ndarray, m: np.ndarray, k: int) -> tuple[float, float, float]:
    """Least squares of the profile ``m`` [J] over ``x`` [J] by a line with a step before index
    ``k``: m = a + b x + s [j >= k]; returns (s, b, residual sum of squares)."""
    A = np.stack([np.ones_like(x), x, (np.arange(len(x)) >= k).astype(float)], axis=1)
    coef, *_ = np.linalg.lstsq(A, m, rcond=None)
    r = m - A @ coef
    return float(coef[2]), float(coef[1]), float(r @ r)


STEP_BAND = 0.001  # m: a mesh cut whose length tests clear or miss their bounds by less than this is near them
SHARE_BAND = 0.02  # an outline step's notch share of other surfaces this close to its 2/3 bound is near it


def depth_step_cuts(front: Front, points: np.ndarray, step_range: tuple[float, float], min_piece: float,
                    bin_m: float = 0.02, max_depth: int = 2, log: list | None = None,
                    near: list | None = None) -> list[Front]:
    """``front`` cut where the surface under it steps back or forward along u by a sliding
    door's track offset: two panels on two tracks that the detector merged in every view give
    one segment, one plane between them and one rectangle over both, but the mesh still shows
    one panel ``step_range`` (m, lo, hi) proud of the other.

    ``points`` [P, 3]: the segment's surface points; those over the rectangle within
    ``step_range[1]`` + 2 cm of its plane are binned along u (``bin_m``), each bin's median
    offset from the plane is the profile, and the profile is fitted by a line with one step (a
    line, since the plane fitted over two offset panels is yawed). The best step over every
    position is a cut when its size is within ``step_range``, it lies at least ``min_piece``
    from the piece's ends (the recessed panel of a frame-and-panel door steps next to its stile,
    well inside that), the residual RMS is under a quarter of the step (two flat panels), and the
    step has the same sign and at least half of ``step_range[0]`` in each third of the height
    (it runs the whole height: a handle or a shelf behind glass does not). Each side is cut again
    up to ``max_depth``. Pieces keep the front's axes and take their own plane offset (the
    median of their points). ``[front]`` without a step. ``log`` (a list) receives each cut's
    evidence (position along u, step, residual RMS, the least step over the thirds; m), so
    ``decisions.json`` shows how far each test cleared its threshold, and its ``margin``: the
    least of those clearances (m). ``near`` (a list) receives the best step of each piece, cut or
    not, whose margin lies within :data:`STEP_BAND` of 0 (``made``, ``at_u``, ``margin``, m): a
    mesh that moves by its last bits (another machine, SDF seed or thread count) could decide
    that cut the other way."""
    w, h = front.size
    pu, pv, pn = front_coords(front, points).T
    ok = (np.abs(pu) <= w / 2) & (np.abs(pv) <= h / 2) & (np.abs(pn) <= step_range[1] + 0.02) & np.isfinite(pn)
    pu, pv, pn = pu[ok], pv[ok], pn[ok]

    def cut(a: float, b: float, depth: int) -> list[tuple[float, float]]:
        sel = (pu >= a) & (pu < b)
        if depth <= 0 or b - a < 2 * min_piece or sel.sum() < 20:
            return [(a, b)]
        x_all, n_all, v_all = pu[sel], pn[sel], pv[sel]
        x, m = _binned(x_all, n_all, a, b, bin_m, 3, (np.median,))
        m = m[:, 0]
        if len(x) < 6:
            return [(a, b)]
        best = min(((k, *_step_fit(x, m, k)) for k in range(2, len(x) - 1)), key=lambda t: t[3])
        k, step, slope, sse = best
        at = 0.5 * (x[k - 1] + x[k])
        rms = float(np.sqrt(sse / len(x)))
        # each test's clearance (m; < 0: failed): the step's size, the pieces' widths, the residual
        clear = [abs(step) - step_range[0], step_range[1] - abs(step), min(at - a, b - at) - min_piece,
                 abs(step) / 4 - rms]
        flat = n_all - slope * x_all  # the yaw taken out
        least = abs(step)
        for t0, t1 in ((-h / 2, -h / 6), (-h / 6, h / 6), (h / 6, h / 2)):
            in_t = (v_all >= t0) & (v_all <= t1)
            lo, hi = flat[in_t & (x_all < at)], flat[in_t & (x_all >= at)]
            if len(lo) >= 5 and len(hi) >= 5:
                st = float(np.median(hi) - np.median(lo))
                signed = st * np.sign(step)  # along the step: > 0 when this third steps the same way
                clear.append(signed - step_range[0] / 2)
                least = min(least, abs(st))
        margin = float(min(clear))
        made = margin >= 0
        if near is not None and abs(margin) < STEP_BAND:
            near.append({"cut": "depth_step", "made": made, "at_u": round(float(at), 4), "margin": round(margin, 4)})
        if not made:
            return [(a, b)]
        if log is not None:
            log.append({"cut": "depth_step", "at_u": round(float(at), 4), "step": round(step, 4),
                        "rms": round(rms, 4), "least_third": round(least, 4), "margin": round(margin, 4)})
        return cut(a, at, depth - 1) + cut(at, b, depth - 1)

    spans = cut(-w / 2, w / 2, max_depth)
    if len(spans) == 1:
        return [front]
    out = []
    for a, b in spans:
        sel = (pu >= a) & (pu < b)
        out.append(sub_front(front, a, b, offset=float(np.median(pn[sel])) if sel.any() else 0.0))
    return out


def _change_point(x: np.ndarray, m: np.ndarray) -> tuple[int, float, float]:
    """The best split of the profile ``m`` [J] (over ``x`` [J], sorted) into two constant
    runs: (index k of the first value of the second run, the step median(right) -
    median(left), the larger of the two runs' median absolute deviations)."""
    best = (-1, 0.0, np.inf, np.inf)
    for k in range(2, len(m) - 1):
        lo, hi = m[:k], m[k:]
        ml, mh = float(np.median(lo)), float(np.median(hi))
        cost = float(np.abs(lo - ml).sum() + np.abs(hi - mh).sum())
        if cost < best[3]:
            spread = max(float(np.median(np.abs(lo - ml))), float(np.median(np.abs(hi - mh))))
            best = (k, mh - ml, spread, cost)
    return best[0], best[1], best[2]


def extent_step_cuts(front: Front, points: np.ndarray, scene_points: np.ndarray, scene_segment: np.ndarray,
                     segment: int, min_step: float, min_piece: float, bin_m: float = 0.02, max_depth: int = 2,
                     plane_tol: float = 0.005, log: list | None = None, near: list | None = None) -> list[Front]:
    """``front`` cut where its segment's outline steps: a front is a rectangle, so a segment
    shaped like an L (a door merged with a shorter door or a drawer stack beside it, by a
    detector that merged them in every view) is two fronts side by side.

    ``points`` [P, 3]: the segment's surface points within 5 cm of the front's plane, binned
    along u (``bin_m``); per bin the top and the bottom of the segment (the 98th and 2nd
    percentiles of v). The best change point of either profile (two constant runs) is a cut
    when the step is at least ``min_step``, each run is straight (median absolute deviation
    under a quarter of the step), it lies at least ``min_piece`` from the piece's ends, and the
    notch (the corner the shorter side leaves empty) is seen and is something else:
    ``scene_points`` [Q, 3] (the whole mesh; ``scene_segment`` [Q]: the segment each lies on,
    -1 for none) has points over it, and at least two thirds of them lie on another segment
    than ``segment`` or off the plane (more than ``plane_tol`` behind it, or in front by up to
    3 cm: a neighbouring front, a recess, the wall above a shorter cabinet). A notch of the
    front's own plane that no segment holds is the same front, part of which decompose gave
    no segment; an object in front of a door hides its corner. Pieces span their own part of u
    and their own points' height (clipped to the front's); each side is cut again up to
    ``max_depth``. ``[front]`` otherwise. ``log`` (a list) receives each cut's evidence (which
    outline, position along u, step, spread (m), the notch's share of other surfaces), its
    ``margin`` (the least clearance of the tests in metres: step, straightness, pieces' widths)
    and ``notch_margin`` (the notch's share of other surfaces less 2/3). ``near`` (a list)
    receives each outline's best step, cut or not, that is as close to its bounds as
    :func:`depth_step_cuts`' (a margin within :data:`STEP_BAND`, a notch share within
    :data:`SHARE_BAND`; ``made``, ``outline``, ``at_u``, ``margin``, ``notch_margin``): the
    tests that failed all within their bands, or a made cut with one test within its band."""
    w, h = front.size
    pu, pv, pn = front_coords(front, points).T
    ok = (np.abs(pu) <= w / 2) & (np.abs(pv) <= h / 2) & (np.abs(pn) <= 0.05)
    pu, pv = pu[ok], pv[ok]
    su, sv, sn = front_coords(front, scene_points).T

    def height(a: float, b: float) -> tuple[float, float]:
        sel = (pu >= a) & (pu < b)
        if sel.sum() < 10:
            return -h / 2, h / 2
        return max(float(np.percentile(pv[sel], 1)), -h / 2), min(float(np.percentile(pv[sel], 99)), h / 2)

    def cut(a: float, b: float, depth: int) -> list[tuple[float, float]]:
        sel = (pu >= a) & (pu < b)
        if depth <= 0 or b - a < 2 * min_piece or sel.sum() < 50:
            return [(a, b)]
        x, tb = _binned(pu[sel], pv[sel], a, b, bin_m, 10,
                        (lambda q: np.percentile(q, 98), lambda q: np.percentile(q, 2)))
        if len(x) < 6:
            return [(a, b)]
        for prof, is_top in ((tb[:, 0], True), (tb[:, 1], False)):
            k, step, spread = _change_point(x, prof)
            if k < 0:
                continue
            at = 0.5 * (x[k - 1] + x[k])
            # each length test's clearance (m; < 0: failed): the step's size, the runs' straightness, the pieces
            margin = min(abs(step) - min_step, abs(step) / 4 - spread, min(at - a, b - at) - min_piece)
            # the notch: over the shorter side, between its edge and the longer side's
            lo_side = (step > 0) == is_top  # the side (left of ``at``) whose outline is short
            nu0, nu1 = (a, at) if lo_side else (at, b)
            e0, e1 = float(np.median(prof[:k])), float(np.median(prof[k:]))
            nv0, nv1 = sorted((e0, e1))
            nv0, nv1 = nv0 + 0.01, nv1 - 0.01
            in_notch = (su >= nu0 + 0.01) & (su < nu1 - 0.01) & (sv >= nv0) & (sv <= nv1) & (np.abs(sn) < 0.6)
            other = ((scene_segment[in_notch] >= 0) & (scene_segment[in_notch] != segment)) | (
                (np.abs(sn[in_notch]) > plane_tol) & (sn[in_notch] <= 0.03))
            seen = in_notch.sum() >= 10
            notch_margin = float(other.mean()) - 2 / 3 if seen else -1.0
            made = margin >= 0 and notch_margin >= 0
            flip = min(margin / STEP_BAND, notch_margin / SHARE_BAND)  # in bands: |flip| < 1 is near
            if near is not None and seen and abs(flip) < 1:
                near.append({"cut": "outline_step", "made": made, "outline": "top" if is_top else "bottom",
                             "at_u": round(float(at), 4), "margin": round(float(margin), 4),
                             "notch_margin": round(notch_margin, 3)})
            if not made:
                continue
            if log is not None:
                log.append({"cut": "outline_step", "outline": "top" if is_top else "bottom", "at_u": round(float(at), 4),
                            "step": round(step, 4), "spread": round(spread, 4), "notch_other": round(float(other.mean()), 3),
                            "margin": round(float(margin), 4), "notch_margin": round(notch_margin, 3)})
            return cut(a, at, depth - 1) + cut(at, b, depth - 1)
        return [(a, b)]

    spans = cut(-w / 2, w / 2, max_depth)
    if len(spans) == 1:
        return [front]
    return [sub_front(front, a, b, *height(a, b)) for a, b in spans]


SIDES = ("left", "right", "bottom", "top")


def border_lines(front: Front, rf: RectifiedFront, cfg: SplitConfig, slack: float, corner: float = 0.02
                 ) -> dict[str, float | None]:
    """Per side of the rectangle (left, right, bottom, top), the fraction of its length (less
    ``corner`` at each end) along which the rectified image shows a line or an edge
    (:func:`line_cells` over the whole grid, margin included) within ``slack`` m of the side:
    the gap that runs round a real front. None for a side no view saw."""
    uu, vv = rf.uv()
    w, h = front.size
    gray = rf.rgb.mean(axis=2)
    seen = np.isfinite(gray)
    out: dict[str, float | None] = dict.fromkeys(SIDES)
    if not seen.any():
        return out
    gray = np.where(seen, gray, np.nanmedian(gray))
    iu, iv = line_cells(gray, cfg.step, cfg.contrast, cfg.texture_k)
    u, v = uu[0], vv[:, 0]
    along_v = (np.abs(v) <= h / 2 - corner)
    along_u = (np.abs(u) <= w / 2 - corner)
    for side, at, lines, across in (("left", -w / 2, iu, along_v), ("right", w / 2, iu, along_v),
                                    ("bottom", -h / 2, iv, along_u), ("top", h / 2, iv, along_u)):
        if side in ("left", "right"):
            near = np.abs(u - at) <= slack
            hit, ok = lines[:, near].any(axis=1)[across], seen[:, near].any(axis=1)[across]
        else:
            near = np.abs(v - at) <= slack
            hit, ok = lines[near, :].any(axis=0)[across], seen[near, :].any(axis=0)[across]
        if ok.sum() >= 3:
            out[side] = float(hit[ok].mean())
    return out
