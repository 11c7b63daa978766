"""Physical checks of a built twin: does every part open, stop at its limits and stay
clear of the scene, do rigid objects rest, does nothing blow up, and how fast does it simulate.

Each part's drive and pull tests start from a fresh ``MjData`` (all joints at q = 0, every other
control 0, so the other servos hold their parts like dampers). Non-finite states are caught both
as NaN in ``qpos`` / ``qvel`` and through MuJoCo's warning counters (``data.warning``: MuJoCo
resets a diverging simulation instead of returning NaN). All failures are collected and raised
together, each naming its part: :class:`TwinCheckError` (with ``failures`` and the measured
``report``), or :class:`NonFiniteError` when a simulation diverged.

Penetration is measured on a copy of the model in which every collision geom collides with every
other (the exported model may exclude part-vs-static contacts, see
:mod:`drawer_lib.sim.mjcf`), from ``data.contact`` distances (MuJoCo's signed distance of the
convex solids; negative = penetration depth).
"""

import copy
import math
import time
from pathlib import Path

import mujoco
import numpy as np

from drawer_lib.errors import InputError, NonFiniteError, TwinCheckError
from drawer_lib.sim.mjcf import GROUP_COLLISION, STATIC, drives_on, part_index, set_drives
from drawer_lib.bodies import PartBody, TwinModel
from drawer_lib.sim.config import SimConfig

_UNIT = {"revolute": "rad", "prismatic": "m"}
_NONFINITE_WARNINGS = {mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                       mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADCTRL}


class _Failures:
    def __init__(self):
        self.items: list[dict] = []
        self.nonfinite = False

    def add(self, oid: str, check: str, message: str, nonfinite: bool = False) -> None:
        self.items.append({"id": oid, "check": check, "message": message})
        self.nonfinite |= nonfinite


def health(m: mujoco.MjModel, d: mujoco.MjData) -> tuple[str | None, bool]:
    """(problem or None, whether it is non-finite) after a simulation: NaN / inf in the state or
    a MuJoCo warning counter above 0."""
    problems, nonfinite = [], False
    if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
        problems.append("NaN or inf in qpos / qvel")
        nonfinite = True
    counts = np.asarray(d.warning.number)
    for i in np.flatnonzero(counts > 0):
        w = mujoco.mjtWarning(int(i))
        problems.append(f"MuJoCo warning {w.name} x{int(counts[i])}")
        nonfinite |= w in _NONFINITE_WARNINGS
    return ("; ".join(problems) if problems else None), nonfinite


def _run(m: mujoco.MjModel, d: mujoco.MjData, n: int, qadr: int) -> np.ndarray:
    """Step ``n`` times; the joint value at qpos address ``qadr`` after each step [n]."""
    q = np.empty(n)
    for i in range(n):
        mujoco.mj_step(m, d)
        q[i] = d.qpos[qadr]
    return q


