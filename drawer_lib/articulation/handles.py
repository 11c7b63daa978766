"""Handles: the evidence (mesh protrusions in front of a front, faces that "handle" masks
cover), its assignment to fronts, the choice of each front's handle, and the handle's place
and shape in the front's unit square. Lengths in metres."""

import numpy as np
from jaxtyping import Float

from typing import TYPE_CHECKING

from drawer_lib.articulation.config import HandlesConfig
from drawer_lib.articulation.fronts import abutting_edges
from drawer_lib.articulation.vocab import Handle
from drawer_lib.errors import InputError
from drawer_lib.geometry.frames import UP
from drawer_lib.io.parts import Front
from drawer_lib.perception.views import connected_components

if TYPE_CHECKING:
    from drawer_lib.articulation.config import RectifyConfig
    from drawer_lib.articulation.rectify import RectifiedFront

Candidates = list[list[tuple[np.ndarray, float]]]  # per front: [(points [M, 3], weight)], heaviest first
RUNNER_UP_NEAR = 0.8  # a second pull weighing this share of the chosen one's, elsewhere on the front, is near
RUNNER_UP_APART = 0.25  # "elsewhere": centres this share of the front's width or height apart


def handle_clusters(points: Float[np.ndarray, "N 3"], radius: float, min_points: int) -> list[np.ndarray]:
    """Handle candidates: indices into ``points`` of the groups that single linkage at
    ``radius`` (m) forms, each of at least ``min_points``."""
    if len(points) < min_points:
        return []
    from scipy.spatial import cKDTree

    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray").astype(np.int64).reshape(-1, 2)
    lab = connected_components(len(points), pairs)
    return [np.nonzero(lab == k)[0] for k in np.unique(lab) if (lab == k).sum() >= min_points]


def rect_distance(front: Front, points: Float[np.ndarray, "N 3"]) -> np.ndarray:
    """Signed in-plane distance [N] (m) of ``points`` from the front's rectangle: positive
    outside (to the nearest point of the rectangle), negative inside (minus the distance to the
    nearest edge)."""
    rel = points - np.asarray(front.center)
    eu = np.abs(rel @ np.asarray(front.u)) - front.size[0] / 2
    ev = np.abs(rel @ front.v) - front.size[1] / 2
    inside = (eu <= 0) & (ev <= 0)
    return np.where(inside, np.maximum(eu, ev), np.hypot(np.maximum(eu, 0), np.maximum(ev, 0)))


def handle_candidates(fronts: list[Front], points: Float[np.ndarray, "N 3"], cfg: HandlesConfig, radius: float,
                      min_points: int, weights: np.ndarray | None = None) -> Candidates:
    """Per front, its handle candidates [(points [M, 3], total weight)], heaviest first: every
    handle point goes to the front whose rectangle it lies deepest in (signed in-plane distance,
    negative inside; at most ``cfg.max_gap`` outside) among those it stands -``below_plane`` ..
    ``max`` in front of; the candidates are the clusters of a front's points
    (:func:`handle_clusters`) that span less than ``max_span`` of the front either way, weighed
    by ``weights`` [N] >= 0 (default 1 per point). An edge pull straddling the gap between two
    fronts thus goes, point by point, mostly to the front it reaches into."""
    out: Candidates = [[] for _ in fronts]
    if len(fronts) == 0 or len(points) == 0:
        return out
    w_all = np.ones(len(points)) if weights is None else np.asarray(weights, float)
    if w_all.shape != (len(points),) or not np.all(np.isfinite(w_all)) or (w_all < 0).any():
        raise ValueError(f"handle_candidates: weights must be [{len(points)}] finite and >= 0")
    best = np.full(len(points), np.inf)
    owner = np.full(len(points), -1)
    for k, f in enumerate(fronts):
        d = rect_distance(f, points)
        h = (points - np.asarray(f.center)) @ np.asarray(f.normal)
        ok = (h >= -cfg.below_plane) & (h <= cfg.max) & (d <= cfg.max_gap) & (d < best)
        best[ok] = d[ok]
        owner[ok] = k
    for k, f in enumerate(fronts):
        u, v = np.asarray(f.u), f.v
        pts, w = points[owner == k], w_all[owner == k]
        # a handle is shorter than its front: a cluster spanning it is a counter edge or a plinth
        cl = [i for i in handle_clusters(pts, radius, min_points)
              if np.ptp(pts[i] @ u) < cfg.max_span * f.size[0] and np.ptp(pts[i] @ v) < cfg.max_span * f.size[1]]
        cl.sort(key=lambda i: (-float(w[i].sum()), -len(i)))
        out[k] = [(pts[i], float(w[i].sum())) for i in cl]
    return out


