"""Articulation inference: segments + mesh -> parts (DESIGN §5), without learned models.

Per planar, vertical segment:

- **front**: a robust plane through the segment (area-weighted, re-fitted on the inliers),
  outward normal toward the cameras that saw it, ``u`` horizontal, the rectangle from robust
  (2nd-98th percentile) extents of the segment's points in (u, v);
- **handle**: mesh points within the rectangle and ``handle_min``..``handle_max`` in front of
  the plane, plus faces hit by "handle" masks; per front the largest cluster (by face count, or
  with ``handle_evidence: view_rate`` by the fraction of the views seeing each face in which a
  mask covers it), its median in the front's unit square (a_u left->right, a_v bottom->top)
  and its elongation (horizontal, vertical or round);
- **type** (the rule DRAWER applies to the 3DOI affordance peak, reference §3.10(c), with the
  handle in place of the peak):

  | evidence | type |
  |---|---|
  | handle near the left / right edge (a_u < f or > 1 - f; a horizontal one within f / 2) | door hinged on the far side |
  | handle near the bottom edge | flap hinged at the top |
  | handle near the top edge | drawer, or a flap hinged at the bottom when the labels say door |
  | handle central | drawer |
  | a neighbouring front overlapping it in u at a different depth | sliding door (toward it) |
  | no handle | not articulated (a fixed panel) |

- **axis**: revolute on the hinge edge, direction = (hinge -> free side) x outward normal, so a
  positive angle opens outward; prismatic along the outward normal (drawer) or along u (sliding).
- **limits**: revolute ``revolute_limit_deg``; a drawer travels ``drawer_travel`` x the depth
  of the carcass the mesh shows behind the front (distance to the farthest surface facing the
  same way behind it, within 1 m), sliding doors the partner's width minus the overlap.

Non-planar segments become ``rigid`` parts (centre and axis-aligned bounds).
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh

from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Axis, Front, Part
from drawer_lib.perception.config import ArticulateConfig
from drawer_lib.perception.decompose import Segment
from drawer_lib.perception.views import UP, connected_components, plane_axes


@dataclass
class Handle:
    a_u: float  # handle centroid in the front's unit square, left -> right
    a_v: float  # bottom -> top
    orientation: str  # horizontal | vertical | round
    n_points: int
    source: str  # geometry (mesh protrusions) | masks (handle detections)


@dataclass
class Decision:
    family: str  # drawer | door | flap | sliding | fixed
    hinge: str | None = None  # left | right | top | bottom (revolute)
    reason: str = ""


def _sample_points(mesh: trimesh.Trimesh, faces: np.ndarray, per_m2: float = 40000.0, seed: int = 0,
                   with_faces: bool = False):
    """Area-uniform points on the given faces (plus their centroids); with ``with_faces`` also
    the face id of each point."""
    tri = np.asarray(mesh.triangles)[faces]
    area = np.asarray(mesh.area_faces)[faces]
    n = int(min(max(area.sum() * per_m2, 0), 400_000))
    cen = tri.mean(1)
    if n == 0 or area.sum() <= 0:
        return (cen, faces) if with_faces else cen
    rng = np.random.default_rng(seed)
    k = rng.choice(len(faces), n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    b = np.stack([1 - s, s * (1 - r2), s * r2], -1)
    pts = np.concatenate([cen, (b[:, :, None] * tri[k]).sum(1)])
    return (pts, np.concatenate([faces, faces[k]])) if with_faces else pts


def fit_front(mesh: trimesh.Trimesh, seg: Segment, cam_centers: np.ndarray, inlier_m: float = 0.01) -> Front | None:
    """The front rectangle of a planar segment, or None for a degenerate one."""
    P = _sample_points(mesh, seg.faces)
    if len(P) < 3:
        return None
    n = seg.normal / max(np.linalg.norm(seg.normal), 1e-12)
    if not np.all(np.isfinite(n)) or np.linalg.norm(n) < 0.5:
        return None
    c = np.median(P, 0)
    for _ in range(3):  # re-fit the plane on its inliers
        d = (P - c) @ n
        inl = np.abs(d - np.median(d)) < inlier_m
        if inl.sum() < 3:
            break
        Q = P[inl]
        c = Q.mean(0)
        _, _, vt = np.linalg.svd(Q - c, full_matrices=False)
        n_new = vt[2]
        n = n_new if n_new @ n >= 0 else -n_new
    # outward = toward the cameras
    view = cam_centers - c
    if np.sum(view @ n > 0) < len(cam_centers) / 2:
        n = -n
    u, v = plane_axes(n)
    d = (P - c) @ n
    inl = np.abs(d - np.median(d)) < inlier_m
    Q = P[inl] if inl.sum() >= 3 else P
    uv = np.stack([(Q - c) @ u, (Q - c) @ v], -1)
    lo, hi = np.percentile(uv, 2, 0), np.percentile(uv, 98, 0)
    mid = (lo + hi) / 2
    lo, hi = mid + (lo - mid) / 0.96, mid + (hi - mid) / 0.96  # percentiles of a uniform spread
    off = float(np.percentile((Q - c) @ n, 90))  # the outer face of the panel
    center = c + mid[0] * u + mid[1] * v + off * n
    size = hi - lo
    return Front(tuple(center.tolist()), tuple(n.tolist()), tuple(u.tolist()), (float(size[0]), float(size[1])))


def handle_clusters(points: np.ndarray, radius: float = 0.015, min_points: int = 6) -> list[np.ndarray]:
    """Handle candidates: indices into ``points`` [N, 3] of the groups that single linkage at
    ``radius`` (m) forms, each of at least ``min_points``."""
    if len(points) < min_points:
        return []
    from scipy.spatial import cKDTree

    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray").astype(np.int64).reshape(-1, 2)
    lab = connected_components(len(points), pairs)
    return [np.nonzero(lab == k)[0] for k in np.unique(lab) if (lab == k).sum() >= min_points]


def handle_candidates(fronts: list[Front], points: np.ndarray, cfg: ArticulateConfig, radius: float,
                      min_points: int, max_gap: float = 0.03, max_span: float = 0.85,
                      weights: np.ndarray | None = None) -> list[list[tuple[np.ndarray, float]]]:
    """Per front, its handle candidates [(points [M, 3], total weight)], heaviest first: every
    handle point goes to the front whose rectangle it lies deepest in (signed in-plane distance,
    negative inside; at most ``max_gap`` outside) among those it stands 0..``handle_max`` in
    front of; the candidates are the clusters of a front's points (:func:`handle_clusters`) that
    span less than ``max_span`` of the front either way, weighed by ``weights`` [N] >= 0
    (default 1 per point). An edge pull straddling the gap between two fronts thus goes, point
    by point, mostly to the front it reaches into."""
    out: list[list[tuple[np.ndarray, float]]] = [[] for _ in fronts]
    if len(fronts) == 0 or len(points) == 0:
        return out
    w_all = np.ones(len(points)) if weights is None else np.asarray(weights, float)
    if w_all.shape != (len(points),) or not np.all(np.isfinite(w_all)) or (w_all < 0).any():
        raise ValueError(f"assign_handles: weights must be [{len(points)}] finite and >= 0")
    best = np.full(len(points), np.inf)
    owner = np.full(len(points), -1)
    for k, f in enumerate(fronts):
        rel = points - np.asarray(f.center)
        eu = np.abs(rel @ np.asarray(f.u)) - f.size[0] / 2
        ev = np.abs(rel @ f.v) - f.size[1] / 2
        h = rel @ np.asarray(f.normal)
        inside = (eu <= 0) & (ev <= 0)
        d = np.where(inside, np.maximum(eu, ev), np.hypot(np.maximum(eu, 0), np.maximum(ev, 0)))
        ok = (h >= -0.01) & (h <= cfg.handle_max) & (d <= max_gap) & (d < best)
        best[ok] = d[ok]
        owner[ok] = k
    for k, f in enumerate(fronts):
        u, v = np.asarray(f.u), f.v
        pts, w = points[owner == k], w_all[owner == k]
        # a handle is shorter than its front: a cluster spanning it is a counter edge or a plinth
        cl = [i for i in handle_clusters(pts, radius, min_points)
              if np.ptp(pts[i] @ u) < max_span * f.size[0] and np.ptp(pts[i] @ v) < max_span * f.size[1]]
        cl.sort(key=lambda i: (-float(w[i].sum()), -len(i)))
        out[k] = [(pts[i], float(w[i].sum())) for i in cl]
    return out


def _heaviest(cands: list[list[tuple[np.ndarray, float]]]) -> list[np.ndarray | None]:
    return [c[0][0] if c else None for c in cands]


def assign_handles(fronts: list[Front], points: np.ndarray, cfg: ArticulateConfig, radius: float, min_points: int,
                   max_gap: float = 0.03, max_span: float = 0.85, weights: np.ndarray | None = None
                   ) -> list[np.ndarray | None]:
    """The handle points [M, 3] of each front: its heaviest candidate (:func:`handle_candidates`);
    with weights = how often the masks hold a point, the fringe that ragged masks smear onto a
    neighbour weighs less than the pull it belongs to."""
    return _heaviest(handle_candidates(fronts, points, cfg, radius, min_points, max_gap, max_span, weights))


def resolve_stacked_pulls(fronts: list[Front], cands: list[list[tuple[np.ndarray, float]]], edge_frac: float,
                          max_gap: float = 0.03, plane_tol: float = 0.02, min_overlap: float = 0.5
                          ) -> tuple[list[np.ndarray | None], list[tuple[int, int]]]:
    """The handle of each front (its heaviest candidate) once stacked fronts share no pull.

    An edge pull in the gap between a front and the one below it (:func:`abutting_edges`) is
    seen by both:
    masks ragged by a pixel or two at ~1.3 cm per pixel cover both sides, so the upper front
    may take the lower one's pull as "a handle near my bottom edge" (a flap) while the lower
    takes it as its top-edge pull. When the upper front's choice lies in its bottom ``edge_frac``
    and the lower front's in its top ``edge_frac``, both wider than tall and overlapping in width,
    they are one pull, and it goes to the lower front: a pull in such a gap is a lip pull on the
    top edge of the front below (the point weights cannot tell: on kitchen_tiny's drawer stack
    the upper front holds 75 of the pull's mask faces, the lower 30). The upper front takes its
    next candidate if it has one; repeated until nothing changes (in a stack of three, the
    middle front's change can make the top one's choice a shared pull). Returns (handle points
    per front or None, [(front that gave up a candidate, front below)])."""
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


def describe_handle(front: Front, pts: np.ndarray | None, source: str) -> Handle | None:
    """The handle's place (median of its points [M, 3] in the front's unit square) and shape
    (5th-95th percentile extents)."""
    if pts is None:
        return None
    c, u, v = np.asarray(front.center), np.asarray(front.u), front.v
    hw, hh = front.size[0] / 2, front.size[1] / 2
    rel = pts - c
    pu, pv = rel @ u, rel @ v
    a_u = float(np.clip((np.median(pu) + hw) / max(2 * hw, 1e-9), 0, 1))
    a_v = float(np.clip((np.median(pv) + hh) / max(2 * hh, 1e-9), 0, 1))
    eu = np.percentile(pu, 95) - np.percentile(pu, 5)
    ev = np.percentile(pv, 95) - np.percentile(pv, 5)
    orient = "round" if max(eu, ev) < 1.8 * min(eu, ev) + 0.01 else ("horizontal" if eu > ev else "vertical")
    return Handle(a_u, a_v, orient, int(len(pts)), source)


def protrusions(front: Front, mesh_points: np.ndarray, normals: np.ndarray, cfg: ArticulateConfig) -> np.ndarray:
    """Mesh points within the front rectangle and ``handle_min``..``handle_max`` in front of it,
    except on surfaces facing up or down (a counter's overhang above a front, a shelf)."""
    rel = mesh_points - np.asarray(front.center)
    pu, pv, pn = rel @ np.asarray(front.u), rel @ front.v, rel @ np.asarray(front.normal)
    sel = (np.abs(pu) <= front.size[0] / 2) & (np.abs(pv) <= front.size[1] / 2) & (pn >= cfg.handle_min) & (pn <= cfg.handle_max)
    sel &= np.abs(normals @ UP) < np.cos(np.deg2rad(30.0))
    # full-width rows / full-height columns are a counter edge, a plinth, a carcass side: not handles
    for coord, other, extent in ((pv, pu, front.size[0]), (pu, pv, front.size[1])):
        bins = np.floor(coord / 0.01).astype(np.int64)
        for b in np.unique(bins[sel]):
            row = sel & (bins == b)
            if np.ptp(other[row]) > 0.8 * extent:
                sel &= ~row
    return mesh_points[sel]


def decide(h: Handle | None, labels: dict, cfg: ArticulateConfig) -> Decision:
    """The type from the handle position (and, for the one ambiguous case, the label votes)."""
    if h is None:
        return Decision("fixed", reason="no handle")
    f = cfg.edge_frac
    side = h.a_u < f or h.a_u > 1 - f
    if side and (h.orientation != "horizontal" or h.a_u < f / 2 or h.a_u > 1 - f / 2):
        # doors carry their handle at the free side (a horizontal bar only right at the edge)
        return Decision("door", "right" if h.a_u < 0.5 else "left", "handle near a side edge")
    if h.a_v < f:
        return Decision("flap", "top", "handle near the bottom edge")
    if h.a_v > 1 - f:
        if cfg.use_labels:
            door_votes = sum(v for k, v in labels.items() if k in ("door", "flap", "cabinet door"))
            drawer_votes = sum(v for k, v in labels.items() if k == "drawer")
            if door_votes > drawer_votes:
                return Decision("flap", "bottom", "handle near the top edge; labels say door")
        return Decision("drawer", reason="handle near the top edge")
    if side:  # a horizontal bar near a side, halfway up: still a side-hinged door
        return Decision("door", "right" if h.a_u < 0.5 else "left", "handle near a side edge")
    return Decision("drawer", reason="central handle")


def refine_with_masks(front: Front, masks: list[tuple[np.ndarray, np.ndarray, tuple]], min_frames: int = 2,
                      border_px: int = 2) -> tuple[Front, int]:
    """The front's rectangle from the 2D masks it matched: each mask's pixels are cast onto the
    front plane; per mask and side, the 1st / 99th percentile extent along u and v (corrected
    for a uniform spread); per side the median over the masks whose extreme pixels on that side
    do not touch the image border (a mask cut by the frame says nothing about that edge). A side
    with fewer than ``min_frames`` such masks keeps the mesh fit. ``masks``: [(bool mask [H, W],
    w2c, (fx, fy, cx, cy))]. Returns (front, masks used)."""
    c, u = np.asarray(front.center), np.asarray(front.u)
    v = front.v
    hw, hh = front.size[0] / 2, front.size[1] / 2
    sides: list[list[float]] = [[], [], [], []]  # lo_u, lo_v, hi_u, hi_v
    used = 0
    for mk in masks:
        r = _mask_uv(front, mk, border_px)
        if r is None:
            continue
        uv, at_border = r
        lo, hi = np.percentile(uv, 1, 0), np.percentile(uv, 99, 0)
        mid = (lo + hi) / 2
        lo_c, hi_c = mid + (lo - mid) / 0.98, mid + (hi - mid) / 0.98
        any_side = False
        for a in range(2):
            if not at_border[uv[:, a] <= lo[a]].any():
                sides[a].append(lo_c[a])
                any_side = True
            if not at_border[uv[:, a] >= hi[a]].any():
                sides[2 + a].append(hi_c[a])
                any_side = True
        used += any_side
    fallback = [-hw, -hh, hw, hh]
    ext = [float(np.median(x)) if len(x) >= min_frames else fb for x, fb in zip(sides, fallback)]
    lo_u, lo_v, hi_u, hi_v = ext
    if hi_u <= lo_u or hi_v <= lo_v:
        return front, 0
    center = c + (lo_u + hi_u) / 2 * u + (lo_v + hi_v) / 2 * v
    return Front(tuple(center.tolist()), front.normal, front.u, (float(hi_u - lo_u), float(hi_v - lo_v))), used


def _mask_uv(front: Front, mk, border_px: int) -> tuple[np.ndarray, np.ndarray] | None:
    """((u, v) [N, 2] of a mask's pixels cast onto the front plane, [N] pixel within
    ``border_px`` of the image border); ``mk`` = (mask, w2c, K)."""
    from drawer_lib.geometry.camera import invert_rigid

    mask, w2c, K = mk
    H, W = mask.shape
    ii, jj = np.nonzero(mask)
    if len(ii) < 20:
        return None
    fx, fy, cx, cy = K
    d_cam = np.stack([(jj + 0.5 - cx) / fx, (ii + 0.5 - cy) / fy, np.ones(len(ii))], -1)
    c2w = invert_rigid(w2c)
    d = d_cam @ c2w[:3, :3].T
    o = c2w[:3, 3]
    c, n = np.asarray(front.center), np.asarray(front.normal)
    den = d @ n
    ok = np.abs(den) > 1e-9
    t = ((c - o) @ n) / np.where(ok, den, 1.0)
    ok &= t > 0
    if ok.sum() < 20:
        return None
    P = o + t[ok, None] * d[ok]
    rel = P - c
    border = (ii < border_px) | (ii >= H - border_px) | (jj < border_px) | (jj >= W - border_px)
    return np.stack([rel @ np.asarray(front.u), rel @ front.v], -1), border[ok]


def abutting_edges(a: Front, b: Front, max_gap: float, plane_tol: float, min_overlap: float = 0.5,
                   max_angle_deg: float = 10.0) -> list[tuple[int, int, float]]:
    """Where front ``b`` abuts front ``a``: [(axis, side, offset)] with axis 0 (a's u) or 1 (a's
    v), side +1 when b lies beyond a's high edge along that axis and -1 beyond its low edge, and
    offset = b's centre along the *other* axis in a's frame (m). Abutting: coplanar within
    ``plane_tol`` m, same axes within ``max_angle_deg``, the facing edges under ``max_gap`` m
    apart either way, overlapping over ``min_overlap`` of the shorter side."""
    cos_t = np.cos(np.deg2rad(max_angle_deg))
    na, ua, va = np.asarray(a.normal), np.asarray(a.u), a.v
    d = np.asarray(b.center) - np.asarray(a.center)
    if na @ np.asarray(b.normal) < cos_t or ua @ np.asarray(b.u) < cos_t or abs(d @ na) > plane_tol:
        return []
    du, dv = d @ ua, d @ va  # b's centre in a's frame
    aw, ah, bw, bh = a.size[0] / 2, a.size[1] / 2, b.size[0] / 2, b.size[1] / 2
    out = []
    for ax, off, (alo, ahi), (blo, bhi), (olo, ohi), (oblo, obhi), other in (
            (0, du, (-aw, aw), (du - bw, du + bw), (-ah, ah), (dv - bh, dv + bh), dv),
            (1, dv, (-ah, ah), (dv - bh, dv + bh), (-aw, aw), (du - bw, du + bw), du)):
        overlap = min(ohi, obhi) - max(olo, oblo)
        if overlap < min_overlap * min(ohi - olo, obhi - oblo):
            continue
        if off > 0 and abs(blo - ahi) < max_gap:
            out.append((ax, 1, float(other)))
        elif off < 0 and abs(alo - bhi) < max_gap:
            out.append((ax, -1, float(other)))
    return out


def share_edges(fronts: list[Front], max_gap: float, plane_tol: float = 0.006, min_overlap: float = 0.5,
                max_angle_deg: float = 10.0) -> list[Front]:
    """Fronts whose facing edges abut (:func:`abutting_edges`) have one boundary, estimated
    independently from each front's masks: both edges move to the midpoint of the two estimates
    (the mean of the midpoints when an edge has several neighbours), halving the variance of a
    hinge edge that a neighbour shares. A sliding pair, a track apart, is not coplanar and is
    left alone. ``max_gap`` <= 0 returns the fronts unchanged."""
    if max_gap <= 0 or len(fronts) < 2:
        return fronts
    # per front: (lo_u, hi_u, lo_v, hi_v) in its own frame
    ext = [[-f.size[0] / 2, f.size[0] / 2, -f.size[1] / 2, f.size[1] / 2] for f in fronts]
    props: list[list[list[float]]] = [[[], [], [], []] for _ in fronts]
    for i, a in enumerate(fronts):
        for j in range(i + 1, len(fronts)):
            b = fronts[j]
            d = np.asarray(b.center) - np.asarray(a.center)
            offs = (d @ np.asarray(a.u), d @ a.v)  # b's centre in a's frame
            for ax, side, _ in abutting_edges(a, b, max_gap, plane_tol, min_overlap, max_angle_deg):
                k = 2 * ax  # index of lo along this axis in (lo_u, hi_u, lo_v, hi_v)
                off, half_b = offs[ax], b.size[ax] / 2
                if side > 0:  # b beyond a's high edge
                    m = (ext[i][k + 1] + (off - half_b)) / 2
                    props[i][k + 1].append(m)
                    props[j][k].append(m - off)
                else:  # b beyond a's low edge
                    m = (ext[i][k] + (off + half_b)) / 2
                    props[i][k].append(m)
                    props[j][k + 1].append(m - off)
    out = []
    for f, e, pr in zip(fronts, ext, props):
        e = [float(np.mean(x)) if x else y for x, y in zip(pr, e)]
        if e[1] <= e[0] or e[3] <= e[2]:
            out.append(f)
            continue
        c = np.asarray(f.center) + (e[0] + e[1]) / 2 * np.asarray(f.u) + (e[2] + e[3]) / 2 * f.v
        out.append(Front(tuple(c.tolist()), f.normal, f.u, (e[1] - e[0], e[3] - e[2])))
    return out


def hinge_axis(front: Front, hinge: str) -> Axis:
    c, n, u = np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u)
    v = front.v
    edge = {"left": -u * front.size[0] / 2, "right": u * front.size[0] / 2,
            "bottom": -v * front.size[1] / 2, "top": v * front.size[1] / 2}[hinge]
    to_free = -edge / np.linalg.norm(edge)
    d = np.cross(to_free, n)
    return Axis(tuple((c + edge).tolist()), tuple((d / np.linalg.norm(d)).tolist()))


