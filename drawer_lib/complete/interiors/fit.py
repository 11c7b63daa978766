"""The joint fit of the template depths (:func:`fit_depths`) and the whole interior step
(:func:`build_interiors`): measure the evidence, partition the footprints, fit, build.

Fit: minimise sum_i w_i (d_i - m_i)^2 + rho x (inside the carcass, in front of a blocking
front, drawer box >= its travel, pairwise overlap volume of the occupied boxes (a drawer's box
swept over its travel) / the smaller front area)^2 over d in [min, max] with L-BFGS-B (overlap
gradients by central differences), the penalty raised in rounds. Parts without evidence get
the median fitted carcass depth of the fronts in their plane (their run), else of the kitchen,
else ``fit.default_depth`` behind the front.
"""

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from jaxtyping import Float
from scipy.optimize import minimize

from drawer_lib.complete.interiors.config import EvidenceConfig, InteriorsConfig
from drawer_lib.complete.interiors.evidence import DepthEvidence, measure_evidence
from drawer_lib.complete.interiors.templates import (MIN_HALF, Footprint, Interior, build_template, full_footprint,
                                                     occupied_box, travel)
from drawer_lib.errors import NonFiniteError
from drawer_lib.geometry.boxes import OrientedBox, front_frame, overlap_volume
from drawer_lib.io.parts import Part


def partition_footprints(parts: Sequence[Part], cfg: EvidenceConfig) -> list[Footprint]:
    """Each front's footprint, cut at the middle of any overlap with a near-parallel front less
    than ``track_gap`` in front of or behind it (neighbours in one cabinet, the two panels of a
    sliding pair), across the axis of the smaller overlap, so such neighbours never share
    interior space (depth cannot resolve a side-by-side overlap)."""
    fps = []
    for i, pi in enumerate(parts):
        a0, a1, b0, b1 = full_footprint(pi.front)
        c, R = np.asarray(pi.front.center, np.float64), front_frame(pi.front.normal, pi.front.u)
        for j, pj in enumerate(parts):
            if i == j or np.asarray(pi.front.normal) @ np.asarray(pj.front.normal) < cfg.normal_cos:
                continue
            if abs(float((c - np.asarray(pj.front.center)) @ R[:, 2])) >= cfg.track_gap:
                continue
            loc = (pj.front.corners() - c) @ R
            ja0, ja1, jb0, jb1 = loc[:, 0].min(), loc[:, 0].max(), loc[:, 1].min(), loc[:, 1].max()
            ou = min(a1, ja1) - max(a0, ja0)
            ov = min(b1, jb1) - max(b0, jb0)
            if ou <= 0 or ov <= 0:
                continue
            if ou <= ov:
                mid = (max(a0, ja0) + min(a1, ja1)) / 2
                if (ja0 + ja1) / 2 > (a0 + a1) / 2:
                    a1 = min(a1, mid)
                else:
                    a0 = max(a0, mid)
            else:
                mid = (max(b0, jb0) + min(b1, jb1)) / 2
                if (jb0 + jb1) / 2 > (b0 + b1) / 2:
                    b1 = min(b1, mid)
                else:
                    b0 = max(b0, mid)
        fps.append((float(a0), float(a1), float(b0), float(b1)))
    return fps


@dataclass
class FitResult:
    depths: np.ndarray  # [P] fitted template depths
    records: list[dict]
    default_extent: float  # the kitchen's median fitted carcass extent (m behind the outer face), else the config's
    default_source: str  # "kitchen_median" | "config"
    objective: float
    iterations: int
    success: bool


