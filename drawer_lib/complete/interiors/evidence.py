"""What the scene says about the depth behind each front (:func:`measure_evidence`): the wall
behind (the farthest well-supported surface facing like the front within its u-range, as a
plane), caps (a counter top, a wall cabinet's underside, an end panel continuing the front's
edges backwards: their extent), the other fronts' planes (another track of the same cabinet,
or a front behind that blocks), the floor (appliance rule);
:func:`drawer_lib.articulation.probes.carcass_depth` on the points level with the front is the
fallback measurement. Distances from the front's outer face, metres."""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from jaxtyping import Float

from drawer_lib.articulation.config import JointsConfig
from drawer_lib.articulation.probes import carcass_depth
from drawer_lib.complete.interiors.config import EvidenceConfig, InteriorsConfig
from drawer_lib.complete.interiors.templates import check_part, template_kind
from drawer_lib.errors import NonFiniteError
from drawer_lib.geometry.boxes import front_frame
from drawer_lib.io.parts import Front, Part


@dataclass(frozen=True, kw_only=True)
class DepthEvidence:
    """What the mesh and the other fronts say about the depth behind one front (distances from
    its outer face, m). ``extent``: the measured carcass extent (None: no evidence), from
    ``source``; ``support``: points behind it; ``start``: where its interior starts; ``limit``:
    how far its interior may reach (the wall or a blocking front; None: unbounded)."""

    part_id: str
    template: str
    reason: str
    wall: float | None
    wall_points: int
    caps: dict
    carcass_depth: float | None
    tracks: list[str]
    blocking: float | None
    blocking_id: str | None
    start: float
    extent: float | None
    support: int
    source: str
    floor_z: float | None

    @property
    def limit(self) -> float | None:
        vals = [x for x in (self.wall, self.blocking) if x is not None]
        return min(vals) if vals else None

    def to_json(self) -> dict:
        return {"template": self.template, "reason": self.reason, "wall": self.wall, "wall_points": self.wall_points,
                "caps": {k: {"extent": e, "points": n} for k, (e, n) in self.caps.items()},
                "carcass_depth": self.carcass_depth, "tracks": self.tracks, "blocking": self.blocking,
                "blocking_id": self.blocking_id, "start": self.start, "extent": self.extent,
                "support": self.support, "source": self.source}


def floor_height(points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                 up_cos: float = 0.9) -> float | None:
    """Height of the floor: the 1st percentile of z of the up-facing points (None without any)."""
    up = normals[:, 2] >= up_cos
    if up.sum() < 10:
        return None
    return float(np.percentile(points[up, 2], 1.0))


@dataclass(frozen=True)
class LocalPoints:
    """Mesh points near one front in its frame: ``a``, ``b`` along (u, v), ``z`` behind its
    outer face; ``n`` [K, 3] their normals in (u, v, normal) coordinates; ``world`` [K, 3]."""

    a: np.ndarray
    b: np.ndarray
    z: np.ndarray
    n: np.ndarray
    world: np.ndarray
    world_n: np.ndarray


def local_points(front: Front, points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                 cfg: EvidenceConfig) -> LocalPoints:
    """The points within reach of every measurement on ``front`` (its extent grown by
    ``cap_band`` / ``v_band``, from 5 cm in front of it to ``max_behind``)."""
    c, R = np.asarray(front.center, np.float64), front_frame(front.normal, front.u)
    w, h = front.size
    loc = (points - c) @ R  # [N, 3]
    keep = ((np.abs(loc[:, 0]) <= w / 2 + cfg.cap_band) & (np.abs(loc[:, 1]) <= h / 2 + max(cfg.v_band, cfg.cap_band))
            & (loc[:, 2] < 0.05) & (loc[:, 2] > -cfg.max_behind))
    loc = loc[keep]
    return LocalPoints(loc[:, 0], loc[:, 1], -loc[:, 2], normals[keep] @ R, points[keep], normals[keep])


