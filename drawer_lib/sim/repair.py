"""Repair of the small defects a reconstructed twin carries, so that the twin loads with its
contacts on and nothing in contact at q = 0: a part that sits a few millimetres into the static
scene (a drawer front 4 mm into a carcass box, a door into a skin of the wall) is freed by
carving the static scene, and two neighbouring fronts whose rectangles overlap by a few
millimetres are both trimmed back, not reported as a broken twin.

Part vs part (:func:`part_part_overlaps`, done first): two collision boxes of different parts
that intersect at q = 0 are separated along the in-plane axis (any box axis but the two boxes'
thickness axes, the thinnest ones) on which they overlap least: each loses half that overlap
plus half of ``clearance`` on the faces that meet. Through the thickness they are never
separated, since two fronts in one plane that are pushed apart in depth would still block each
other as either opens. An overlap deeper than ``max_depth`` (a part detected twice, one inside
the other) or a trim that would leave a box thinner than ``min_half`` x 2 is left as it is and
reported ("too deep" / "too thin"); the checks then name the pair.

Part vs static: each static collision box that a part penetrates at q = 0 by more than
``min_depth`` (and at most ``max_depth``: deeper is no small defect but a wrong rectangle or
axis, left to the checks to report) loses that much plus ``clearance`` on the face the part
presses on (the box axis most aligned with the contact normal). A box that would become thinner
than ``min_half`` x 2 is removed. Repeated until nothing penetrates beyond ``min_depth`` (or
``max_rounds``). A static mesh piece is never changed (it is reported by the checks).

Along the paths (:func:`path_grazes`, last): each part is opened on ``path_samples`` poses in
(0, hi], every other part closed; a box it runs into at all, by at most ``max_graze`` (a neighbour's
edge its corner brushes, a carcass side a drawer rubs) loses that depth plus ``clearance`` on
the face the part presses on, as above (a static box that would become too thin is removed, a
part's is left and reported "too thin"). Deeper is where the part really stops (the checks'
stop) and is reported "too deep". Without this, a 0.7 mm graze with wood's friction holds a
door against a robot's grip. Lengths m.
"""

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from drawer_lib.bodies import Shape, TwinModel
from drawer_lib.errors import ConfigError
from drawer_lib.geometry.boxes import OrientedBox, separated
from drawer_lib.sim.config import SimConfig
from drawer_lib.sim.mjcf import STATIC as STATIC_OWNER

_TOUCH = 1e-5  # m: along a path any contact is a graze (even one that touches wedges a door against its neighbour)


@dataclass(frozen=True)
class RepairConfig:
    """``twin.repair``: see the module doc."""

    enabled: bool = True
    min_depth: float = 0.0002
    max_depth: float = 0.02
    clearance: float = 0.001
    min_half: float = 0.001
    max_rounds: int = 4
    path_samples: int = 32
    max_graze: float = 0.005

    def __post_init__(self):
        if not 0 <= self.min_depth < self.max_depth or self.clearance < 0 or self.min_half <= 0 or self.max_rounds < 1:
            raise ConfigError("twin.repair: need 0 <= min_depth < max_depth, clearance >= 0, min_half > 0, "
                              "max_rounds >= 1")
        if self.path_samples < 0 or not 0 <= self.max_graze <= self.max_depth:
            raise ConfigError("twin.repair: need path_samples >= 0 and 0 <= max_graze <= max_depth")