def fit_depths(parts: Sequence[Part], evidence: Sequence[DepthEvidence], cfg: InteriorsConfig,
               footprints: Sequence[Footprint] | None = None) -> FitResult:
    """Fit all template depths jointly (module doc). ``parts`` and ``evidence`` align (the
    articulated parts, in order)."""
    parts = [p for p in parts if p.articulated]
    if len(parts) != len(evidence):
        raise ValueError(f"fit_depths: {len(parts)} articulated parts but {len(evidence)} evidence records")
    fc, tc = cfg.fit, cfg.template
    P = len(parts)
    fps = list(footprints) if footprints is not None else partition_footprints(parts, cfg.evidence)
    start = np.array([e.start for e in evidence])
    clear = np.array([tc.drawer_back_clearance if e.template == "drawer" else 0.0 for e in evidence])
    has = np.array([e.extent is not None for e in evidence], bool)
    ext = np.array([e.extent if e.extent is not None else np.nan for e in evidence])
    w = np.where(has, np.array([e.support / (e.support + cfg.evidence.support) for e in evidence]), fc.default_weight)
    ub = np.array([(e.limit - s) if e.limit is not None else np.inf for e, s in zip(evidence, start)])
    lb = np.minimum(np.array([travel(p) if e.template == "drawer" else 0.0 for p, e in zip(parts, evidence)]),
                    fc.max_depth)
    area = np.array([(fp[1] - fp[0]) * (fp[3] - fp[2]) for fp in fps])

    def box(i: int, d: float) -> OrientedBox:
        b = occupied_box(parts[i], evidence[i].template, start[i], d, fps[i], tc)
        return replace(b, half=np.maximum(b.half - fc.overlap_tol, MIN_HALF))

    def overlap(i: int, j: int, di: float, dj: float) -> float:
        return overlap_volume(box(i, di), box(j, dj))

    # the pairs whose boxes meet at some depths in range (at the deepest, if at all)
    pairs = [(i, j, max(min(area[i], area[j]), 1e-6)) for i in range(P) for j in range(i + 1, P)
             if overlap(i, j, fc.max_depth, fc.max_depth) > 1e-12]

    def run(target: np.ndarray, weight: np.ndarray):
        """L-BFGS-B on the penalised objective, the penalty raised 10x per round from
        ``penalty`` / 1000 (continuation: the stiff final problem starts near its solution)."""
        h = fc.fd_step

        def f(x, rho):
            r = x - target
            val = float(np.sum(weight * r * r))
            g = 2 * weight * r
            a = np.maximum(x - ub, 0.0)
            b = np.maximum(lb - x, 0.0)
            val += rho * float(np.sum(a * a) + np.sum(b * b))
            g += 2 * rho * (a - b)
            for i, j, ar in pairs:
                o = overlap(i, j, x[i], x[j]) / ar
                if o <= 0:
                    continue
                val += rho * o * o
                gi = (overlap(i, j, x[i] + h, x[j]) - overlap(i, j, x[i] - h, x[j])) / (2 * h * ar)
                gj = (overlap(i, j, x[i], x[j] + h) - overlap(i, j, x[i], x[j] - h)) / (2 * h * ar)
                g[i] += 2 * rho * o * gi
                g[j] += 2 * rho * o * gj
            return val, g

        x = np.clip(np.minimum(target, np.where(np.isfinite(ub), ub, np.inf)), fc.min_depth, fc.max_depth)
        x = np.clip(np.maximum(x, lb), fc.min_depth, fc.max_depth)
        nit = 0
        for rho in fc.penalty * np.array([1e-3, 1e-2, 1e-1, 1.0]):
            res = minimize(f, x, args=(rho,), jac=True, method="L-BFGS-B",
                           bounds=[(fc.min_depth, fc.max_depth)] * P, options={"maxiter": fc.max_iter})
            x, nit = res.x, nit + res.nit
        if not np.all(np.isfinite(x)):
            raise NonFiniteError("fit_depths: the optimiser returned non-finite depths")
        res.nit = nit
        return res

    # pass 1: the parts with evidence (the others pulled weakly to the config default); pass 2
    # with each part without evidence pulled to the median of its run, else of the kitchen
    default_ext, default_src = tc.front_thickness + fc.default_depth, "config"
    target = np.where(has, ext - start - clear, default_ext - start - clear)
    part_src = np.where(has, "", "config").astype(object)
    if P == 0:
        return FitResult(np.zeros(0), [], default_ext, default_src, 0.0, 0, True)
    res = run(target, w)
    if has.any():
        fitted_ext = res.x + start + clear  # carcass extents behind the outer faces
        default_ext, default_src = float(np.median(fitted_ext[has])), "kitchen_median"
    if has.any() and (~has).any():
        for i in np.nonzero(~has)[0]:  # coplanar fronts (one run) share their carcass depth
            ni, ci = np.asarray(parts[i].front.normal), np.asarray(parts[i].front.center)
            co = [j for j in np.nonzero(has)[0]
                  if ni @ np.asarray(parts[j].front.normal) >= cfg.evidence.normal_cos
                  and abs((np.asarray(parts[j].front.center) - ci) @ ni) <= fc.coplanar_tol]
            e_i, part_src[i] = ((float(np.median(fitted_ext[co])), "coplanar_median") if co
                                else (default_ext, "kitchen_median"))
            target[i] = e_i - start[i] - clear[i]
        res = run(target, w)

    d = np.asarray(res.x, np.float64)
    tol = fc.active_tol
    t0 = np.clip(target, fc.min_depth, fc.max_depth)
    records = []
    for i, (p, e) in enumerate(zip(parts, evidence)):
        active = []
        if target[i] > ub[i] + tol:
            active.append("blocking_front" if (e.blocking is not None and e.limit == e.blocking) else "inside_carcass")
        if target[i] < lb[i] - tol:
            active.append("drawer_travel")
        if target[i] < fc.min_depth - tol:
            active.append("min_depth")
        if target[i] > fc.max_depth + tol:
            active.append("max_depth")
        records.append({"part": p.id, "template": e.template, "evidence": e.source,
                        "measured_depth": float(target[i]) if has[i] else None,
                        "default_depth": None if has[i] else float(target[i]),
                        "default_source": part_src[i] or None,
                        "fitted_depth": float(d[i]), "start": float(start[i]), "weight": float(w[i]),
                        "active": active, "overlap_with": []})
    for i, j, ar in pairs:
        before = overlap(i, j, t0[i], t0[j]) / ar
        after = overlap(i, j, d[i], d[j]) / ar
        if before > tol:
            records[i]["active"].append(f"overlap:{parts[j].id}")
            records[j]["active"].append(f"overlap:{parts[i].id}")
        if after > 0:
            records[i]["overlap_with"].append({"part": parts[j].id, "m": float(after)})
            records[j]["overlap_with"].append({"part": parts[i].id, "m": float(after)})
    return FitResult(d, records, default_ext, default_src, float(res.fun), int(res.nit), bool(res.success))


