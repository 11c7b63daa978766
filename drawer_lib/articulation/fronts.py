"""Front rectangles: a robust plane through a planar segment, its outward normal, the
rectangle from the segment's points or from the 2D masks it matched, and the shared edges of
abutting fronts. Lengths in metres."""

import numpy as np
import trimesh
from jaxtyping import Float, Int

from drawer_lib.articulation.config import FrontsConfig
from drawer_lib.geometry.camera import Camera
from drawer_lib.geometry.frames import plane_axes
from drawer_lib.geometry.sampling import local_triangle_points, sample_triangles
from drawer_lib.io.parts import Front
from drawer_lib.perception.decompose import Segment

MAX_SAMPLES = 400_000


def sample_points(mesh: trimesh.Trimesh, faces: Int[np.ndarray, "K"], per_m2: float, seed: int,
                  local: bool = False) -> tuple[Float[np.ndarray, "P 3"], Int[np.ndarray, "P"]]:
    """The centroids of ``faces`` followed by area-uniform points on them (``per_m2`` per
    square metre, at most 400k); returns (points [P, 3], face id of each point [P]). ``local``:
    each face's points depend on that face alone
    (:func:`~drawer_lib.geometry.sampling.local_triangle_points`; ``seed`` unused), so another
    simplification of the mesh moves the points of the faces it changed only; else a random
    draw over all of them (seeded by ``seed``)."""
    tri = np.asarray(mesh.triangles)[faces]
    area = np.asarray(mesh.area_faces)[faces]
    total = float(area.sum())
    n = int(min(max(total * per_m2, 0), MAX_SAMPLES))
    cen = tri.mean(1)
    if n == 0 or total <= 0:
        return cen, faces
    if local:
        pts, k = local_triangle_points(tri, per_m2 * min(1.0, MAX_SAMPLES / (total * per_m2)), areas=area)
    else:
        pts, k = sample_triangles(tri, n, np.random.default_rng(seed), areas=area)
    return np.concatenate([cen, pts]), np.concatenate([faces, faces[k]])


def _uniform_extent(lo: np.ndarray, hi: np.ndarray, pct: float) -> tuple[np.ndarray, np.ndarray]:
    """The full extent of a uniform spread whose ``pct`` and 100 - ``pct`` percentiles are
    ``lo`` and ``hi``."""
    mid = (lo + hi) / 2
    keep = 1 - 2 * pct / 100
    return mid + (lo - mid) / keep, mid + (hi - mid) / keep


def fit_front(mesh: trimesh.Trimesh, seg: Segment, cam_centers: Float[np.ndarray, "C 3"], cfg: FrontsConfig
              ) -> Front | None:
    """The front rectangle of a planar segment (outward normal toward most of the cameras, u
    horizontal, centre on the panel's outer face), or None for a degenerate one."""
    P, _ = sample_points(mesh, seg.faces, cfg.sample_per_m2, seed=0, local=cfg.sampling == "local")
    if len(P) < 3:
        return None
    n = seg.normal / max(np.linalg.norm(seg.normal), 1e-12)
    if not np.all(np.isfinite(n)) or np.linalg.norm(n) < 0.5:
        return None
    c = np.median(P, 0)
    for _ in range(3):  # re-fit the plane on its inliers
        d = (P - c) @ n
        inl = np.abs(d - np.median(d)) < cfg.inlier_m
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
    inl = np.abs(d - np.median(d)) < cfg.inlier_m
    Q = P[inl] if inl.sum() >= 3 else P
    uv = np.stack([(Q - c) @ u, (Q - c) @ v], -1)
    pct = cfg.extent_percentile
    lo, hi = np.percentile(uv, pct, 0), np.percentile(uv, 100 - pct, 0)
    mid = (lo + hi) / 2
    lo, hi = _uniform_extent(lo, hi, pct)
    off = float(np.percentile((Q - c) @ n, cfg.outer_percentile))  # the outer face of the panel
    center = c + mid[0] * u + mid[1] * v + off * n
    size = hi - lo
    return Front(tuple(center.tolist()), tuple(n.tolist()), tuple(u.tolist()), (float(size[0]), float(size[1])))


