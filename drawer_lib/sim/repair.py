"""Repair of the small defects a reconstructed twin carries: a part that sits a few millimetres
into the static scene at q = 0 (a drawer front 4 mm into a carcass box, a door into a skin of
the wall) is freed by carving the static scene, not reported as a broken twin.

Each static collision box that a part penetrates at q = 0 by more than ``min_depth`` (and at
most ``max_depth``: deeper is no small defect but a wrong rectangle or axis, left to the checks
to report) loses that much plus ``clearance`` on the face the part presses on (the box axis
most aligned with the contact normal). A box that would become thinner than ``min_half`` x 2
is removed. Repeated until nothing penetrates beyond ``min_depth`` (or ``max_rounds``). A static
mesh piece is never changed (it is reported by the checks). Lengths m.
"""

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from drawer_lib.bodies import Shape, TwinModel
from drawer_lib.errors import ConfigError
from drawer_lib.geometry.boxes import OrientedBox
from drawer_lib.sim.config import SimConfig


@dataclass(frozen=True)
class RepairConfig:
    """``twin.repair``: see the module doc."""

    enabled: bool = True
    min_depth: float = 0.001
    max_depth: float = 0.02
    clearance: float = 0.001
    min_half: float = 0.001
    max_rounds: int = 4

    def __post_init__(self):
        if not 0 <= self.min_depth < self.max_depth or self.clearance < 0 or self.min_half <= 0 or self.max_rounds < 1:
            raise ConfigError("twin.repair: need 0 <= min_depth < max_depth, clearance >= 0, min_half > 0, "
                              "max_rounds >= 1")


def static_part_penetrations(model: TwinModel, sim: SimConfig) -> list[tuple[int, str, float, np.ndarray]]:
    """At q = 0, every (static collision piece k, part id, depth m > 0, unit normal pointing from
    the static piece into the part) whose collision geoms overlap, deepest per pair, every pair
    of collision geoms tested (the contacts of the model as built do not matter)."""
    from drawer_lib.sim.checks import collide_all, geom_owners
    from drawer_lib.sim.mjcf import build_spec, compile_spec

    m = compile_spec(build_spec(model, sim))
    owner, names = geom_owners(m, model)  # collision geoms only: 0 static, 1.. the parts
    mc = collide_all(m, owner)
    d = mujoco.MjData(mc)
    mujoco.mj_fwdPosition(mc, d)
    n_parts = len(model.parts)
    best: dict[tuple[int, str], tuple[float, np.ndarray]] = {}
    for c in d.contact[: d.ncon]:
        g1, g2 = int(c.geom[0]), int(c.geom[1])
        o1, o2 = owner[g1], owner[g2]
        depth = -float(c.dist)
        if depth <= 0:
            continue
        n = np.asarray(c.frame[:3], np.float64)  # from geom1 to geom2
        if o1 == 0 and 1 <= o2 <= n_parts:
            gs, pid = g1, names[o2]
        elif o2 == 0 and 1 <= o1 <= n_parts:
            gs, pid, n = g2, names[o1], -n
        else:
            continue
        name = mujoco.mj_id2name(mc, mujoco.mjtObj.mjOBJ_GEOM, gs) or ""
        if not name.startswith("static/col"):
            continue
        k = int(name.removeprefix("static/col"))
        if depth > best.get((k, pid), (0.0, None))[0]:
            best[(k, pid)] = (depth, n)
    return [(k, pid, dep, n) for (k, pid), (dep, n) in sorted(best.items())]


def _carve(box: OrientedBox, normal: np.ndarray, amount: float) -> OrientedBox:
    """``box`` with the face that ``normal`` (unit, out of the box toward what presses on it)
    points through moved back by ``amount``."""
    a = box.rotation.T @ normal
    i = int(np.argmax(np.abs(a)))
    s = 1.0 if a[i] > 0 else -1.0
    half = box.half.copy()
    half[i] -= amount / 2
    return OrientedBox(box.center - s * box.rotation[:, i] * amount / 2, box.rotation, half)


def repair_penetrations(model: TwinModel, sim: SimConfig, cfg: RepairConfig
                        ) -> tuple[TwinModel, list[dict], list[tuple[int, Shape | None]]]:
    """The twin with its static collision carved free of the parts at q = 0 (module doc); what
    was done, ``[{"part", "static_piece", "depth_m", "action": "carved" | "removed" | "too deep"
    | "not a box"}]`` (``static_piece``: the index in the input's ``static_collision``); and
    per kept piece of the output's static collision (index in the input, its new shape when
    carved else None)."""
    static = list(model.static_collision)
    alive = [True] * len(static)
    log: list[dict] = []
    if not cfg.enabled or not model.parts:
        return model, log, [(k, None) for k in range(len(static))]
    carved: set[int] = set()
    skip: set[tuple[int, str]] = set()
    for _ in range(cfg.max_rounds):
        idx = [k for k in range(len(static)) if alive[k]]
        current = replace(model, static_collision=[static[k] for k in idx])
        hits = [(idx[j], pid, dep, n) for j, pid, dep, n in static_part_penetrations(current, sim)
                if dep > cfg.min_depth and (idx[j], pid) not in skip]
        if not hits:
            break
        for k, pid, dep, n in hits:
            rec = {"part": pid, "static_piece": k, "depth_m": round(dep, 5)}
            if dep > cfg.max_depth:
                rec["action"] = "too deep"
                skip.add((k, pid))
            elif static[k].kind != "box":
                rec["action"] = "not a box"
                skip.add((k, pid))
            elif not alive[k]:
                continue
            else:
                box = _carve(static[k].box, n, dep + cfg.clearance)
                if box.half.min() < cfg.min_half:
                    alive[k] = False
                    rec["action"] = "removed"
                else:
                    static[k] = Shape("box", box=box)
                    carved.add(k)
                    rec["action"] = "carved"
            log.append(rec)
    kept = [k for k in range(len(static)) if alive[k]]
    out = replace(model, static_collision=[static[k] for k in kept])
    return out.validate(), log, [(k, static[k] if k in carved else None) for k in kept]
