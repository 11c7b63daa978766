"""Interior depth against the ground truth (evaluation only: reads ``gt/``).

GT interior depth of a part: rays along -normal from a ``grid`` x ``grid`` lattice over the
central ``span`` of its GT front (starting 1 cm in front of it) through the closed GT mesh; the
front's own geometry (its panel, handle, glass: with per-face instance ids the faces of its own
instance, else the first two hits) within ``max_front`` of the first hit is skipped; the depth
is the distance from where the ray leaves the front (its inner face) to the next hit (of any
other instance, or of its own beyond the front: a drawer's box), the median over the rays that
hit the front first. A GT front with nothing behind it within 3 cm (a solid
appliance body, e.g. a microwave modelled as a block) is flagged ``gt_solid`` and left out of
the summary. Predictions are matched to GT parts as the articulation metrics do (front IoU).

Per matched part: ``fitted`` and ``rule`` free depths (from the predicted front's inner face to
the inner face of the template's back wall: the ``free_depth`` of the interiors the
``complete`` stage fits, :mod:`drawer_lib.complete.interiors`), their absolute errors against
the GT depth.
"""

import numpy as np
import trimesh

from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.io.parts import Front, PartsFile
from drawer_lib.metrics.articulation import match_parts

SOLID_MAX = 0.03  # m: less free depth than this behind a GT front means a solid body


def _hits(rc: Raycaster, o: np.ndarray, d: np.ndarray, max_hits: int, stop_after: float) -> np.ndarray:
    """[R, max_hits] distances of the successive hits along each ray (inf after the last); a ray
    stops once a hit lies more than ``stop_after`` beyond its first one."""
    R = len(o)
    ts = np.full((R, max_hits), np.inf)
    t_acc = np.zeros(R)
    alive = np.ones(R, bool)
    for k in range(max_hits):
        if not alive.any():
            break
        idx = np.nonzero(alive)[0]
        eps = 2e-5 if k else 0.0
        t, _, _ = rc.cast(o[idx] + (t_acc[idx] + eps)[:, None] * d[idx], d[idx])
        hit = np.isfinite(t)
        ts[idx[hit], k] = t_acc[idx[hit]] + eps + t[hit]
        t_acc[idx[hit]] = ts[idx[hit], k]
        alive[idx[~hit]] = False
        alive[idx[hit & (ts[idx, k] - ts[idx, 0] > stop_after)]] = False
    return ts


class GtInteriorProbe:
    """Measures GT interior depths on one GT mesh (module doc). With ``face_instances`` [F] the
    front's own faces (its instance) and the rest are cast separately, so a body whose face
    coincides with the front's inner face (a solid appliance behind its door) counts."""

    def __init__(self, gt_mesh: trimesh.Trimesh, face_instances: np.ndarray | None = None):
        self.V, self.F = np.asarray(gt_mesh.vertices), np.asarray(gt_mesh.faces)
        self.inst = None if face_instances is None else np.asarray(face_instances)
        if self.inst is not None and len(self.inst) != len(self.F):
            raise ValueError(f"GtInteriorProbe: {len(self.inst)} face instances for {len(self.F)} faces")
        self.all = Raycaster(self.V, self.F)

    def _split(self, instance_id: int) -> tuple[Raycaster | None, Raycaster | None]:
        own = self.inst == instance_id
        mk = lambda m: Raycaster(self.V, self.F[m]) if m.any() else None  # noqa: E731
        return mk(own), mk(~own)

    def depth(self, front: Front, instance_id: int | None = None, grid: int = 5, span: float = 0.6,
              max_front: float = 0.06, max_hits: int = 12) -> dict:
        """{"depth": median free depth behind the front (m; inf when nothing is hit),
        "front_thickness", "rays": the rays that hit the front first}."""
        c, n, u, v = (np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u), front.v)
        g = (np.arange(grid) + 0.5) / grid - 0.5
        A, B = np.meshgrid(g * span * front.size[0], g * span * front.size[1])
        o = c + 0.01 * n + A.reshape(-1, 1) * u + B.reshape(-1, 1) * v  # [R, 3], 1 cm in front
        d = np.broadcast_to(-n, o.shape).copy()
        first = _hits(self.all, o, d, 1, np.inf)[:, 0]
        split = self.inst is not None and instance_id is not None
        if split:
            own_rc, other_rc = self._split(instance_id)
            own = _hits(own_rc, o, d, max_hits, max_front + 1.0) if own_rc else np.full((len(o), 1), np.inf)
            other = _hits(other_rc, o, d, 1, np.inf)[:, 0] if other_rc else np.full(len(o), np.inf)
        else:
            allh = _hits(self.all, o, d, max_hits, max_front)
        depths, thick = [], []
        for r in range(len(o)):
            t0 = first[r]
            if not np.isfinite(t0) or abs(t0 - 0.01) > 0.03:
                continue  # the ray misses this front (a hole, a neighbour in front)
            if split:
                t = own[r]
                within = np.isfinite(t) & (t - t0 <= max_front)
                if not within.any() or other[r] < t[within].min() - 1e-4:
                    continue  # something else lies in front of this front
                t_exit = t[within].max()
                nxt = min(other[r], t[~within & np.isfinite(t)].min(initial=np.inf))
            else:
                t = allh[r]
                k_exit = 1 if np.isfinite(t[1]) and t[1] - t0 <= max_front else 0
                t_exit, nxt = t[k_exit], t[k_exit + 1]
            depths.append(float(max(nxt - t_exit, 0.0)))
            thick.append(float(t_exit - t0))
        if not depths:
            return {"depth": None, "front_thickness": None, "rays": 0}
        return {"depth": float(np.median(depths)), "front_thickness": float(np.median(thick)), "rays": len(depths)}