def pull(m: mujoco.MjModel, ix: dict, force: float, seconds: float) -> tuple[np.ndarray, mujoco.MjData]:
    """A person's pull: the constant generalised ``force`` (N along a slide, N·m about a hinge)
    on part ``ix`` (:func:`~drawer_lib.sim.mjcf.part_index`) of ``m`` exactly as it is (drives
    as the model has them), from rest for ``seconds``. Returns (joint value after each step [n],
    the final data)."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    d.qfrc_applied[ix["dof"]] = force
    return _run(m, d, math.ceil(seconds / m.opt.timestep), ix["qpos"]), d


def _first_time(q: np.ndarray, level: float, dt: float) -> float | None:
    hit = np.flatnonzero(q >= level)
    return float((hit[0] + 1) * dt) if len(hit) else None


def geom_owners(m: mujoco.MjModel, twin: TwinModel) -> tuple[np.ndarray, list[str]]:
    """Per geom the index of its owner in ``names`` = ["static", *part ids, *rigid ids]
    (-1 for geoms that do not collide: visual ones)."""
    names = [STATIC, *(p.id for p in twin.parts), *(r.id for r in twin.rigid)]
    body_owner = np.full(m.nbody, -1)
    for k, name in enumerate(names):
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        if b >= 0:
            body_owner[b] = k
    owner = body_owner[m.geom_bodyid]
    owner[m.geom_group != GROUP_COLLISION] = -1
    return owner, names


def collide_all(m: mujoco.MjModel, owner: np.ndarray) -> mujoco.MjModel:
    """A copy of ``m`` where every collision geom collides with every other, without margins."""
    mc = copy.deepcopy(m)
    col = owner >= 0
    mc.geom_contype[:] = np.where(col, 1, 0)
    mc.geom_conaffinity[:] = np.where(col, 1, 0)
    mc.geom_margin[:] = 0.0
    mc.geom_gap[:] = 0.0
    # the broad phase filters body pairs by the OR of their geoms' bits, precomputed at compile
    body_bits = np.zeros(m.nbody, np.int32)
    np.bitwise_or.at(body_bits, m.geom_bodyid[col], 1)
    mc.body_contype[:] = body_bits
    mc.body_conaffinity[:] = body_bits
    return mc


def _penetrations(mc: mujoco.MjModel, d: mujoco.MjData, owner: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """After ``mj_fwdPosition``: (owner a [C], owner b [C], depth [C] m > 0) of the penetrating
    contacts between different owners."""
    mujoco.mj_fwdPosition(mc, d)
    n = d.ncon
    if n == 0:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
    geom = np.asarray(d.contact.geom[:n])
    depth = -np.asarray(d.contact.dist[:n])
    a, b = owner[geom[:, 0]], owner[geom[:, 1]]
    keep = (depth > 0) & (a >= 0) & (b >= 0) & (a != b)
    return a[keep], b[keep], depth[keep]


def _resolve(m: mujoco.MjModel, twin: TwinModel, fails: _Failures) -> dict[str, dict]:
    """MuJoCo ids of every part and rigid object, checking the model matches the twin (names,
    joint types, world axes, ranges)."""
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    out = {}
    for p in twin.parts:
        ix = part_index(m, p.id)
        if min(ix["body"], ix["joint"], ix["actuator"]) < 0:
            fails.add(p.id, "model", f"part {p.id!r}: the model lacks its body, joint or actuator")
            continue
        jtype = mujoco.mjtJoint.mjJNT_HINGE if p.kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE
        axis = d.xaxis[ix["joint"]]
        rng = m.jnt_range[ix["joint"]]
        if (m.jnt_type[ix["joint"]] != jtype or np.abs(axis - p.unit_axis).max() > 1e-6
                or np.abs(rng - np.array(p.limits)).max() > 1e-9 or m.actuator_trnid[ix["actuator"], 0] != ix["joint"]):
            fails.add(p.id, "model", f"part {p.id!r}: the model's joint (type {int(m.jnt_type[ix['joint']])}, axis "
                      f"{np.round(axis, 6).tolist()}, range {rng.tolist()}) differs from the twin's "
                      f"({p.kind}, {np.round(p.unit_axis, 6).tolist()}, {list(p.limits)}) or its actuator "
                      "does not drive it")
            continue
        out[p.id] = ix
    for r in twin.rigid:
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, r.id)
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, r.id)
        if b < 0 or j < 0 or m.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE:
            fails.add(r.id, "model", f"rigid object {r.id!r}: the model lacks its body or free joint")
            continue
        out[r.id] = {"body": b, "joint": j}
    return out


def _colliders(names: list[str], n_parts: int, cfg: SimConfig) -> np.ndarray:
    """Per owner in ``names`` (static, parts, rigid objects) whether a part collides with it in
    the exported model (``cfg.contact``; rigid objects are pushed, not stops)."""
    out = np.zeros(len(names), bool)
    out[0] = cfg.contact.part_static
    out[1:1 + n_parts] = cfg.contact.part_part
    return out


def part_stop(mc: mujoco.MjModel, qadr: int, hi: float, me: int, owner: np.ndarray, colliders: np.ndarray,
              depth: float, samples: int, iters: int = 20) -> tuple[float, int | None]:
    """How far a part opens before it runs into what it collides with, every other joint at 0:
    (stop q in [0, hi], the owner index it runs into or None when it reaches ``hi``). ``mc``:
    the collide-all model (:func:`collide_all`); ``qadr``: the part's qpos address; ``me``: its
    owner index; ``colliders``: per owner whether it stops the part (:func:`_colliders`); a
    pose is blocked when the part penetrates one of them by more than ``depth`` (m) beyond what
    it already did at q = 0 (an overlap at q = 0 is the penetration check's). Poses
    ``samples`` evenly in (0, hi], then ``iters`` bisections between the last free and the first
    blocked one (the stop is the last free pose: within hi / samples / 2^iters of the contact)."""
    d = mujoco.MjData(mc)

    def depths(q: float) -> np.ndarray:  # per owner, how deep the part is in it at q (m)
        d.qpos[:] = mc.qpos0
        d.qpos[qadr] = q
        a, b, dep = _penetrations(mc, d, owner)
        other = np.where(a == me, b, np.where(b == me, a, -1))
        out = np.zeros(len(colliders))
        np.maximum.at(out, other[other >= 0], dep[other >= 0])
        return np.where(colliders, out, 0.0)

    base = depths(0.0)  # an overlap already there at q = 0 is the penetration check's, not a stop

    def hit(q: float) -> int | None:
        extra = depths(q) - base
        k = int(np.argmax(extra))
        return k if extra[k] > depth else None

    free = 0.0
    for q in np.linspace(0.0, hi, samples + 1)[1:]:
        by = hit(float(q))
        if by is None:
            free = float(q)
            continue
        blocked = float(q)
        for _ in range(iters):
            mid = 0.5 * (free + blocked)
            if hit(mid) is None:
                free = mid
            else:
                blocked = mid
        return free, by
    return hi, None


def _check_part(m: mujoco.MjModel, m_pull: mujoco.MjModel, mc: mujoco.MjModel, p: PartBody, ix: dict,
                owner: np.ndarray, names: list[str], cfg: SimConfig, fails: _Failures, colliders: np.ndarray) -> dict:
    c, jc, dt = cfg.checks, cfg.joint(p.kind), m.opt.timestep
    lo, hi = p.limits
    unit = _UNIT[p.kind]
    revolute = p.kind == "revolute"
    rec: dict = {"kind": p.kind, "lo": lo, "hi": hi, "mass_kg": float(m.body_mass[ix["body"]]),
                 "kv": float(-m.actuator_biasprm[ix["actuator"], 2])}

    # where it stops: its upper limit, or what it runs into first with every other part closed
    me = names.index(p.id)
    stop, by = part_stop(mc, ix["qpos"], hi, me, owner, colliders, c.stop_depth, c.stop_samples)
    reach = min(hi, stop) if by is not None else hi
    rec.update(stop_q=reach, stopped_by=names[by] if by is not None else None,
               travel_fraction=reach / hi if hi > 0 else 1.0)
    if by is not None and reach < c.min_travel * hi:
        fails.add(p.id, "blocked", f"part {p.id!r}: with every other part closed it runs into "
                  f"{'the static scene' if names[by] == STATIC else repr(names[by])} at q = {reach:.3g} {unit}, "
                  f"{reach / hi:.0%} of its range {hi:.3g} {unit} (needs {c.min_travel:.0%})")

    # drive: velocity target = drive speed (within the actuator's control range)
    speed = jc.speed
    if m.actuator_ctrllimited[ix["actuator"]]:
        speed = min(speed, float(m.actuator_ctrlrange[ix["actuator"], 1]))
    t_open = max(c.open_time, 1.2 * hi / speed)
    n = math.ceil(t_open / dt)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    d.ctrl[ix["actuator"]] = speed
    q = _run(m, d, n, ix["qpos"])
    problem, nonfinite = health(m, d)
    tol = c.drive_overshoot_rad if revolute else c.drive_overshoot_m
    rec.update(drive_time_s=t_open, drive_time_to_open_s=_first_time(q, c.open_fraction * reach, dt),
               drive_max_q=float(np.nanmax(q)) if np.isfinite(q).any() else math.nan,
               drive_final_q=float(q[-1]))
    rec["drive_overshoot"] = max(0.0, rec["drive_max_q"] - hi) if math.isfinite(rec["drive_max_q"]) else math.nan
    if problem:
        fails.add(p.id, "drive", f"part {p.id!r}: drive test: the simulation is not healthy ({problem})", nonfinite)
    elif rec["drive_time_to_open_s"] is None:
        fails.add(p.id, "drive", f"part {p.id!r}: driven at {speed:.3g} {unit}/s it reached only "
                  f"{max(q.max(), 0) / max(reach, 1e-12):.0%} of {'its upper limit' if by is None else 'its stop'} "
                  f"{reach:.3g} {unit} in {t_open:.3g} s (needs {c.open_fraction:.0%}): it is held back")
    elif rec["drive_overshoot"] > tol:
        fails.add(p.id, "drive", f"part {p.id!r}: driven open it passed its upper limit {hi:.3g} {unit} by "
                  f"{rec['drive_overshoot']:.3g} {unit} (max {tol:.3g})")

    # a person's pull: force along a drawer's axis / torque about a hinge, on the model as loaded
    force = c.pull_torque if revolute else c.pull_force
    q, d = pull(m_pull, ix, force, c.open_time)
    problem, nonfinite = health(m_pull, d)
    tol = c.pull_overshoot_rad if revolute else c.pull_overshoot_m
    level = lo + c.pull_fraction * (reach - lo)
    rec.update(pull_force=force, pull_time_to_open_s=_first_time(q, level, dt),
               pull_max_q=float(np.nanmax(q)) if np.isfinite(q).any() else math.nan, pull_final_q=float(q[-1]))
    rec["pull_overshoot"] = max(0.0, rec["pull_max_q"] - hi) if math.isfinite(rec["pull_max_q"]) else math.nan
    if problem:
        fails.add(p.id, "pull", f"part {p.id!r}: pull test: the simulation is not healthy ({problem})", nonfinite)
    elif rec["pull_time_to_open_s"] is None:
        fails.add(p.id, "pull", f"part {p.id!r}: pulled with {force:.3g} {'N·m' if revolute else 'N'} it opened "
                  f"only to q = {q.max():.3g} {unit} in {c.open_time:.3g} s (needs {c.pull_fraction:.0%} of "
                  f"[{lo:.3g}, {reach:.3g}])")
    elif rec["pull_overshoot"] > tol or q[-1] > hi + tol:
        fails.add(p.id, "pull", f"part {p.id!r}: pulled open it passed its upper limit {hi:.3g} {unit} by "
                  f"{rec['pull_overshoot']:.3g} {unit} (max {tol:.3g}): the limit does not hold it")

    # along its path (0, hi]: penetration into the static scene
    d = mujoco.MjData(mc)
    worst, worst_q = 0.0, 0.0
    for qs in np.linspace(0.0, hi, c.path_samples + 1)[1:]:
        d.qpos[:] = mc.qpos0
        d.qpos[ix["qpos"]] = qs
        a, b, depth = _penetrations(mc, d, owner)
        hit = ((a == me) & (b == 0)) | ((b == me) & (a == 0))
        if hit.any() and depth[hit].max() > worst:
            worst, worst_q = float(depth[hit].max()), float(qs)
    rec.update(path_penetration_m=worst, path_penetration_q=worst_q)
    if worst > c.path_penetration:
        fails.add(p.id, "path", f"part {p.id!r}: opening it, it penetrates the static scene by {worst * 1000:.1f} mm "
                  f"at q = {worst_q:.3g} {unit} (max {c.path_penetration * 1000:.1f} mm): its axis or limit "
                  "runs into the scene")
    return rec


def check_twin(model: mujoco.MjModel | str | Path, twin: TwinModel, cfg: SimConfig | None = None) -> dict:
    """Check the physics of the compiled twin ``model`` (an ``MjModel`` or the path of its
    ``scene.xml``) against its description ``twin``; return what was measured.

    Checks (tolerances in ``cfg.checks``): the model matches the twin (names, types, axes,
    ranges); each part's stop is its upper limit, or, with contacts on, where it first runs
    into another (closed) part or the static scene (:func:`part_stop`), and a part stopped
    before half its range is blocked; every drive (turned on for the test) opens its part to
    95 % of its stop within 3 s (or 1.2 x range / drive speed when a long travel needs more) and passes the limit
    by <= 1° / 1 mm; a person's pull (20 N / 10 N·m as an applied generalised force, on the
    model as it loads: a twin whose drives act as it loads brakes its parts and fails here)
    opens it to 90 % of its stop within 3 s and the limit holds (<= 2° / 5 mm); at q = 0 no
    part penetrates the static scene by > 2 mm (nor another part, when parts collide:
    ``contact.part_part``; else that overlap is only reported), nor the static scene along its
    path; rigid objects move < 1 cm in 2 s at rest and parts open by < 5 mm (a drawer whose
    axis tilts down must not roll open); no NaN and no MuJoCo warning anywhere.
    Simulation speed (steps/s, real-time factor) of the whole scene at rest is measured.

    Returns: a dict of flat aggregates (``n_parts``, ``n_rigid``, ``drive_time_to_open_s_max``,
    ``pull_time_to_open_s_max``, ``penetration_max_m`` (static scene), ``penetration_parts_max_m``,
    ``path_penetration_max_m``, ``n_parts_stopped`` (stopped before their upper limit),
    ``travel_fraction_min``, ``rigid_drift_max_m``, ``sim_steps_per_s``, ``sim_realtime_factor``, ``check_wall_s``) plus
    ``parts: {id: {...}}`` and ``rigid: {id: {...}}`` with the per-body numbers (SI units).
    Raises: ``TwinCheckError`` / ``NonFiniteError`` naming every failing part.
    """
    cfg = cfg or SimConfig()
    c = cfg.checks
    t_start = time.perf_counter()
    if isinstance(model, (str, Path)):
        try:
            m = mujoco.MjModel.from_xml_path(str(model))
        except ValueError as e:
            raise InputError(f"{model}: MuJoCo cannot load it ({e})") from e
    else:
        m = model
    twin.validate()
    fails = _Failures()
    report: dict = {"n_parts": len(twin.parts), "n_rigid": len(twin.rigid), "parts": {}, "rigid": {}}
    ids = _resolve(m, twin, fails)
    owner, names = geom_owners(m, twin)
    mc = collide_all(m, owner)
    # the pull test meets the file as it loads; the drive test turns the drives on
    m_pull = m
    m_drive = set_drives(copy.deepcopy(m), True)
    report["drives_on_load"] = drives_on(m)

    # at q = 0: part vs static scene and vs other parts
    d = mujoco.MjData(mc)
    a, b, depth = _penetrations(mc, d, owner)
    n_static_parts = 1 + len(twin.parts)
    colliders = _colliders(names, len(twin.parts), cfg)
    for p in twin.parts:
        if p.id not in ids:
            continue
        me = names.index(p.id)
        rec = _check_part(m_drive, m_pull, mc, p, ids[p.id], owner, names, cfg, fails, colliders)
        for key, others in (("penetration", (0, 1)), ("penetration_parts", (1, n_static_parts))):
            inr = lambda o: (o >= others[0]) & (o < others[1])  # noqa: E731
            hit = ((a == me) & inr(b)) | ((b == me) & inr(a))
            k = int(np.argmax(np.where(hit, depth, -1.0))) if hit.any() else -1
            pen = float(depth[k]) if k >= 0 else 0.0
            other = names[b[k] if a[k] == me else a[k]] if k >= 0 else None
            rec.update({f"{key}_m": pen, f"{key}_with": other})
            # parts overlapping parts matter only when they collide (contact.part_part); else reported
            if pen > c.penetration and (key == "penetration" or cfg.contact.part_part):
                fails.add(p.id, key, f"part {p.id!r}: at q = 0 it penetrates "
                          f"{'the static scene' if other == STATIC else repr(other)} by {pen * 1000:.1f} mm "
                          f"(max {c.penetration * 1000:.1f} mm)")
        report["parts"][p.id] = rec

    # the whole scene at rest: rigid objects stay, nothing diverges; simulation speed
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rig = [r for r in twin.rigid if r.id in ids]
    bodies = np.array([ids[r.id]["body"] for r in rig], int)
    x0 = d.xpos[bodies].copy()
    n = math.ceil(c.rest_time / m.opt.timestep)
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nstep=n)
    wall = time.perf_counter() - t0
    drift = np.linalg.norm(d.xpos[bodies] - x0, axis=1) if len(rig) else np.zeros(0)
    problem, nonfinite = health(m, d)
    if problem:
        fails.add("scene", "rest", f"the scene at rest: the simulation is not healthy ({problem})", nonfinite)
    for p in twin.parts:  # a passive part stays shut (a reconstructed axis that tilts down must not let it roll open)
        if p.id not in ids or p.id not in report["parts"]:
            continue
        ix = ids[p.id]
        q = float(d.qpos[ix["qpos"]])
        moved = abs(q) * (0.5 if p.kind == "revolute" else 1.0)
        rec = report["parts"][p.id]
        rec["rest_drift_m"] = moved
        if not moved < c.rest_part_drift:
            tilt = math.degrees(math.asin(min(1.0, abs(float(p.unit_axis[2])))))
            why = (f"its axis tilts {tilt:.1f}° from level and its friction "
                   f"{float(m.dof_frictionloss[ix['dof']]):.3g} N does not hold it" if p.kind == "prismatic"
                   else "its weight or a neighbour moves it")
            fails.add(p.id, "rest", f"part {p.id!r}: as the file loads it moved to q = {q:.3g} {_UNIT[p.kind]} in "
                      f"{c.rest_time:.3g} s at rest (max {c.rest_part_drift * 1000:.1f} mm): {why}")
    for r, dr, b in zip(rig, drift, bodies):
        report["rigid"][r.id] = {"drift_m": float(dr), "mass_kg": float(m.body_mass[b])}
        if not dr < c.rest_drift:
            fails.add(r.id, "rest", f"rigid object {r.id!r}: at rest it moved {dr * 100:.2f} cm in {c.rest_time:.3g} s "
                      f"(max {c.rest_drift * 100:.2f} cm): it does not rest on its support")

    parts = report["parts"].values()

    def _max(key: str) -> float | None:
        vals = [v[key] for v in parts if v.get(key) is not None]
        return float(max(vals)) if vals else None

    report.update(
        drive_time_to_open_s_max=_max("drive_time_to_open_s"), pull_time_to_open_s_max=_max("pull_time_to_open_s"),
        penetration_max_m=_max("penetration_m"), penetration_parts_max_m=_max("penetration_parts_m"),
        path_penetration_max_m=_max("path_penetration_m"),
        n_parts_stopped=sum(v.get("stopped_by") is not None for v in parts),
        travel_fraction_min=min((v["travel_fraction"] for v in parts), default=None),
        rigid_drift_max_m=float(drift.max()) if len(drift) else None,
        sim_steps_per_s=n / wall if wall > 0 else None,
        sim_realtime_factor=n * m.opt.timestep / wall if wall > 0 else None,
        check_wall_s=time.perf_counter() - t_start)
    if fails.items:
        msg = f"{len(fails.items)} twin check(s) failed:\n" + "\n".join(f["message"] for f in fails.items)
        if fails.nonfinite:
            raise NonFiniteError(msg)
        raise TwinCheckError(msg, fails.items, report)
    return report