def wall_behind(front: Front, lp: LocalPoints, cfg: EvidenceConfig) -> tuple[float, int] | None:
    """(distance from the front's centre to the wall plane behind it, points on it), or None:
    the farthest histogram bin of the points facing like the front (within its u-range and
    ``v_band`` of its v-range) holding max(``min_points``, ``min_frac`` x the fullest bin)."""
    w, h = front.size
    a, b, z = lp.a, lp.b, lp.z
    sel = ((lp.n[:, 2] >= cfg.normal_cos) & (np.abs(a) <= cfg.u_frac * w / 2) & (np.abs(b) <= h / 2 + cfg.v_band)
           & (z > cfg.min_behind) & (z < cfg.max_behind))
    if sel.sum() < cfg.min_points:
        return None
    edges = np.arange(cfg.min_behind, cfg.max_behind + cfg.bin, cfg.bin)
    hist, _ = np.histogram(z[sel], edges)
    ok = np.nonzero(hist >= max(cfg.min_points, cfg.min_frac * hist.max()))[0]
    if len(ok) == 0:
        return None
    k = ok[-1]
    win = sel & (z >= edges[k] - cfg.bin) & (z <= edges[k + 1] + cfg.bin)
    cen = lp.world[win].mean(0)
    nw = lp.world_n[win].mean(0)
    nw /= np.linalg.norm(nw)
    return float((np.asarray(front.center) - cen) @ nw), int(win.sum())


_EDGES = {"top": (1, 1.0), "bottom": (1, -1.0), "right": (0, 1.0), "left": (0, -1.0)}


def cap_points(front: Front, lp: LocalPoints, cfg: EvidenceConfig, edge: str) -> np.ndarray:
    """[K] bool: the points of the surface continuing ``edge`` (top | bottom | left | right) of
    the front backwards: facing away from the edge, within ``cap_band`` beyond it."""
    ax, sgn = _EDGES[edge]
    coord, other = (lp.a, lp.b) if ax == 0 else (lp.b, lp.a)
    half, other_half = front.size[ax] / 2, front.size[1 - ax] / 2
    off = sgn * coord - half
    return ((sgn * lp.n[:, ax] >= cfg.normal_cos) & (off > -0.02) & (off < cfg.cap_band)
            & (np.abs(other) < cfg.u_frac * other_half) & (lp.z > -0.05) & (lp.z < cfg.max_behind))


def caps(front: Front, lp: LocalPoints, cfg: EvidenceConfig) -> dict[str, tuple[float, int]]:
    """{edge: (extent behind the outer face, points)} of the caps that start at the front."""
    out = {}
    for edge in _EDGES:
        sel = cap_points(front, lp, cfg, edge)
        if sel.sum() < cfg.cap_min_points:
            continue
        zs = lp.z[sel]
        ext = float(np.percentile(zs, cfg.cap_percentile))
        if np.percentile(zs, 5.0) < cfg.cap_reach and ext > cfg.cap_min_extent:
            out[edge] = (ext, int(sel.sum()))
    return out


def _projected_overlap(fi: Front, fj: Front) -> tuple[float, float, float]:
    """(overlap along u, overlap along v, fraction of front i covered) of front j's rectangle
    projected on front i's plane."""
    c, R = np.asarray(fi.center, np.float64), front_frame(fi.normal, fi.u)
    loc = (fj.corners() - c) @ R
    w, h = fi.size
    ou = min(w / 2, loc[:, 0].max()) - max(-w / 2, loc[:, 0].min())
    ov = min(h / 2, loc[:, 1].max()) - max(-h / 2, loc[:, 1].min())
    frac = max(ou, 0.0) * max(ov, 0.0) / (w * h)
    return float(ou), float(ov), float(frac)


def _swept_front(p: Part, in_plane_cos: float = 0.5) -> Front:
    """The rectangle a sliding panel covers over its range (its front extended along its axis
    when the axis lies in the front's plane); any other part's front as it is."""
    f = p.front
    d = np.asarray(p.axis.direction, np.float64) if p.axis is not None else None
    if p.kind != "prismatic" or d is None or abs(d @ np.asarray(f.normal)) >= in_plane_cos or p.limits is None:
        return f
    lo, hi = p.limits
    travel = hi - lo
    du, dv = abs(float(d @ np.asarray(f.u))), abs(float(d @ np.asarray(f.v)))
    c = np.asarray(f.center) + d * (lo + hi) / 2
    return Front(tuple(c.tolist()), f.normal, f.u, (f.size[0] + du * travel, f.size[1] + dv * travel))