def interior_depth_error(parts_pred: PartsFile, gt_mesh: trimesh.Trimesh, gt_parts: PartsFile,
                         fitted: dict[str, tuple[str, float]], rule: dict[str, float],
                         gt_face_instances: np.ndarray | None = None, grid: int = 5) -> dict[str, dict]:
    """{predicted part id: {"gt", "template", "gt_depth", "gt_front_thickness", "gt_solid",
    "fitted", "rule", "fitted_error", "rule_error"}} for every predicted articulated part matched
    to a GT one that has a fitted interior; ``fitted``: {part id: (template, free depth m)},
    ``rule``: {part id: free depth m} (DRAWER's rule)."""
    probe = GtInteriorProbe(gt_mesh, gt_face_instances)
    m = match_parts(parts_pred, gt_parts)
    out = {}
    for i, j, iou in m.pairs:
        p, g = m.pred[i], m.gt[j]
        if p.id not in fitted:
            continue
        gd = probe.depth(g.front, g.instance_id, grid)
        template, free = fitted[p.id]
        row = {"gt": g.id, "iou": float(iou), "template": template, "gt_depth": gd["depth"],
               "gt_front_thickness": gd["front_thickness"], "rays": gd["rays"],
               "fitted": float(free), "rule": float(rule[p.id]) if p.id in rule else None}
        ok = gd["depth"] is not None and np.isfinite(gd["depth"])
        row["gt_solid"] = bool(ok and gd["depth"] < SOLID_MAX)
        row["fitted_error"] = abs(row["fitted"] - gd["depth"]) if ok else None
        row["rule_error"] = abs(row["rule"] - gd["depth"]) if ok and row["rule"] is not None else None
        out[p.id] = row
    return out


def summarise_depth_errors(rows: dict[str, dict]) -> dict:
    """{"n", "fitted_mean", "fitted_max", "rule_mean", "rule_max", "excluded"} over the rows with
    a GT depth that is not a solid body."""
    ok = [r for r in rows.values() if r["fitted_error"] is not None and not r["gt_solid"]]
    out = {"n": len(ok), "excluded": sorted(k for k, r in rows.items() if r not in ok)}
    for key in ("fitted", "rule"):
        e = np.array([r[f"{key}_error"] for r in ok if r[f"{key}_error"] is not None])
        out[f"{key}_mean"] = float(e.mean()) if len(e) else None
        out[f"{key}_max"] = float(e.max()) if len(e) else None
    return out