def plumb(front: Front, max_deg: float) -> tuple[Front, float]:
    """The gravity prior on a front's joint: a front whose normal rises or falls less than
    ``max_deg`` from the horizontal plane (world +z up) is turned about its centre and its
    horizontal axis u to hang plumb (normal levelled, v vertical; centre and size kept), so
    that a drawer slides level and a door's hinge stands vertical. Returns (front, its tilt
    before, degrees); a steeper front, or ``max_deg`` <= 0, is returned as it is.

    >>> f = Front((0.0, 0.0, 0.5), (0.0, -np.cos(0.05), np.sin(0.05)), (1.0, 0.0, 0.0), (0.4, 0.2))
    >>> g, tilt = plumb(f, 10.0)
    >>> (np.asarray(g.normal) + 0.0).round(6).tolist(), (g.v + 0.0).round(6).tolist(), round(tilt, 3)
    ([0.0, -1.0, 0.0], [0.0, 0.0, 1.0], 2.865)
    """
    n = np.asarray(front.normal, float)
    n = n / np.linalg.norm(n)
    tilt = float(np.degrees(np.arcsin(np.clip(abs(n[2]), 0.0, 1.0))))
    if max_deg <= 0 or tilt >= max_deg:
        return front, tilt
    h = np.array([n[0], n[1], 0.0])
    h = h / np.linalg.norm(h) + 0.0  # no -0.0
    u, _ = plane_axes(h)
    if u @ np.asarray(front.u) < 0:
        u = -u
    return Front(front.center, tuple(h.tolist()), tuple(u.tolist()), front.size), tilt


def sub_front(front: Front, u0: float, u1: float, v0: float | None = None, v1: float | None = None,
              offset: float | None = None) -> Front:
    """The rectangle of ``front`` over u0..u1 and v0..v1 (m from its centre along its u and v;
    v None: its whole height), in its plane and axes, moved ``offset`` m along its normal when
    given: a piece of a front that a cut, the masks or a step made."""
    c, u = np.asarray(front.center), np.asarray(front.u)
    centre = c + 0.5 * (u0 + u1) * u
    h = front.size[1]
    if v0 is not None:
        centre = centre + 0.5 * (v0 + v1) * front.v
        h = v1 - v0
    if offset is not None:
        centre = centre + offset * np.asarray(front.normal)
    return Front(tuple(centre.tolist()), front.normal, front.u, (float(u1 - u0), float(h)))


def cut_u(front: Front, t: float) -> tuple[Front, Front]:
    """``front`` cut across u at ``t`` (0 < t < 1, the cut's place as a fraction of the width
    from the -u side): (the -u piece, the +u piece), each in the front's plane and axes, of the
    front's height, together exactly its width.

    >>> a, b = cut_u(Front((1.0, 0.0, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.8, 0.6)), 0.5)
    >>> a.center, a.size, b.center, b.size
    ((0.8, 0.0, 0.5), (0.4, 0.6), (1.2, 0.0, 0.5), (0.4, 0.6))
    """
    if not 0 < t < 1:
        raise ValueError(f"cut_u: t = {t} must be in (0, 1)")
    w = front.size[0]
    at = (t - 0.5) * w  # the cut's u offset from the centre
    return sub_front(front, -w / 2, at), sub_front(front, at, w / 2)


def mask_uv(front: Front, mask: np.ndarray, cam: Camera, border_px: int, min_pixels: int
            ) -> tuple[np.ndarray, np.ndarray] | None:
    """((u, v) [N, 2] of the pixels of ``mask`` [H, W] cast from ``cam`` onto the front plane,
    [N] pixel within ``border_px`` of the image border), or None for fewer than ``min_pixels``."""
    H, W = mask.shape
    ii, jj = np.nonzero(mask)
    if len(ii) < min_pixels:
        return None
    _, d = cam.rays(ii, jj)
    o = cam.center
    c, n = np.asarray(front.center), np.asarray(front.normal)
    den = d @ n
    ok = np.abs(den) > 1e-9
    t = ((c - o) @ n) / np.where(ok, den, 1.0)
    ok &= t > 0
    if ok.sum() < min_pixels:
        return None
    P = o + t[ok, None] * d[ok]
    rel = P - c
    border = (ii < border_px) | (ii >= H - border_px) | (jj < border_px) | (jj >= W - border_px)
    return np.stack([rel @ np.asarray(front.u), rel @ front.v], -1), border[ok]