def resolve_split_pulls(fronts: list[Front], cands: Candidates, link: float, margin: float,
                        reach_percentile: float = 90.0) -> tuple[Candidates, list[tuple[int, int, float]]]:
    """One pull that two fronts share, given whole to one of them.

    A pull by the edge between two fronts (a sliding panel's bar by its leading edge beside a
    flap, a door's knob by the gap) is read on both: the rectified masks of each front reach
    ``margin`` beyond its rectangle and every point goes to the rectangle it lies deepest in,
    so a pull near the gap splits between the two, and the front that is not its own takes a
    bar "at its very edge" (a hinge side, a kind) from a neighbour's pull. Two candidates of
    different fronts whose points come within ``link`` (m) of each other are one pull; it goes
    whole to the front its points reach deeper into (the ``reach_percentile`` of their depth
    inside each rectangle, m), when deeper by at least ``margin`` (m); otherwise both keep their
    share (a pull in the gap between stacked fronts is :func:`resolve_stacked_pulls`' case).
    Repeated until nothing moves. Returns (the candidates, heaviest first per front, [(front
    that gave up its share, front that took the pull, reach difference m)])."""
    from scipy.spatial import cKDTree

    out: Candidates = [list(c) for c in cands]
    moves: list[tuple[int, int, float]] = []
    moved = True
    while moved:
        moved = False
        for a in range(len(fronts)):
            for b in range(len(fronts)):
                if a == b or not out[a] or not out[b]:
                    continue
                for i, (pa, wa) in enumerate(out[a]):
                    tree = cKDTree(pa)
                    j = next((j for j, (pb, _) in enumerate(out[b])
                              if np.isfinite(tree.query(pb, distance_upper_bound=link)[0]).any()), None)
                    if j is None:
                        continue
                    pb, wb = out[b][j]
                    union = np.concatenate([pa, pb])
                    reach_a = float(np.percentile(-rect_distance(fronts[a], union), reach_percentile))
                    reach_b = float(np.percentile(-rect_distance(fronts[b], union), reach_percentile))
                    if reach_b - reach_a < margin:
                        continue
                    del out[a][i]
                    out[b][j] = (union, wa + wb)
                    out[b].sort(key=lambda c: (-c[1], -len(c[0])))
                    moves.append((a, b, round(reach_b - reach_a, 4)))
                    moved = True
                    break
    return out, moves


def heaviest(cands: Candidates) -> list[np.ndarray | None]:
    """Each front's heaviest candidate (its points), or None."""
    return [c[0][0] if c else None for c in cands]


