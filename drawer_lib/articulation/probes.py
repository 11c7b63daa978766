"""Mesh probes: what the reconstructed mesh shows around a front, measured on points sampled
on it (each with its face normal). The depth of the cabinet behind a front, how far a
neighbouring front lies behind it, and the track a sliding door runs on. Lengths in metres;
a front's frame is (``u``, ``v`` = normal x u, ``normal``) about the centre of its outer face
(:class:`~drawer_lib.io.parts.Front`)."""

from dataclasses import replace

import numpy as np

from drawer_lib.articulation.config import JointsConfig
from drawer_lib.io.parts import Front


def carcass_depth(front: Front, mesh_points: np.ndarray, mesh_normals: np.ndarray, cfg: JointsConfig) -> float | None:
    """Depth of the cabinet behind a front as the mesh shows it: a low percentile of the
    distances of the points facing the same way as the front (a wall or back panel) behind it,
    within the front's rectangle (its u- and v-range: the fronts of the wall cabinets above a
    base cabinet face the same way but are not behind it); None when the mesh shows too few."""
    c, n, u = np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u)
    rel = mesh_points - c
    d = -(rel @ n)
    sel = ((d > cfg.carcass_min_depth) & (d < cfg.carcass_max_depth) & (np.abs(rel @ u) < front.size[0] / 2)
           & (np.abs(rel @ front.v) < front.size[1] / 2) & ((mesh_normals @ n) > cfg.carcass_normal_cos))
    if sel.sum() < cfg.carcass_min_points:
        return None
    return float(np.percentile(d[sel], cfg.carcass_percentile))


def local_step(fa: Front, fb: Front, pa: np.ndarray, pb: np.ndarray, band: float) -> float:
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


def rail_extent(front, points: np.ndarray, normals: np.ndarray, band: float = 0.06, inside: float = 0.0) -> float:
    """The track's length along the front in units of its width (0: none; :func:`rail_run`)."""
    run = rail_run(front, points, normals, band, inside)
    return 0.0 if run is None else float((run[1] - run[0]) / max(front.size[0], 1e-6))


TRACK_PLANE = 0.002  # m: how far another machine's mesh could move a front's plane (near_track)
TRACK_EDGE = 0.005  # m: and each side of its rectangle


def rail_extents_moved(front: Front, points: np.ndarray, normals: np.ndarray, inside: float = 0.0,
                       plane: float = TRACK_PLANE, edge: float = TRACK_EDGE) -> list[float]:
    """:func:`rail_extent` of the front moved as another machine's mesh could move it: its
    plane ``plane`` out and in along its normal, its width and its height each ``2 edge``
    wider and narrower (every side ``edge`` out or in); six lengths, in units of each moved
    front's width. ``points`` [P, 3], ``normals`` [P, 3] as for :func:`rail_run`."""
    c, n = np.asarray(front.center, np.float64), np.asarray(front.normal, np.float64)
    w, h = front.size
    # the points any of the moved fronts can read: within the widest one's width of the centre
    # along u, and within half the tallest one's height and the 6 cm band beyond it along v
    # (rail_run reads no further)
    rel = np.asarray(points) - c
    keep = ((np.abs(rel @ np.asarray(front.u)) < w + 2 * edge + 1e-9)
            & (np.abs(rel @ front.v) < h / 2 + edge + 0.06 + 1e-9))
    pts, nrm = np.asarray(points)[keep], np.asarray(normals)[keep]
    moved = [replace(front, center=tuple(c + s * plane * n)) for s in (1.0, -1.0)]
    moved += [replace(front, size=(w + s * 2 * edge, h)) for s in (1.0, -1.0)]
    moved += [replace(front, size=(w, h + s * 2 * edge)) for s in (1.0, -1.0)]
    return [rail_extent(f, pts, nrm, inside=inside) for f in moved]