def refine_with_masks(front: Front, masks: list[tuple[np.ndarray, Camera]], cfg: FrontsConfig) -> tuple[Front, int]:
    """The front's rectangle from the 2D masks it matched: each mask's pixels are cast onto the
    front plane; per mask and side, the ``mask_percentile`` extent along u and v (corrected
    for a uniform spread); per side the median over the masks whose extreme pixels on that side
    do not touch the image border (a mask cut by the frame says nothing about that edge). A side
    with fewer than ``mask_min_frames`` such masks keeps the mesh fit. ``masks``: [(bool mask
    [H, W], the camera that saw it)]. Returns (front, masks used)."""
    hw, hh = front.size[0] / 2, front.size[1] / 2
    sides: list[list[float]] = [[], [], [], []]  # lo_u, lo_v, hi_u, hi_v
    used = 0
    pct = cfg.mask_percentile
    for mask, cam in masks:
        r = mask_uv(front, mask, cam, cfg.mask_border_px, cfg.mask_min_pixels)
        if r is None:
            continue
        uv, at_border = r
        lo, hi = np.percentile(uv, pct, 0), np.percentile(uv, 100 - pct, 0)
        lo_c, hi_c = _uniform_extent(lo, hi, pct)
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
    ext = [float(np.median(x)) if len(x) >= cfg.mask_min_frames else fb for x, fb in zip(sides, fallback)]
    lo_u, lo_v, hi_u, hi_v = ext
    if hi_u <= lo_u or hi_v <= lo_v:
        return front, 0
    return sub_front(front, lo_u, hi_u, lo_v, hi_v), used


def abutting_edges(a: Front, b: Front, max_gap: float, plane_tol: float, min_overlap: float = 0.5,
                   max_angle_deg: float = 10.0, max_cross: float = 0.0) -> list[tuple[int, int, float]]:
    """Where front ``b`` abuts front ``a``: [(axis, side, offset)] with axis 0 (a's u) or 1 (a's
    v), side +1 when b lies beyond a's high edge along that axis and -1 beyond its low edge, and
    offset = b's centre along the *other* axis in a's frame (m). Abutting: coplanar within
    ``plane_tol`` m, same axes within ``max_angle_deg``, the facing edges under ``max_gap`` m
    apart either way, overlapping over ``min_overlap`` of the shorter side. With ``max_cross``
    > 0 the facing edges may also cross each other (the rectangles overlap along the axis) by
    up to ``max_cross`` x the shorter of the two sides along it; one rectangle over most of the
    other is no neighbour but a repeat, and never abuts."""
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
        cross = max(max_gap, max_cross * min(ahi - alo, bhi - blo))  # how far the edges may run past each other
        if off > 0 and -cross < blo - ahi < max_gap:
            out.append((ax, 1, float(other)))
        elif off < 0 and -cross < alo - bhi < max_gap:
            out.append((ax, -1, float(other)))
    return out


def _coplanar_overlap(a: Front, b: Front, plane_tol: float, max_angle_deg: float) -> tuple[float, float]:
    """(area of the two rectangles' intersection in ``a``'s plane, ``b``'s area there) in m²;
    (0, area) when their normals differ by more than ``max_angle_deg`` or ``b``'s centre lies
    farther than ``plane_tol`` (m) from ``a``'s plane. ``b``'s corners are cast onto ``a``'s u, v
    and bounded there."""
    na, nb = np.asarray(a.normal), np.asarray(b.normal)
    ca = np.asarray(a.center)
    u, v = np.asarray(a.u), a.v
    rel = b.corners() - ca
    bu, bv = rel @ u, rel @ v
    area_b = float(np.ptp(bu) * np.ptp(bv))
    if na @ nb < np.cos(np.deg2rad(max_angle_deg)) or abs((np.asarray(b.center) - ca) @ na) > plane_tol:
        return 0.0, area_b
    lo = np.maximum([-a.size[0] / 2, -a.size[1] / 2], [bu.min(), bv.min()])
    hi = np.minimum([a.size[0] / 2, a.size[1] / 2], [bu.max(), bv.max()])
    return float(np.prod(np.clip(hi - lo, 0.0, None))), area_b


def coplanar_iou(a: Front, b: Front, plane_tol: float = 0.05, max_angle_deg: float = 25.0) -> float:
    """IoU of two fronts' rectangles in ``a``'s plane (``b``'s corners cast onto ``a``'s u, v and
    bounded there); 0 when their normals differ by more than ``max_angle_deg`` or ``b``'s centre
    lies farther than ``plane_tol`` (m) from ``a``'s plane."""
    inter, area_b = _coplanar_overlap(a, b, plane_tol, max_angle_deg)
    union = a.size[0] * a.size[1] + area_b - inter
    return inter / union if union > 0 else 0.0