def resolve_stacked_pulls(fronts: list[Front], cands: Candidates, edge_frac: float, max_gap: float,
                          plane_tol: float = 0.02, min_overlap: float = 0.5
                          ) -> tuple[list[np.ndarray | None], list[tuple[int, int]]]:
    """The handle of each front (its heaviest candidate) once stacked fronts share no pull.

    An edge pull in the gap between a front and the one below it (:func:`abutting_edges`) is
    seen by both: masks ragged by a pixel or two at ~1.3 cm per pixel cover both sides, so the
    upper front may take the lower one's pull as "a handle near my bottom edge" (a flap) while
    the lower takes it as its top-edge pull. When the upper front's choice lies in its bottom
    ``edge_frac`` and the lower front's in its top ``edge_frac``, both wider than tall and
    overlapping in width, they are one pull, and it goes to the lower front: a pull in such a
    gap is a lip pull on the top edge of the front below (the point weights cannot tell: on
    kitchen_tiny's drawer stack the upper front holds 75 of the pull's mask faces, the lower
    30). The upper front takes its next candidate if it has one; repeated until nothing
    changes (in a stack of three, the middle front's change can make the top one's choice a
    shared pull). Returns (handle points per front or None, [(front that gave up a candidate,
    front below)])."""
    choice = [0 if c else -1 for c in cands]
    changed: list[tuple[int, int]] = []

    def band(k: int) -> tuple[float, float, float, bool]:
        """(u range in the front's frame, median height as a fraction of the front (0 = bottom),
        wider than tall)."""
        f = fronts[k]
        rel = cands[k][choice[k]][0] - np.asarray(f.center)
        pu, pv = rel @ np.asarray(f.u), rel @ f.v
        wide = bool(np.ptp(pu) > np.ptp(pv))
        return float(pu.min()), float(pu.max()), float(np.median(pv)) / max(f.size[1], 1e-9) + 0.5, wide

    # stacked pairs (a above b: b abuts a's low edge along a's v), fixed by the geometry
    pairs = [(a, b, du) for a, fa in enumerate(fronts) for b, fb in enumerate(fronts)
             if a != b and cands[a] and cands[b]
             for ax, side, du in abutting_edges(fa, fb, max_gap, plane_tol, min_overlap) if (ax, side) == (1, -1)]
    # until nothing changes: an upper front only ever moves on to its next candidate, so this
    # ends; a stack of three resolves from the bottom pair up
    moved = True
    while moved:
        moved = False
        for a, b, du in pairs:
            ua0, ua1, va, wide_a = band(a)
            ub0, ub1, vb, wide_b = band(b)
            if va > edge_frac or vb < 1 - edge_frac or min(ua1, ub1 + du) < max(ua0, ub0 + du):
                continue
            if not (wide_a and wide_b):  # two vertical bars by the gap (a tall unit's doors): two handles
                continue
            if choice[a] + 1 < len(cands[a]):  # the upper front gives it up for its next candidate
                choice[a] += 1
                changed.append((a, b))
                moved = True
    return [cands[k][choice[k]][0] if choice[k] >= 0 else None for k in range(len(fronts))], changed


COLOUR_FILL = 0.5  # a colour blob is a bar or a knob when it fills this share of its box ...
COLOUR_NEAR_FILL = 0.05  # ... and near that test within this of it


def colour_blob_slack(long_: float, short: float, n_cells: int, box_cells: int, res: float,
                      cfg: "RectifyConfig") -> float:
    """How far a colour blob passes the tests of a handle (:func:`colour_handle`), in the
    units a blob moves by: cells (``res`` m) for its sides and its count, ``COLOUR_NEAR_FILL``
    for the share of its box it fills; the smallest over the tests, >= 0 when it passes them all.
    A blob one cell longer, shorter or fuller could cross a test whose slack is in [-1, 1).

    >>> from drawer_lib.articulation.config import RectifyConfig
    >>> round(colour_blob_slack(0.448, 0.02, 560, 560, 0.004, RectifyConfig()), 6)  # 0.45 m at most: half a cell left
    0.5
    """
    return min((long_ - cfg.colour_min_len) / res, (cfg.colour_max_len - long_) / res,
               (cfg.colour_max_width - short) / res, float(n_cells - cfg.min_cells),
               (n_cells / max(box_cells, 1) - COLOUR_FILL) / COLOUR_NEAR_FILL)


