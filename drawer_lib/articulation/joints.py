"""Joints: the type decision from the handle (DRAWER's rule on the 3DOI affordance peak,
reference §3.10(c), with the handle in place of the peak), the hinge axis, the drawer's travel
from the carcass depth, and sliding pairs. Lengths in metres, angles in radians in parts.

| evidence | type |
|---|---|
| handle near the left / right edge (a_u < f or > 1 - f; a horizontal one within f / 2) | door hinged on the far side |
| handle near the bottom edge | flap hinged at the top |
| handle near the top edge | drawer, or a flap hinged at the bottom when the labels say door |
| handle central | drawer |
| a neighbouring front of the same height on another track (a depth step) | sliding door (toward it) |
| no handle | not articulated (a fixed panel) |

Axes: revolute on the hinge edge, direction = (hinge -> free side) x outward normal, so a
positive angle opens outward; prismatic along the outward normal (drawer) or along u (sliding).
"""

from dataclasses import dataclass

import numpy as np

from drawer_lib.articulation.config import JointsConfig, TypesConfig
from drawer_lib.articulation.handles import Handle
from drawer_lib.io.parts import Axis, Front, Part


@dataclass
class Decision:
    family: str  # drawer | door | flap | sliding | fixed
    hinge: str | None = None  # left | right | top | bottom (revolute)
    reason: str = ""


def decide(h: Handle | None, labels: dict, cfg: TypesConfig) -> Decision:
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
            door_votes = sum(v for k, v in labels.items() if k in cfg.door_labels)
            drawer_votes = sum(v for k, v in labels.items() if k in cfg.drawer_labels)
            if door_votes > drawer_votes:
                return Decision("flap", "bottom", "handle near the top edge; labels say door")
        return Decision("drawer", reason="handle near the top edge")
    if side:  # a horizontal bar near a side, halfway up: still a side-hinged door
        return Decision("door", "right" if h.a_u < 0.5 else "left", "handle near a side edge")
    return Decision("drawer", reason="central handle")


def hinge_axis(front: Front, hinge: str) -> Axis:
    """The revolute axis on the ``hinge`` edge (left | right | bottom | top), oriented so that
    a positive angle opens the front outward."""
    c, n, u = np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u)
    v = front.v
    edge = {"left": -u * front.size[0] / 2, "right": u * front.size[0] / 2,
            "bottom": -v * front.size[1] / 2, "top": v * front.size[1] / 2}[hinge]
    to_free = -edge / np.linalg.norm(edge)
    d = np.cross(to_free, n)
    return Axis(tuple((c + edge).tolist()), tuple((d / np.linalg.norm(d)).tolist()))


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


def sliding_partners(fronts: list[Front], handles: list[Handle | None], cfg: JointsConfig,
                     points: list[np.ndarray]) -> dict[int, tuple[int, float]]:
    """Sliding doors: a front standing out of the run by a step of ``sliding_step`` (the outer
    panel on its own track; measured locally, :func:`local_step`) and the adjacent
    stepped-back front of the same height on the side away from its handle (the inner panel).
    ``points``: each front's segment points. Returns {front: (partner, overlap in u (m))} for
    both panels of each pair; the outer one is paired first and only once."""
    out: dict[int, tuple[int, float]] = {}
    cands = []
    for a, fa in enumerate(fronts):
        na, ua = np.asarray(fa.normal), np.asarray(fa.u)
        for b, fb in enumerate(fronts):
            if a == b or np.dot(na, fb.normal) < cfg.sliding_normal_cos:
                continue
            dc = np.asarray(fb.center) - np.asarray(fa.center)
            du = dc @ ua
            overlap_u = (fa.size[0] + fb.size[0]) / 2 - abs(du)
            if overlap_u <= -cfg.sliding_adjacent_gap:  # not adjacent
                continue
            step = local_step(fa, fb, points[a], points[b], cfg.sliding_band)  # > 0: b lies behind a
            if not cfg.sliding_step[0] <= step <= cfg.sliding_step[1]:
                continue
            same_h = (abs(fa.size[1] - fb.size[1]) < cfg.sliding_same_height * max(fa.size[1], fb.size[1])
                      and abs(dc @ fa.v) < cfg.sliding_aligned * fa.size[1])
            if same_h:
                h = handles[a]
                away = 0.0 if h is None else np.sign(0.5 - h.a_u)  # the side away from the handle
                cands.append((away != 0 and np.sign(du) != away, -overlap_u, a, b, overlap_u))
    for _, _, a, b, ov in sorted(cands):
        if a not in out and b not in out:
            out[a] = (b, max(ov, 0.0))
            out[b] = (a, max(ov, 0.0))
    return out