class _ContactScan:
    """The twin ``model`` compiled so that every collision geom collides with every other
    (:func:`~drawer_lib.sim.checks.collide_all`), to read which boxes a part touches at a pose:
    ``owner`` per geom (0 static, 1.. the parts, then rigid objects; -1 visual), ``names`` of the
    owners, ``piece`` per geom (its index ``k`` in its body's collision list, from ``<owner>/col<k>``)."""

    def __init__(self, model: TwinModel, sim: SimConfig):
        from drawer_lib.sim.checks import collide_all, geom_owners
        from drawer_lib.sim.mjcf import build_spec, compile_spec

        m = compile_spec(build_spec(model, sim))
        self.owner, self.names = geom_owners(m, model)
        self.mc = collide_all(m, self.owner)
        self.d = mujoco.MjData(self.mc)
        self.n_parts = len(model.parts)
        self.piece = np.full(m.ngeom, -1)
        for g in np.flatnonzero(self.owner >= 0):
            name = mujoco.mj_id2name(self.mc, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or ""
            if "/col" in name:
                self.piece[g] = int(name.rsplit("/col", 1)[1])

    def contacts(self, me: int, qadr: int = -1, q: float = 0.0) -> dict[tuple[int, int], tuple[float, np.ndarray]]:
        """With every joint at rest but qpos address ``qadr`` at ``q``: for owner ``me`` (a
        part), {(its geom, the other geom): (deepest penetration m > 0, unit normal from the other
        geom into it)} over the static scene and the other parts."""
        d, mc, owner = self.d, self.mc, self.owner
        d.qpos[:] = mc.qpos0
        if qadr >= 0:
            d.qpos[qadr] = q
        mujoco.mj_fwdPosition(mc, d)
        out: dict[tuple[int, int], tuple[float, np.ndarray]] = {}
        for c in d.contact[: d.ncon]:
            g1, g2 = int(c.geom[0]), int(c.geom[1])
            o1, o2 = owner[g1], owner[g2]
            depth = -float(c.dist)
            if depth <= 0:
                continue
            n = np.asarray(c.frame[:3], np.float64)  # from geom1 to geom2
            if o1 == me and 0 <= o2 <= self.n_parts and o2 != me:
                mine, other, n = g1, g2, -n
            elif o2 == me and 0 <= o1 <= self.n_parts and o1 != me:
                mine, other = g2, g1
            else:
                continue
            key = (int(mine), int(other))
            if depth > out.get(key, (0.0, None))[0]:
                out[key] = (depth, n)
        return out


def static_part_penetrations(model: TwinModel, sim: SimConfig) -> list[tuple[int, str, float, np.ndarray]]:
    """At q = 0, every (static collision piece k, part id, depth m > 0, unit normal pointing from
    the static piece into the part) whose collision geoms overlap, deepest per pair, every pair
    of collision geoms tested (the contacts of the model as built do not matter)."""
    scan = _ContactScan(model, sim)
    best: dict[tuple[int, str], tuple[float, np.ndarray]] = {}
    for me in range(1, scan.n_parts + 1):
        for (_, other), (depth, n) in scan.contacts(me).items():
            if scan.owner[other] != 0 or scan.piece[other] < 0:
                continue
            key = (int(scan.piece[other]), scan.names[me])
            if depth > best.get(key, (0.0, None))[0]:
                best[key] = (depth, n)
    return [(k, pid, dep, n) for (k, pid), (dep, n) in sorted(best.items())]


def path_grazes(model: TwinModel, sim: SimConfig, samples: int, refine: int = 16
                ) -> list[tuple[str, int, str, int, float, np.ndarray]]:
    """Along each part's path, every other part closed: the collision boxes it runs into, as
    (moving part id, its box index, what it meets: ``static`` or a part id, that body's box
    index, the deepest penetration m over ``samples`` poses in (0, hi] and ``refine`` more
    within a step of each pose where a pair was deepest, the contact normal there pointing from
    what it meets into the moving part). Pairs already overlapping at q = 0 are
    left out (the q = 0 repair's or the checks'). Every pair of collision geoms is tested."""
    from drawer_lib.sim.mjcf import part_index

    if samples < 1 or not model.parts:
        return []
    scan = _ContactScan(model, sim)
    found: dict[tuple[int, int], tuple[float, np.ndarray]] = {}
    for p in model.parts:
        me = scan.names.index(p.id)
        qadr = part_index(scan.mc, p.id)["qpos"]
        at_rest = set(scan.contacts(me))
        qs = np.linspace(0.0, p.limits[1], samples + 1)
        mine: dict[tuple[int, int], tuple[float, np.ndarray, float]] = {}

        def visit(q: float) -> None:
            for key, (depth, n) in scan.contacts(me, qadr, q).items():
                if key not in at_rest and depth > mine.get(key, (0.0, None, 0.0))[0]:
                    mine[key] = (depth, n, q)

        for q in qs[1:]:
            visit(float(q))
        # the deepest pose lies within a step of the deepest sample: look again there, finer
        step = qs[1] - qs[0]
        for q_best in sorted({v[2] for v in mine.values()}):
            for q in np.linspace(max(0.0, q_best - step), min(p.limits[1], q_best + step), refine + 2)[1:-1]:
                visit(float(q))
        for key, (depth, n, _) in mine.items():
            if depth > found.get(key, (0.0, None))[0]:
                found[key] = (depth, n)
    o, pc, nm = scan.owner, scan.piece, scan.names
    return [(nm[o[g]], int(pc[g]), nm[o[h]], int(pc[h]), dep, n) for (g, h), (dep, n) in sorted(found.items())]


def _extent(box: OrientedBox, axis: np.ndarray) -> float:
    """Half the extent of ``box`` along the unit ``axis`` (m)."""
    return float(np.sum(box.half * np.abs(box.rotation.T @ axis)))


def _thin_axis(box: OrientedBox) -> np.ndarray:
    return box.rotation[:, int(np.argmin(box.half))]


def inplane_overlap(a: OrientedBox, b: OrientedBox) -> tuple[float, np.ndarray] | None:
    """The least overlap of boxes ``a`` and ``b`` (m) over the face axes of both that are more
    than 45 deg from either box's thickness axis, and that axis (unit, pointing from ``a`` to
    ``b``); None when such an axis separates them or when there is none (boxes turned across
    each other). Overlap along axis e: the two projected half extents minus the centres'
    distance along e (separating-axis test)."""
    thin = (_thin_axis(a), _thin_axis(b))
    d = b.center - a.center
    best: tuple[float, np.ndarray] | None = None
    for e in [*a.rotation.T, *b.rotation.T]:
        if max(abs(float(e @ t)) for t in thin) > np.sqrt(0.5):
            continue
        ov = _extent(a, e) + _extent(b, e) - abs(float(d @ e))
        if ov <= 0:
            return None
        if best is None or ov < best[0]:
            best = (ov, e * (1.0 if d @ e >= 0 else -1.0))
    return best


def part_part_overlaps(model: TwinModel) -> list[tuple[str, int, str, int, float, np.ndarray]]:
    """At q = 0, every pair of collision boxes of two different parts that intersect: (part a,
    its box index, part b, its box index, their :func:`inplane_overlap` (m), the axis from a to
    b); pairs without an in-plane axis are left out. Meshes are not tested here (the
    checks measure them)."""
    boxes = [(p.id, k, s.box) for p in model.parts for k, s in enumerate(p.collision) if s.kind == "box"]
    out = []
    for i, (pa, ka, a) in enumerate(boxes):
        for pb, kb, b in boxes[i + 1:]:
            if pa == pb or separated(a, b):
                continue
            ov = inplane_overlap(a, b)
            if ov is None:
                # no in-plane axis (boxes turned across each other): nothing to trim along; the
                # checks measure what is left
                continue
            out.append((pa, ka, pb, kb, ov[0], ov[1]))
    return out


def _repair_parts(model: TwinModel, cfg: RepairConfig) -> tuple[TwinModel, list[dict], dict[str, dict[int, Shape]]]:
    """Part-vs-part trims of :func:`repair_penetrations` (module doc)."""
    shapes = {p.id: list(p.collision) for p in model.parts}
    changed: dict[str, dict[int, Shape]] = {}
    log: list[dict] = []
    skip: set[tuple[str, int, str, int]] = set()
    for _ in range(cfg.max_rounds):
        current = replace(model, parts=[replace(p, collision=shapes[p.id]) for p in model.parts])
        hits = [h for h in part_part_overlaps(current) if h[4] > cfg.min_depth and h[:4] not in skip]
        if not hits:
            break
        for pa, ka, pb, kb, ov, axis in hits:
            rec = {"part": pa, "piece": ka, "other": pb, "other_piece": kb, "depth_m": round(ov, 5)}
            if ov > cfg.max_depth:
                rec["action"] = "too deep"
                skip.add((pa, ka, pb, kb))
            else:
                a = _carve(shapes[pa][ka].box, axis, (ov + cfg.clearance) / 2)
                b = _carve(shapes[pb][kb].box, -axis, (ov + cfg.clearance) / 2)
                if min(a.half.min(), b.half.min()) < cfg.min_half:
                    rec["action"] = "too thin"
                    skip.add((pa, ka, pb, kb))
                else:
                    shapes[pa][ka] = changed.setdefault(pa, {})[ka] = Shape("box", box=a)
                    shapes[pb][kb] = changed.setdefault(pb, {})[kb] = Shape("box", box=b)
                    rec["action"] = "carved"
            log.append(rec)
    return replace(model, parts=[replace(p, collision=shapes[p.id]) for p in model.parts]), log, changed


def _carve(box: OrientedBox, normal: np.ndarray, amount: float) -> OrientedBox:
    """``box`` with the face that ``normal`` (unit, out of the box toward what presses on it)
    points through moved back far enough to recede by ``amount`` along ``normal``: amount /
    cos(the angle between the normal and that face's axis), the cosine at least 0.5 (a corner
    pressing in obliquely needs its face moved back further than the penetration depth)."""
    a = box.rotation.T @ normal
    i = int(np.argmax(np.abs(a)))
    s = 1.0 if a[i] > 0 else -1.0
    amount = amount / max(abs(float(a[i])) / max(float(np.linalg.norm(a)), 1e-12), 0.5)
    half = box.half.copy()
    half[i] -= amount / 2
    return OrientedBox(box.center - s * box.rotation[:, i] * amount / 2, box.rotation, half)


def repair_penetrations(model: TwinModel, sim: SimConfig, cfg: RepairConfig
                        ) -> tuple[TwinModel, list[dict], list[tuple[int, Shape | None]], dict[str, dict[int, Shape]]]:
    """The twin with its parts' overlapping boxes trimmed apart, its static collision carved
    free of the parts at q = 0, and what each part grazes along its path carved back (module
    doc). Returns (the model; what was done, part vs part
    ``{"part", "piece", "other", "other_piece", "depth_m", "action": "carved" | "too deep" |
    "too thin"}`` then part vs static ``{"part", "static_piece", "depth_m", "action": "carved" |
    "removed" | "too deep" | "not a box"}`` (``static_piece``: the index in the input's
    ``static_collision``), then the grazes along the paths, the same records with
    ``"along_path": True``; per kept piece of the output's static collision (index in the input,
    its new shape when carved else None); per part the collision pieces trimmed, {index: new
    shape})."""
    static = list(model.static_collision)
    alive = [True] * len(static)
    if not cfg.enabled or not model.parts:
        return model, [], [(k, None) for k in range(len(static))], {}
    model, log, part_changed = _repair_parts(model, cfg)
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
    # along the paths: what a part grazes as it opens (a neighbour's edge, a carcass side), carved back
    shapes = {p.id: list(p.collision) for p in model.parts}
    skip_path: set[tuple] = set()
    for _ in range(cfg.max_rounds if cfg.path_samples else 0):
        idx = [k for k in range(len(static)) if alive[k]]
        current = replace(model, static_collision=[static[k] for k in idx],
                          parts=[replace(p, collision=shapes[p.id]) for p in model.parts])
        hits = [h for h in path_grazes(current, sim, cfg.path_samples) if h[4] > _TOUCH
                and (h[0], h[2], idx[h[3]] if h[2] == STATIC_OWNER else h[3]) not in skip_path]
        if not hits:
            break
        for pid, piece, other, k, dep, n in hits:
            if other == STATIC_OWNER:
                k = idx[k]
                rec = {"part": pid, "piece": piece, "static_piece": k, "depth_m": round(dep, 5), "along_path": True}
                shape = static[k] if alive[k] else None
            else:
                rec = {"part": pid, "piece": piece, "other": other, "other_piece": k, "depth_m": round(dep, 5),
                       "along_path": True}
                shape = shapes[other][k]
            if shape is None:
                continue
            if dep > cfg.max_graze or shape.kind != "box":
                rec["action"] = "too deep" if dep > cfg.max_graze else "not a box"
                skip_path.add((pid, other, k))
                log.append(rec)
                continue
            box = _carve(shape.box, n, dep + cfg.clearance)
            if box.half.min() < cfg.min_half:
                if other == STATIC_OWNER:
                    alive[k] = False
                    rec["action"] = "removed"
                else:
                    rec["action"] = "too thin"
                    skip_path.add((pid, other, k))
            elif other == STATIC_OWNER:
                static[k] = Shape("box", box=box)
                carved.add(k)
                rec["action"] = "carved"
            else:
                shapes[other][k] = part_changed.setdefault(other, {})[k] = Shape("box", box=box)
                rec["action"] = "carved"
            log.append(rec)
    model = replace(model, parts=[replace(p, collision=shapes[p.id]) for p in model.parts])
    kept = [k for k in range(len(static)) if alive[k]]
    out = replace(model, static_collision=[static[k] for k in kept])
    return out.validate(), log, [(k, static[k] if k in carved else None) for k in kept], part_changed