def colour_handle(front: Front, rf: "RectifiedFront", cfg: "RectifyConfig",
                  near: dict | None = None) -> np.ndarray | None:
    """A handle the detector never found, read off the rectified front's colours: the cells
    (seen in >= ``min_views`` views, at least ``colour_edge_band`` m inside the rectangle: gaps
    and neighbours bleed into its border) whose colour lies farther from the front's median
    colour than max(``colour_contrast``, ``colour_texture_k`` x the median such distance), in
    4-connected blobs; a blob is a handle when it is a bar or a knob: its longer side
    ``colour_min_len`` .. ``colour_max_len`` m, its shorter at most ``colour_max_width`` m, at
    least ``min_cells`` cells, and it fills half of its box. The biggest such blob, as points on
    the front's plane [M, 3], or None. Colours in [0, 1].

    ``near``: filled with ``{"why", "a_u", "a_v"}`` when the choice had no margin, i.e. when
    a blob one cell bigger or smaller would change it (:func:`colour_blob_slack` in [-1, 1)):
    ``"bound"``, the chosen blob passes a test by less than that (``a_u``, ``a_v``: its place in
    the front's unit square); ``"rival"``, another blob that passes, or fails only by that,
    holds at least ``RUNNER_UP_NEAR`` of the chosen one's cells and lies ``RUNNER_UP_APART``
    from it, or, with no blob chosen, fails only by that (its place)."""
    from scipy import ndimage

    from drawer_lib.articulation.rectify import grid_points

    uu, vv = rf.uv()
    w, h = front.size
    band = cfg.colour_edge_band
    inside = (np.abs(uu) <= w / 2 - band) & (np.abs(vv) <= h / 2 - band) & (rf.seen >= cfg.min_views)
    inside &= np.isfinite(rf.rgb).all(axis=2)
    if inside.sum() < 10:
        return None
    panel = np.median(rf.rgb[inside], axis=0)
    dist = np.where(inside, np.linalg.norm(np.nan_to_num(rf.rgb) - panel, axis=2), 0.0)
    thr = max(cfg.colour_contrast, cfg.colour_texture_k * float(np.median(dist[inside])))
    lab, n = ndimage.label(dist > thr)
    blobs = []  # (points, cells, slack) of every blob that passes or fails only by a cell
    for k, sl in enumerate(ndimage.find_objects(lab), start=1):
        if sl is None:
            continue
        cells = lab[sl] == k
        ext_v, ext_u = cells.shape[0] * rf.res, cells.shape[1] * rf.res
        slack = colour_blob_slack(max(ext_u, ext_v), min(ext_u, ext_v), int(cells.sum()), cells.size, rf.res, cfg)
        if slack >= -1:
            blobs.append((grid_points(front, uu[sl][cells], vv[sl][cells]), int(cells.sum()), slack))
    passing = [b for b in blobs if b[2] >= 0]
    best = max(passing, key=lambda b: b[1]) if passing else None  # the first of equals
    if near is not None:
        rivals = [b for b in blobs if b is not best and (
            best is None or (b[1] >= RUNNER_UP_NEAR * best[1] and elsewhere(front, best[0], b[0])))]
        record = (("bound", best[0]) if best is not None and best[2] < 1
                  else ("rival", rivals[0][0]) if rivals else None)
        if record is not None:
            a_u, a_v = unit_place(front, record[1])
            near.update(why=record[0], a_u=round(a_u, 3), a_v=round(a_v, 3))
    return None if best is None else best[0]


def unit_place(front: Front, pts: Float[np.ndarray, "M 3"]) -> tuple[float, float]:
    """The median of ``pts`` in the front's unit square (a_u from its left edge, a_v from its
    bottom edge; clipped to [0, 1])."""
    rel = pts - np.asarray(front.center)
    hw, hh = front.size[0] / 2, front.size[1] / 2
    a_u = float(np.clip((np.median(rel @ np.asarray(front.u)) + hw) / max(2 * hw, 1e-9), 0, 1))
    a_v = float(np.clip((np.median(rel @ front.v) + hh) / max(2 * hh, 1e-9), 0, 1))
    return a_u, a_v


def elsewhere(front: Front, p1: Float[np.ndarray, "M 3"], p2: Float[np.ndarray, "N 3"]) -> bool:
    """Whether two pulls' points lie at other places of ``front``: their centres (:func:`unit_place`)
    more than :data:`RUNNER_UP_APART` of its width or height apart, so that taking one for the
    other would read another hinge side or kind."""
    (u1, v1), (u2, v2) = unit_place(front, p1), unit_place(front, p2)
    return abs(u2 - u1) > RUNNER_UP_APART or abs(v2 - v1) > RUNNER_UP_APART