def slide_side(front: Front, mesh_points: np.ndarray, handle: Handle | None, cfg: JointsConfig,
               rail: tuple[float, float] | None = None) -> float:
    """The direction (+1: along u, -1: against it) a sliding door without a partner opens:
    along its ``rail`` (lo, hi along u from its centre, m) where the rail runs on past it by
    more than a fifth of its width; else toward the side where the mesh, probed over
    ``sliding_probe`` x its width beyond each side edge within its height, lies deeper behind
    its plane (an open shelf, a panel it slides over, not a wall it would run into); away from
    its handle when both sides are within 2 cm."""
    hw0 = front.size[0] / 2
    if rail is not None:
        past_lo, past_hi = -hw0 - rail[0], rail[1] - hw0
        if max(past_lo, past_hi) > 0.2 * front.size[0] and abs(past_hi - past_lo) > 0.1 * front.size[0]:
            return 1.0 if past_hi > past_lo else -1.0
    c, n, u = np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u)
    rel = mesh_points - c
    pu, pv, depth = rel @ u, rel @ front.v, -(rel @ n)
    hw, hh = front.size[0] / 2, front.size[1] / 2
    band = (np.abs(pv) < 0.8 * hh) & (depth > -0.01) & (depth < 1.5)
    out = []
    for sgn in (-1.0, 1.0):
        sel = band & (sgn * pu > hw + 0.01) & (sgn * pu < hw + cfg.sliding_probe * 2 * hw)
        out.append(float(np.median(depth[sel])) if sel.sum() >= 10 else 0.0)
    if abs(out[1] - out[0]) > 0.02:
        return 1.0 if out[1] > out[0] else -1.0
    if handle is not None and abs(handle.a_u - 0.5) > 0.05:
        return 1.0 if handle.a_u < 0.5 else -1.0
    return 1.0


def make_part(pid: str, dec: Decision, front: Front, cfg: JointsConfig, extra: dict,
              carcass: float | None = None, partner: tuple[Front, float] | None = None,
              slide_dir: float | None = None) -> Part:
    """The part of a front with decision ``dec`` (not ``fixed``): a revolute part on its hinge,
    a drawer along the outward normal travelling ``drawer_travel`` x ``carcass`` (the carcass
    depth, or ``default_depth``), a sliding door toward ``partner`` = (the other panel, their
    overlap in u), or without a partner along ``slide_dir`` x u (:func:`slide_side`) by
    ``sliding_single_travel`` x its width."""
    if dec.family in ("door", "flap"):
        lim = (0.0, float(np.deg2rad(cfg.revolute_limit_deg)))
        return Part(pid, "revolute", hinge_axis(front, dec.hinge), lim, front, extra=extra | {"hinge": dec.hinge})
    if dec.family == "drawer":
        travel = cfg.drawer_travel * (carcass if carcass is not None else cfg.default_depth)
        return Part(pid, "prismatic", Axis(front.center, front.normal), (0.0, float(travel)), front,
                    extra=extra | {"carcass_depth": carcass})
    if dec.family == "sliding" and partner is not None:  # toward the partner, by its width minus the overlap
        other, ov = partner
        du = (np.asarray(other.center) - np.asarray(front.center)) @ np.asarray(front.u)
        u = np.asarray(front.u) * (1.0 if du >= 0 else -1.0)
        travel = max(other.size[0] - ov - cfg.sliding_clearance, cfg.sliding_min_travel)
        return Part(pid, "prismatic", Axis(front.center, tuple(u.tolist())), (0.0, float(travel)), front, extra=extra)
    if dec.family == "sliding" and slide_dir is not None:
        u = np.asarray(front.u) * (1.0 if slide_dir >= 0 else -1.0)
        travel = max(cfg.sliding_single_travel * front.size[0], cfg.sliding_min_travel)
        return Part(pid, "prismatic", Axis(front.center, tuple(u.tolist())), (0.0, float(travel)), front,
                    extra=extra | {"partner": None})
    raise ValueError(f"make_part: no part for family {dec.family!r}" +
                     (" without a partner or a direction" if dec.family == "sliding" else ""))