def carcass_depth(front: Front, mesh_points: np.ndarray, mesh_normals: np.ndarray, max_depth: float = 1.0) -> float | None:
    """Depth of the cabinet behind a front as the mesh shows it: the farthest point facing the
    same way as the front (a wall or back panel) behind it, within the front's u-range."""
    c, n, u = np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u)
    rel = mesh_points - c
    d = -(rel @ n)
    sel = (d > 0.1) & (d < max_depth) & (np.abs(rel @ u) < front.size[0] / 2) & ((mesh_normals @ n) > 0.9)
    if sel.sum() < 10:
        return None
    return float(np.percentile(d[sel], 10))


def _rigid(seg: Segment, mesh: trimesh.Trimesh, k: int) -> Part:
    V = np.asarray(mesh.vertices)[np.unique(np.asarray(mesh.faces)[seg.faces])]
    lo, hi = V.min(0), V.max(0)
    return Part(f"object_{k}", "rigid", center=tuple(((lo + hi) / 2).tolist()),
                bounds=(tuple(lo.tolist()), tuple(hi.tolist())), extra={"segment": seg.id, "labels": seg.labels})


# -- learned estimators (slots) ------------------------------------------------------------------
Estimator = Callable[..., tuple[list[Part], list[dict]]]
_REGISTRY: dict[str, Estimator] = {}
_SLOTS = {"3doi": "3DOI (SAM-transformer ViT-B, checkpoint_20230515.pth)",
          "vlm": "a vision-language model (DRAWER: GPT-4o through the OpenAI API)"}


