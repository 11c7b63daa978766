"""Joints of typed fronts: the hinge axis of a door or flap, a drawer's travel from the carcass
depth, sliding pairs and the direction a sliding door without a partner opens. Lengths in
metres, angles in radians in parts.

Axes: revolute on the hinge edge, direction = (hinge -> free side) x outward normal, so a
positive angle opens outward; prismatic along the outward normal (drawer) or along u (sliding).
"""

import numpy as np

from drawer_lib.articulation.config import JointsConfig
from drawer_lib.articulation.probes import local_step
from drawer_lib.articulation.vocab import Decision, Handle
from drawer_lib.io.parts import Axis, Front, Part


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


def _pull_toward(handle: Handle | None, toward_u: float, off_centre: float) -> bool:
    """Whether ``handle`` sits more than ``off_centre`` (a fraction of the front's width) from
    the front's centre on the side of ``toward_u`` (a signed offset along the front's u)."""
    if handle is None or toward_u == 0.0:
        return False
    return bool((handle.a_u - 0.5) * np.sign(toward_u) > off_centre)


def sliding_partners(fronts: list[Front], handles: list[Handle | None], cfg: JointsConfig,
                     points: list[np.ndarray]) -> dict[int, tuple[int, float]]:
    """Sliding doors: a front standing out of the run by a step of ``sliding_step`` (the outer
    panel on its own track; measured locally, :func:`local_step`) and the adjacent
    stepped-back front of the same height on the side away from its handle (the inner panel).
    Two fronts either of whose pulls sits more than ``sliding_pull_meets`` of its width off
    centre toward the other are not a pair: a double door's leaves are pulled where they meet,
    a sliding pair's panels at their outer edges (a pull there would stop the outer panel
    against the inner one's).
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
                if cfg.sliding_pull_meets is not None and (
                        _pull_toward(handles[a], float(du), cfg.sliding_pull_meets)
                        or _pull_toward(handles[b], float(-(dc @ np.asarray(fb.u))), cfg.sliding_pull_meets)):
                    continue  # a double door's leaves: pulled where they meet, not at their outer edges
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