def _neighbours(parts: Sequence[Part], cfg: EvidenceConfig, t_front: float, min_step: float = 0.008):
    """Per part: (start, track ids, blocking distance, blocking id) from the other fronts. A
    sliding panel counts as a track of the fronts its swept rectangle (:func:`_swept_front`)
    overlaps: the panels of a sliding pair abut at q = 0 and pass each other when opened."""
    out = []
    for i, pi in enumerate(parts):
        fi = pi.front
        ni, ci = np.asarray(fi.normal), np.asarray(fi.center)
        start, tracks, block, block_id = t_front, [], None, None
        for j, pj in enumerate(parts):
            fj = pj.front
            if i == j or ni @ np.asarray(fj.normal) < cfg.normal_cos:
                continue
            delta = float((ci - np.asarray(fj.center)) @ ni)  # > 0: j lies behind i
            if delta <= min_step:
                continue
            ou, ov, frac = _projected_overlap(fi, fj)
            su, sv, _ = _projected_overlap(fi, _swept_front(pj))
            if delta < cfg.track_gap and su > 0 and sv > 0:
                start = max(start, delta + t_front)
                tracks.append(pj.id)
            elif ou <= 0 or ov <= 0:
                continue
            elif frac >= cfg.blocking_overlap and (block is None or delta < block):
                block, block_id = delta, pj.id
        out.append((start, tracks, block, block_id))
    return out


def measure_evidence(parts: Sequence[Part], points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                     cfg: InteriorsConfig, floor_z: float | None = None) -> list[DepthEvidence]:
    """The evidence of every articulated part (in order). ``points`` / ``normals``: samples of
    the scene mesh (visible surface, world frame, unit normals); ``floor_z``: the floor height
    (default: :func:`floor_height`)."""
    parts = [p for p in parts if p.articulated]
    for p in parts:
        check_part(p)
    points = np.asarray(points, np.float64)
    normals = np.asarray(normals, np.float64)
    if not (np.all(np.isfinite(points)) and np.all(np.isfinite(normals))):
        raise NonFiniteError("measure_evidence: the mesh points or normals hold NaN or inf")
    if floor_z is None and len(points):
        floor_z = floor_height(points, normals)
    ec, tc = cfg.evidence, cfg.template
    nb = _neighbours(parts, ec, tc.front_thickness)
    jc = JointsConfig()
    out = []
    for p, (start, tracks, block, block_id) in zip(parts, nb):
        tmpl, reason = template_kind(p, floor_z, tc)
        f = p.front
        if len(points):
            lp = local_points(f, points, normals, ec)
            wb = wall_behind(f, lp, ec)
            cp = caps(f, lp, ec)
            level = np.abs(lp.b) <= f.size[1] / 2
            cd = carcass_depth(f, lp.world[level], lp.world_n[level], jc)
        else:
            wb, cp, cd = None, {}, None
        wall, wall_n = (wb if wb is not None else (None, 0))
        extent, support, source = None, 0, "none"
        if cp and wall is not None and max(e for e, _ in cp.values()) > wall + ec.cap_short:
            wall, wall_n = None, 0  # a cap reaches behind it: a surface in front of the carcass
        if cp:
            edge = max(cp, key=lambda k: cp[k][0])
            cap_ext, cap_n = cp[edge]
            if wall is None or cap_ext < wall - ec.cap_short:
                extent, support, source = cap_ext, cap_n, f"cap:{edge}"
        if extent is None and wall is not None:
            extent, support, source = wall, wall_n, "wall"
        if extent is None and cd is not None:
            extent, support, source = cd, jc.carcass_min_points, "carcass_depth"
        out.append(DepthEvidence(part_id=p.id, template=tmpl, reason=reason, wall=wall, wall_points=wall_n, caps=cp,
                                 carcass_depth=cd, tracks=tracks, blocking=block, blocking_id=block_id, start=float(start),
                                 extent=extent, support=int(support), source=source, floor_z=floor_z))
    return out