def register_estimator(name: str, fn: Estimator) -> None:
    """Make ``articulate.estimator: <name>`` call ``fn(mesh, segments, cam_centers, cfg, **kw)``
    -> (parts, per-segment decisions), like :func:`infer_parts`."""
    _REGISTRY[name] = fn


def get_estimator(name: str) -> Estimator:
    if name == "geometric":
        return infer_parts
    if name in _REGISTRY:
        return _REGISTRY[name]
    if name in _SLOTS:
        raise ConfigError(f"articulate.estimator = {name!r}: {_SLOTS[name]} needs weights or a service that are not "
                          "available here; use 'geometric' or register an implementation with "
                          "drawer_lib.perception.articulate.register_estimator")
    raise ConfigError(f"articulate.estimator = {name!r} is unknown (known: geometric, {sorted(_REGISTRY) + sorted(_SLOTS)})")


def _local_step(fa: Front, fb: Front, pa: np.ndarray, pb: np.ndarray, band: float = 0.08) -> float:
    """How far front b lies behind front a (m), measured on the segments' own points within
    ``band`` of the line between them along the mean normal — not from the two centres, whose
    lateral distance times a degree of plane-fit tilt would fake a step."""
    n = np.asarray(fa.normal) + np.asarray(fb.normal)
    n /= np.linalg.norm(n)
    u = np.asarray(fa.u)
    ca, cb = np.asarray(fa.center), np.asarray(fb.center)
    mid = ca + u * np.sign((cb - ca) @ u) * fa.size[0] / 2  # a's edge facing b
    near_a = pa[np.abs((pa - mid) @ u) < band]
    near_b = pb[np.abs((pb - mid) @ u) < band]
    if len(near_a) < 3 or len(near_b) < 3:
        return float((ca - cb) @ n)
    return float(np.median(near_a @ n) - np.median(near_b @ n))