def runner_up(front: Front, cands: list[tuple[np.ndarray, float]], chosen: np.ndarray | None) -> dict | None:
    """Whether the choice of ``front``'s handle had a margin: the candidate after the chosen one
    (``cands`` heaviest first; ``chosen``: the points of the one taken, as the list holds them)
    when it weighs at least :data:`RUNNER_UP_NEAR` of it and its centre lies more than
    :data:`RUNNER_UP_APART` of the front's width or height from the chosen one's, so that
    taking it would read another hinge side or kind: ``{"ratio", "a_u", "a_v"}`` (its weight
    over the chosen one's, its place in the unit square); None otherwise. The weights are sums
    of cell rates, which a view's masks moving by a pixel, or the rectangle by a few
    millimetres, change by several per cent."""
    i = next((i for i, (p, _) in enumerate(cands) if p is chosen), None)
    if i is None or i + 1 >= len(cands) or cands[i][1] <= 0:
        return None
    (p1, w1), (p2, w2) = cands[i], cands[i + 1]
    if w2 < RUNNER_UP_NEAR * w1 or not elsewhere(front, p1, p2):
        return None
    u2, v2 = unit_place(front, p2)
    return {"ratio": round(w2 / w1, 3), "a_u": round(u2, 3), "a_v": round(v2, 3)}


def describe_handle(front: Front, pts: np.ndarray | None, source: str, cfg: HandlesConfig) -> Handle | None:
    """The handle's place (median of its points [M, 3] in the front's unit square) and shape
    (``extent_percentile`` extents: round when the longer is below ``round_aspect`` x the
    shorter + ``round_slack``)."""
    if pts is None:
        return None
    rel = pts - np.asarray(front.center)
    pu, pv = rel @ np.asarray(front.u), rel @ front.v
    a_u, a_v = unit_place(front, pts)
    lo, hi = cfg.extent_percentile, 100 - cfg.extent_percentile
    eu = np.percentile(pu, hi) - np.percentile(pu, lo)
    ev = np.percentile(pv, hi) - np.percentile(pv, lo)
    round_ = max(eu, ev) < cfg.round_aspect * min(eu, ev) + cfg.round_slack
    orient = "round" if round_ else ("horizontal" if eu > ev else "vertical")
    return Handle(a_u, a_v, orient, len(pts), source, (round(float(eu), 4), round(float(ev), 4)))


def protrusions(front: Front, mesh_points: Float[np.ndarray, "P 3"], normals: Float[np.ndarray, "P 3"],
                cfg: HandlesConfig) -> np.ndarray:
    """Mesh points within the front rectangle and ``min``..``max`` in front of it, except on
    surfaces within ``flat_deg`` of facing up or down (a counter's overhang above a front, a
    shelf) and in rows / columns spanning more than ``full_span`` of the front."""
    rel = mesh_points - np.asarray(front.center)
    pu, pv, pn = rel @ np.asarray(front.u), rel @ front.v, rel @ np.asarray(front.normal)
    sel = (np.abs(pu) <= front.size[0] / 2) & (np.abs(pv) <= front.size[1] / 2) & (pn >= cfg.min) & (pn <= cfg.max)
    sel &= np.abs(normals @ UP) < np.cos(np.deg2rad(cfg.flat_deg))
    # full-width rows / full-height columns are a counter edge, a plinth, a carcass side: not handles
    for coord, other, extent in ((pv, pu, front.size[0]), (pu, pv, front.size[1])):
        bins = np.floor(coord / cfg.row_bin).astype(np.int64)
        for b in np.unique(bins[sel]):
            row = sel & (bins == b)
            if np.ptp(other[row]) > cfg.full_span * extent:
                sel &= ~row
    return mesh_points[sel]