def share_inside(a: Front, b: Front, plane_tol: float, max_angle_deg: float = 10.0) -> float:
    """The share of ``b``'s rectangle that lies inside ``a``'s (in ``a``'s plane), in [0, 1]; 0
    when the two are not coplanar (as :func:`coplanar_iou` says, with these tolerances)."""
    inter, area_b = _coplanar_overlap(a, b, plane_tol, max_angle_deg)
    return inter / area_b if area_b > 0 else 0.0


def edge_moves(before: Front, after: Front) -> dict[str, float]:
    """How far each side of ``before`` moved inward to give ``after`` (same plane and axes):
    {"left" / "right" / "bottom" / "top" (along u, v): m}, negative for a side that moved out."""
    d = np.asarray(after.center) - np.asarray(before.center)
    cu, cv = float(d @ np.asarray(before.u)), float(d @ before.v)
    (bw, bh), (aw, ah) = (np.asarray(before.size) / 2).tolist(), (np.asarray(after.size) / 2).tolist()
    return {"left": (cu - aw) + bw, "right": bw - (cu + aw), "bottom": (cv - ah) + bh, "top": bh - (cv + ah)}


def share_edges(fronts: list[Front], max_gap: float, plane_tol: float = 0.006, min_overlap: float = 0.5,
                max_angle_deg: float = 10.0, max_cross: float = 0.0,
                points: list[Float[np.ndarray, "_ 3"] | None] | None = None, pct: float = 2.0) -> list[Front]:
    """Fronts whose facing edges abut (:func:`abutting_edges`) have one boundary, estimated
    independently from each front's masks: both edges move to the midpoint of the two estimates
    (the mean of the midpoints when an edge has several neighbours), halving the variance of a
    hinge edge that a neighbour shares. That includes two coplanar rectangles that run into
    each other by more than ``max_gap``, up to ``max_cross`` x the shorter side (masks that
    spill onto a neighbour): two fronts in one plane cannot both be there, so neither could
    open past the other. One front's masks spilt, not both, so the middle of the overlap is no
    estimate of the boundary: with ``points`` (each front's own surface points [P, 3], None for
    one without) the boundary is where the two surfaces part, midway between the ``pct`` and
    100 - ``pct`` percentiles of the two fronts' points along that axis (bounded by the overlap),
    and the middle of the overlap only where either has fewer than 10 points. A sliding pair, a
    track apart, is not coplanar and is left alone. ``max_gap`` <= 0 returns the fronts
    unchanged."""
    if max_gap <= 0 or len(fronts) < 2:
        return fronts
    # per front: (lo_u, hi_u, lo_v, hi_v) in its own frame
    ext = [[-f.size[0] / 2, f.size[0] / 2, -f.size[1] / 2, f.size[1] / 2] for f in fronts]
    props: list[list[list[float]]] = [[[], [], [], []] for _ in fronts]

    def along(k: int, f: Front, ax: int) -> np.ndarray | None:  # front k's points along f's axis ax
        P = None if points is None else points[k]
        if P is None or len(P) < 10:
            return None
        return (np.asarray(P) - np.asarray(f.center)) @ (np.asarray(f.u) if ax == 0 else f.v)

    for i, a in enumerate(fronts):
        for j in range(i + 1, len(fronts)):
            b = fronts[j]
            d = np.asarray(b.center) - np.asarray(a.center)
            offs = (d @ np.asarray(a.u), d @ a.v)  # b's centre in a's frame
            for ax, side, _ in abutting_edges(a, b, max_gap, plane_tol, min_overlap, max_angle_deg, max_cross):
                k = 2 * ax  # index of lo along this axis in (lo_u, hi_u, lo_v, hi_v)
                off, half_b = offs[ax], b.size[ax] / 2
                # a's facing edge and b's, in a's frame: (low front's high edge, high front's low edge)
                lo_hi, hi_lo = (ext[i][k + 1], off - half_b) if side > 0 else (off + half_b, ext[i][k])
                m = (lo_hi + hi_lo) / 2
                pa, pb = (along(i, a, ax), along(j, a, ax)) if hi_lo - lo_hi < -max_gap else (None, None)
                if pa is not None and pb is not None:  # they cross: where the surfaces part
                    lo_pts, hi_pts = (pa, pb) if side > 0 else (pb, pa)
                    m = float(np.clip((np.percentile(lo_pts, 100 - pct) + np.percentile(hi_pts, pct)) / 2,
                                      hi_lo, lo_hi))
                if side > 0:  # b beyond a's high edge
                    props[i][k + 1].append(m)
                    props[j][k].append(m - off)
                else:  # b beyond a's low edge
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