def _sliding_partners(fronts: list[Front], handles: list[Handle | None], cfg: ArticulateConfig,
                      points: list[np.ndarray]) -> dict[int, tuple[int, float]]:
    """Sliding doors: a front standing out of the run by a step of ``sliding_step`` (the outer
    panel on its own track; measured locally, :func:`_local_step`) and the adjacent
    stepped-back front of the same height on the side away from its handle (the inner panel).
    ``points``: each front's segment points. Returns {front: (partner, overlap in u (m))} for
    both panels of each pair; the outer one is paired first and only once."""
    out: dict[int, tuple[int, float]] = {}
    cands = []
    for a, fa in enumerate(fronts):
        na, ua = np.asarray(fa.normal), np.asarray(fa.u)
        for b, fb in enumerate(fronts):
            if a == b or np.dot(na, fb.normal) < 0.95:
                continue
            dc = np.asarray(fb.center) - np.asarray(fa.center)
            du = dc @ ua
            overlap_u = (fa.size[0] + fb.size[0]) / 2 - abs(du)
            if overlap_u <= -0.04:  # not adjacent
                continue
            step = _local_step(fa, fb, points[a], points[b])  # > 0: b lies behind a
            if not cfg.sliding_step[0] <= step <= cfg.sliding_step[1]:
                continue
            same_h = abs(fa.size[1] - fb.size[1]) < 0.15 * max(fa.size[1], fb.size[1]) and abs(dc @ fa.v) < 0.1 * fa.size[1]
            if same_h:
                h = handles[a]
                away = 0.0 if h is None else np.sign(0.5 - h.a_u)  # the side away from the handle
                cands.append((away != 0 and np.sign(du) != away, -overlap_u, a, b, overlap_u))
    for _, _, a, b, ov in sorted(cands):
        if a not in out and b not in out:
            out[a] = (b, max(ov, 0.0))
            out[b] = (a, max(ov, 0.0))
    return out