def front_handles(fronts: list[Front], mesh_pts: np.ndarray, pt_normal: np.ndarray, face_centers: np.ndarray,
                  edge_length: float, cfg: HandlesConfig, edge_frac: float, stack_gap: float,
                  handle_hits: np.ndarray | None = None, face_views: np.ndarray | None = None,
                  image_cells: tuple[np.ndarray, np.ndarray, float, int] | None = None,
                  colour: list[np.ndarray | None] | None = None, near: dict[int, dict] | None = None
                  ) -> tuple[list[Handle | None], list[tuple[int, int, str]]]:
    """Each front's handle (or None) from both kinds of evidence, the masks' first; the split
    and the stacked pulls resolved (:func:`resolve_stacked_pulls`, when ``cfg.stacked_pulls``).
    ``mesh_pts`` / ``pt_normal`` [P, 3]: points sampled on the mesh and their normals;
    ``face_centers`` [F, 3]; ``edge_length``: the mesh's typical edge (m). The masks' evidence:
    ``image_cells`` = (points [M, 3], rates [M], link radius m, min points) of the rectified
    fronts (:func:`~drawer_lib.articulation.rectify.rectify_fronts`; source ``images``), else
    the mesh faces they cover: ``handle_hits`` [F], in how many views a "handle" mask covers
    each face, and ``face_views`` [F], in how many views each face is visible (needed by
    ``evidence: view_rate``; source ``masks``). ``colour[k]``: front k's handle read off its
    rectified colours (:func:`colour_handle`; source ``colour``), taken when the masks show none,
    before the mesh's protrusions. Returns (handle per front, [(front that gave up a mask
    candidate, front that took it, why: a format string for the taker's segment id)]): a pull
    split between side-by-side fronts (:func:`resolve_split_pulls`, ``cfg.split_pulls``) is
    resolved first, then the stacked ones. ``near``: gets, per front whose masks' handle was
    chosen without a margin, :func:`runner_up`'s record."""
    geo = [protrusions(f, mesh_pts, pt_normal, cfg) for f in fronts]
    geo_pts = np.concatenate(geo) if geo else np.zeros((0, 3))
    by_geo = heaviest(handle_candidates(fronts, geo_pts, cfg, cfg.geo_radius, cfg.geo_min_points))
    if image_cells is not None:
        pts, rates, radius, min_points = image_cells
        mask_cands = handle_candidates(fronts, pts, cfg, radius, min_points, weights=rates)
        source = "images"
    else:
        mask_cands = _face_candidates(fronts, face_centers, edge_length, cfg, handle_hits, face_views)
        source = "masks"
    split: list[tuple[int, int, float]] = []
    if cfg.split_pulls:
        mask_cands, split = resolve_split_pulls(fronts, mask_cands, cfg.max_gap, cfg.split_margin)
    if cfg.stacked_pulls:
        by_mask, gave_up = resolve_stacked_pulls(fronts, mask_cands, edge_frac, stack_gap, cfg.stacked_plane_tol,
                                                 cfg.stacked_min_overlap)
    else:
        by_mask, gave_up = heaviest(mask_cands), []
    if near is not None:
        for k, (f, c, m) in enumerate(zip(fronts, mask_cands, by_mask)):
            r = runner_up(f, c, m) if m is not None else None
            if r is not None:
                near[k] = r
    gave = ([(a, b, f"the pull it shared with segment {{}} reaches {100 * d:.1f} cm deeper into that front, "
                    "which took it") for a, b, d in split]
            + [(a, b, "the pull it shared with segment {} went there") for a, b in gave_up])
    by_colour = colour if colour is not None else [None] * len(fronts)
    handles = [describe_handle(f, m, source, cfg) if m is not None
               else describe_handle(f, c, "colour", cfg) if c is not None
               else describe_handle(f, g, "geometry", cfg)
               for f, g, m, c in zip(fronts, by_geo, by_mask, by_colour)]
    return handles, gave


def _face_candidates(fronts: list[Front], face_centers: np.ndarray, edge_length: float, cfg: HandlesConfig,
                     handle_hits: np.ndarray | None, face_views: np.ndarray | None) -> Candidates:
    """Handle candidates from the mesh faces that "handle" masks cover (:func:`front_handles`)."""
    hit_faces = np.nonzero(handle_hits >= cfg.min_hits)[0] if handle_hits is not None else np.zeros(0, np.int64)
    hit_w = None
    if cfg.evidence == "view_rate" and handle_hits is not None:
        if face_views is None:
            raise InputError("articulate.handles.evidence = view_rate needs face_views (a decompose output that "
                             "stores them: re-run decompose)")
        if len(face_views) != len(handle_hits):
            raise InputError(f"articulate: face_views has {len(face_views)} entries, handle_hits {len(handle_hits)}")
        hit_w = np.clip(handle_hits[hit_faces] / np.maximum(face_views[hit_faces], 1), 0.0, 1.0)
    radius = max(cfg.geo_radius, cfg.mask_radius_spacing * edge_length)
    return handle_candidates(fronts, face_centers[hit_faces], cfg, radius, cfg.mask_min_points, weights=hit_w)