@dataclass
class InteriorsResult:
    interiors: list[Interior]
    evidence: list[DepthEvidence]
    fit: FitResult

    def to_json(self) -> dict:
        return {"interiors": [x.to_json() for x in self.interiors],
                "default_extent": self.fit.default_extent, "default_source": self.fit.default_source,
                "objective": self.fit.objective, "iterations": self.fit.iterations, "success": self.fit.success}


def build_interiors(parts: Sequence[Part], points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                    cfg: InteriorsConfig, floor_z: float | None = None) -> InteriorsResult:
    """Measure, fit and build the interior of every articulated part (rigid parts are
    skipped). ``points`` / ``normals``: the scene mesh's visible surface, sampled."""
    arts = [p for p in parts if p.articulated]
    ev = measure_evidence(arts, points, normals, cfg, floor_z)
    fps = partition_footprints(arts, cfg.evidence)
    fit = fit_depths(arts, ev, cfg, fps)
    out = []
    for p, e, fp, d, rec in zip(arts, ev, fps, fit.depths, fit.records):
        it = build_template(p, e.template, e.start, float(d), cfg.template, fp)
        rec = rec | {"free_depth": it.free_depth, "shelves": it.shelves, "reason": e.reason,
                     "evidence_detail": e.to_json()}
        out.append(replace(it, record=rec))
    return InteriorsResult(out, ev, fit)