def infer_parts(mesh: trimesh.Trimesh, segs: list[Segment], cam_centers: np.ndarray, cfg: ArticulateConfig,
                handle_hits: np.ndarray | None = None, masks_of: Callable | None = None,
                face_views: np.ndarray | None = None) -> tuple[list[Part], list[dict]]:
    """(parts, per-segment decisions for the report). ``handle_hits`` [F]: in how many views a
    "handle" mask covers each face (faces with >= 2 are handle evidence); ``face_views`` [F]: in
    how many views each face is visible, needed by ``cfg.handle_evidence = view_rate`` (weighs
    each face by hits / views). ``masks_of(segment)`` -> [(mask, w2c, K)] gives the 2D masks a
    segment matched (refines its rectangle); None uses the mesh alone."""
    mesh_pts, pt_face = _sample_points(mesh, np.arange(len(mesh.faces)), per_m2=20000.0, seed=1, with_faces=True)
    pt_normal = np.asarray(mesh.face_normals)[pt_face]
    fc = np.asarray(mesh.triangles_center)
    parts: list[Part] = []
    report: list[dict] = []
    sin_v = np.sin(np.deg2rad(cfg.vertical_deg))
    n_obj = 0
    fits: list[tuple[Segment, Front, dict]] = []
    for s in segs:
        if not s.planar:
            parts.append(_rigid(s, mesh, n_obj))
            n_obj += 1
            report.append({"segment": s.id, "family": "rigid", "reason": "not planar"})
            continue
        fitted = fit_front(mesh, s, cam_centers)
        if fitted is None:
            report.append({"segment": s.id, "family": "none", "reason": "degenerate plane"})
            continue
        if abs(np.dot(fitted.normal, UP)) > sin_v:
            report.append({"segment": s.id, "family": "none", "reason": "not vertical"})
            continue
        front, used = fitted, 0
        if masks_of is not None:
            front, used = refine_with_masks(fitted, masks_of(s))
        w, h = front.size
        if min(w, h) < cfg.min_size or max(w, h) > cfg.max_size:
            report.append({"segment": s.id, "family": "none", "reason": f"size {w:.2f} x {h:.2f} m out of range"})
            continue
        fits.append((s, front, {"rect_from_masks": used}))
    fronts = share_edges([f for _, f, _ in fits], cfg.shared_edge_gap, plane_tol=0.75 * cfg.sliding_step[0])
    fits = [(s, f, info) for (s, _, info), f in zip(fits, fronts)]
    # handles: clusters of handle-mask faces and of mesh protrusions, each given to one front
    geo = [protrusions(f, mesh_pts, pt_normal, cfg) for f in fronts]
    geo_pts = np.concatenate(geo) if geo else np.zeros((0, 3))
    hit_faces = np.nonzero(handle_hits >= 2)[0] if handle_hits is not None else np.zeros(0, np.int64)
    hit_w = None
    if cfg.handle_evidence == "view_rate" and handle_hits is not None:
        if face_views is None:
            raise ValueError("infer_parts: articulate.handle_evidence = view_rate needs face_views (a decompose "
                             "output that stores them: re-run decompose)")
        if len(face_views) != len(handle_hits):
            raise ValueError(f"infer_parts: face_views has {len(face_views)} entries, handle_hits {len(handle_hits)}")
        hit_w = np.clip(handle_hits[hit_faces] / np.maximum(face_views[hit_faces], 1), 0.0, 1.0)
    by_geo = assign_handles(fronts, geo_pts, cfg, 0.015, 10)
    spacing = float(np.sqrt(2 * np.median(mesh.area_faces)))  # mesh edge length: face centroids are this far apart
    mask_cands = handle_candidates(fronts, fc[hit_faces], cfg, max(0.015, 1.5 * spacing), 3, weights=hit_w)
    if cfg.stacked_pulls:
        by_mask, gave_up = resolve_stacked_pulls(fronts, mask_cands, cfg.edge_frac, max(cfg.shared_edge_gap, 0.03))
    else:
        by_mask, gave_up = _heaviest(mask_cands), []
    handles = [describe_handle(f, m, "masks") if m is not None else describe_handle(f, g, "geometry")
               for f, g, m in zip(fronts, by_geo, by_mask)]
    seg_pts = [np.asarray(mesh.triangles_center)[s.faces] for s, _, _ in fits]
    partner = _sliding_partners(fronts, handles, cfg, seg_pts)
    counts: dict[str, int] = {}
    for k, ((s, fr, info), h) in enumerate(zip(fits, handles)):
        if k in partner:
            dec = Decision("sliding", reason="a neighbouring front on another track (depth step)")
        else:
            dec = decide(h, s.labels, cfg)
        reason = dec.reason + "".join(f"; the pull it shared with segment {fits[hi][0].id} went there"
                                      for lo, hi in gave_up if lo == k)
        row = {"segment": s.id, "family": dec.family, "hinge": dec.hinge, "reason": reason,
               "handle": None if h is None else vars(h), "size": [round(x, 4) for x in fr.size], **info}
        report.append(row)
        if dec.family == "fixed":
            continue
        pid = f"{dec.family}_{counts.get(dec.family, 0)}"
        counts[dec.family] = counts.get(dec.family, 0) + 1
        extra = {"family": dec.family, "segment": s.id}
        if dec.family in ("door", "flap"):
            ax = hinge_axis(fr, dec.hinge)
            lim = (0.0, float(np.deg2rad(cfg.revolute_limit_deg)))
            parts.append(Part(pid, "revolute", ax, lim, fr, extra=extra | {"hinge": dec.hinge}))
        elif dec.family == "drawer":
            depth = carcass_depth(fr, mesh_pts, pt_normal)
            travel = cfg.drawer_travel * (depth if depth is not None else cfg.default_depth)
            parts.append(Part(pid, "prismatic", Axis(fr.center, fr.normal), (0.0, float(travel)), fr,
                              extra=extra | {"carcass_depth": depth}))
        else:  # sliding: toward the partner, by its width minus the overlap
            b, ov = partner[k]
            other = fronts[b]
            du = (np.asarray(other.center) - np.asarray(fr.center)) @ np.asarray(fr.u)
            u = np.asarray(fr.u) * (1.0 if du >= 0 else -1.0)
            travel = max(other.size[0] - ov - 0.02, 0.05)
            parts.append(Part(pid, "prismatic", Axis(fr.center, tuple(u.tolist())), (0.0, float(travel)), fr, extra=extra))
        row["part"] = pid
    return parts, report