def rail_run(front, points: np.ndarray, normals: np.ndarray, band: float = 0.06, inside: float = 0.0
             ) -> tuple[float, float] | None:
    """How far a track runs along the front's top or bottom edge: the unbroken run (2 cm bins
    along u, through the front's middle, at least 90 % of its width) of the mesh ``points``
    [P, 3] (``normals`` [P, 3]) that face outward (cosine > 0.7 with the front's normal), lie
    from ``inside`` within that edge to ``band`` beyond it and 0.4 to 4 cm in front of the
    front's plane (proud of it: coplanar neighbours and the front's own face are not a track),
    divided by the front's width; the larger of the two edges. ``inside`` > 0 finds a track
    that a mask spilt onto puts inside the front's rectangle; a pull shorter than 90 % of the
    width is not one.
    An edge with an upward-facing surface reaching more than 10 cm behind the plane there across
    half the front's width or more (a counter top, a shelf seen from above) has no track; a
    downward-facing one (the underside of a wall cabinet's top, seen through the open half a
    single sliding door leaves) does not hide it. Returns the longer edge's run as (lo, hi) along u from
    the front's centre (m), or None when no edge has one (fewer than 20 points qualify, or the
    run is broken within the front's width)."""
    c, n, u = np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u)
    v = front.v
    rel = points - c
    pu, pv, pn = rel @ u, rel @ v, rel @ n
    hw, hh = front.size[0] / 2, front.size[1] / 2
    near_u = np.abs(pu) < 2.0 * hw
    facing = normals @ n > 0.7
    flat = normals[:, 2] > 0.7  # facing up: a counter top or a shelf seen from above
    proud = facing & (pn > 0.004) & (pn < 0.04)
    if inside > 0:  # a frame-and-panel door's rails come with stiles as proud: look beyond the edges only
        strips = [(s * pu - hw > -inside) & (s * pu - hw <= 0) & (np.abs(pv) < hh) & facing for s in (1.0, -1.0)]
        if all(m.sum() >= 20 and proud[m].mean() > 0.5 for m in strips):
            inside = 0.0
    best: tuple[float, float] | None = None
    for sgn in (1.0, -1.0):
        beyond = sgn * pv - hh
        deep = near_u & (beyond > 0.0) & (beyond < band) & flat & (pn < -0.1)  # read beyond the edge only
        in_band = near_u & (beyond > -inside) & (beyond < band)
        if deep.sum() >= 20 and np.ptp(pu[deep]) > hw:  # a counter top or a shelf across it, not a track
            continue
        sel = in_band & proud
        if sel.sum() < 20:
            continue
        # the unbroken run of 2 cm bins along u holding such points, through the front's middle:
        # a track spans the front, handles and neighbours' pulls leave gaps
        bins = np.floor((pu[sel] + 2.0 * hw) / 0.02).astype(np.int64)
        occ = np.zeros(int(np.ceil(4.0 * hw / 0.02)) + 1, bool)
        occ[np.clip(bins, 0, len(occ) - 1)] = True
        occ[1:-1] |= occ[:-2] & occ[2:]  # a single empty bin between two full ones is sampling, not a gap
        mid = int((2.0 * hw) / 0.02)
        if not occ[mid]:
            continue
        lo = mid - int(np.argmin(occ[mid::-1])) + 1 if not occ[: mid + 1].all() else 0
        hi = mid + int(np.argmin(occ[mid:])) if not occ[mid:].all() else len(occ)
        run = (lo * 0.02 - 2.0 * hw, hi * 0.02 - 2.0 * hw)
        if run[1] - run[0] >= 0.9 * 2 * hw and (best is None or run[1] - run[0] > best[1] - best[0]):
            best = run
    return best


def flush_sides(front: Front, points: np.ndarray, ring: tuple[float, float], tol: float, min_points: int
                ) -> dict[str, float | None]:
    """Per side of the front's rectangle (left, right, bottom, top), the fraction of the mesh
    ``points`` [P, 3] in the band ``ring`` = (from, to) m beyond that side (within the side's
    span) that lie within ``tol`` of the front's plane: 1 where the surface runs on flush (a
    wall, a coplanar neighbour), low where it steps (a counter, a plinth, a cabinet's underside,
    open space). None for a side with fewer than ``min_points`` points there."""
    rel = np.asarray(points, np.float64) - np.asarray(front.center)
    a, b, z = rel @ np.asarray(front.u), rel @ front.v, rel @ np.asarray(front.normal)
    w, h = front.size
    out: dict[str, float | None] = {}
    for side, along, span, half in (("left", -a, np.abs(b) <= h / 2, w / 2), ("right", a, np.abs(b) <= h / 2, w / 2),
                                    ("bottom", -b, np.abs(a) <= w / 2, h / 2), ("top", b, np.abs(a) <= w / 2, h / 2)):
        sel = span & (along >= half + ring[0]) & (along <= half + ring[1]) & (np.abs(z) < 0.25)
        out[side] = float((np.abs(z[sel]) <= tol).mean()) if sel.sum() >= min_points else None
    return out
