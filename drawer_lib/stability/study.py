"""The stability study (the ``stability`` stage): integrators x timesteps x cases, each
cell's error against a reference, its wall time per simulated second and every divergence
signal MuJoCo gives; the choice of the twin's integrator and timestep; remedies for the
extreme cases that choice does not handle.

A :class:`Case` is a compiled MuJoCo model plus what to observe. Its cells run the same model
with ``opt.integrator`` / ``opt.timestep`` changed (and, for a remedy, armature or damping
added to every degree of freedom), from the same initial state, for ``duration`` simulated
seconds, recording ``observe`` after every step. The error of a cell is the largest
``|obs - reference| * scale`` over the run, in the case's ``unit``: the reference is the
closed form where one exists (``exact``), else the same case under RK4 at ``ref_timestep``
(1e-5 s) interpolated to the cell's times. A cell diverges when its state goes non-finite, a
MuJoCo warning counter rises (MuJoCo resets a diverging state rather than leave NaN), a passive
case's energy (``mjENBL_ENERGY``) grows above its start, the speed exceeds ``vmax``, or a
case's own check fails (``fail``: an object fell through its drawer).

Cases (:func:`extreme_cases`; the twin's own parts come from :func:`twin_case`):

* ``stiff_joint``: k = 1e4 N·m/rad on a 1e-3 kg·m^2 link (w = 3162 rad/s), closed form.
* ``heavy_damping``: b = 1e3 N·m·s/rad on the same link, k = 10, closed form (overdamped).
* ``tiny_armature``: a 1e-5 kg·m^2 link (a knob or a thin flap) with the twin's hinge damping
  1 N·m·s/rad and armature 1e-6, k = 1, closed form.
* ``mass_ratio``: a 30 kg door hung on a 30 g hinge body (1000:1), two horizontal hinges in
  gravity with damping; RK4 reference.
* ``stiff_servo``: a position servo kp = 1e4 N·m/rad, kv = 20 (critical) on a 1e-2 kg·m^2 link,
  closed form (the servo is the spring-damper).
* ``contact_rich``: five 4 cm blocks in a drawer driven open at 0.5 m/s with the twin's drive;
  observed: the blocks' positions; RK4 reference; failing if a block leaves the drawer
  downwards.
* ``zero_range``: a drawer whose range is zero wide. MuJoCo refuses ``range="0 0"`` (the case
  records that) so it runs the narrowest range it accepts, [0, 1e-9] m, driven at 0.5 m/s into
  its limit; exact: q = 0 (the error is how far the limit lets it through).
* ``robot_grasp``: the robot stage's contact-rich grasp: the Panda's fingers squeezing a 14 mm
  bar handle (40 N per finger) on a 3 kg drawer while the arm's joint servos pull it 5 cm
  (a step of their targets); observed: the drawer's joint and the TCP's position; RK4
  reference.
* ``axis_near_x``: the ``tiny`` hinge about the axis (1e-9, 0, 1) and ``axis_non_unit`` about
  (0, 0, 2.5): MuJoCo normalises axes, so both are the unit-axis closed form.
"""

import copy
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from drawer_lib.errors import ConfigError, InputError
from drawer_lib.sim.mjcf import INTEGRATOR_ENUM
from drawer_lib.stability.hinge import INTEGRATORS, Hinge

REF_TIMESTEP = 1e-5
# Among integrators that all pass at a timestep: implicitfast first (MuJoCo's recommended
# integrator: within ~20 % of Euler's cost, and it integrates every velocity-dependent force,
# damping and actuator kv alike, implicitly, so a servo of any gain stays stable), then
# implicit (adds the Coriolis derivatives), Euler (damping only), RK4 (four evaluations a step).
PREFERENCE = ("implicitfast", "implicit", "euler", "rk4")


@dataclass
class Case:
    """One row group of the matrix (module doc). ``model`` is compiled once; cells copy it.
    ``observe(m, d)`` -> [K] values after a step; ``scale`` [K] turns their differences into
    ``unit``; ``exact(t [N]) -> [N, K]`` the closed form (None: RK4 reference); ``passive``:
    energy may only fall; ``vmax``: a speed (``unit``/s of qvel, any dof) no stable run reaches;
    ``fail(m, d)`` -> a reason or None; ``columns`` names the K observables (per-part rows of
    the twin case); ``note``: what the case records beyond its cells."""

    name: str
    group: str  # "nominal" | "extreme"
    model: mujoco.MjModel | None
    duration: float
    observe: Callable[[mujoco.MjModel, mujoco.MjData], np.ndarray]
    unit: str
    scale: np.ndarray
    columns: list[str]
    exact: Callable[[np.ndarray], np.ndarray] | None = None
    setup: Callable[[mujoco.MjModel, mujoco.MjData], None] | None = None
    passive: bool = False
    vmax: float = 1e3
    fail: Callable[[mujoco.MjModel, mujoco.MjData], str | None] | None = None
    note: str | None = None
    rejected: str | None = None  # MuJoCo refused the model: every cell records this

    @property
    def reference(self) -> str:
        return "closed form" if self.exact is not None else f"rk4 at {REF_TIMESTEP:g} s"


@dataclass
class Trace:
    """A run of a case: ``t`` [N] s, ``obs`` [N, K], ``reason`` it diverged (None: it did not),
    ``wall`` s spent stepping, ``sim`` s simulated."""

    t: np.ndarray
    obs: np.ndarray
    reason: str | None
    wall: float
    sim: float


def _variant(case: Case, integrator: str, timestep: float, armature: float = 0.0, damping: float = 0.0
             ) -> mujoco.MjModel:
    if integrator not in INTEGRATORS:
        raise ConfigError(f"stability: integrator {integrator!r} must be one of {INTEGRATORS}")
    if not (math.isfinite(timestep) and timestep > 0):
        raise ConfigError(f"stability: timestep {timestep} must be > 0")
    m = copy.copy(case.model)
    m.opt.integrator = INTEGRATOR_ENUM[integrator]
    m.opt.timestep = timestep
    m.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    m.dof_armature[:] += armature
    m.dof_damping[:] += damping
    return m


def simulate_case(case: Case, integrator: str, timestep: float, armature: float = 0.0, damping: float = 0.0,
                  energy_tol: float = 0.5) -> Trace:
    """Run ``case`` once (module doc); stops at the first divergence signal."""
    m = _variant(case, integrator, timestep, armature, damping)
    d = mujoco.MjData(m)
    if armature:  # MuJoCo caches the mass matrix's constant part (dof_M0) at compile time
        mujoco.mj_setConst(m, d)
    if case.setup is not None:
        case.setup(m, d)
    mujoco.mj_forward(m, d)
    e0 = float(d.energy.sum())
    n = int(round(case.duration / timestep))
    K = len(case.columns)
    obs = np.empty((n, K))
    reason = None
    i = 0
    t0 = time.perf_counter()
    for i in range(n):  # one step at a time: the state is checked after every step
        mujoco.mj_step(m, d)
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            reason = "non-finite state"
            break
        obs[i] = case.observe(m, d)
        if case.passive:
            e = float(d.energy.sum())
            if e > e0 + energy_tol * abs(e0) + 1e-9:
                reason = f"energy grew from {e0:.3g} to {e:.3g} J"
                break
        vmax = float(np.abs(d.qvel).max()) if m.nv else 0.0
        if vmax > case.vmax:
            reason = f"speed {vmax:.3g} above {case.vmax:g}"
            break
        if case.fail is not None and (why := case.fail(m, d)) is not None:
            reason = why
            break
    else:
        i = n
    wall = time.perf_counter() - t0
    counts = np.asarray(d.warning.number)
    if reason is None and counts.any():
        reason = "MuJoCo warning " + ", ".join(f"{mujoco.mjtWarning(int(j)).name} x{int(counts[j])}"
                                               for j in np.flatnonzero(counts))
    steps = i + (1 if reason is not None and i < n else 0)
    return Trace(timestep * np.arange(1, steps + 1), obs[:steps], reason, wall, max(d.time, timestep))


@dataclass
class Cell:
    """One case x integrator x timestep: ``error`` in the case's unit (inf when diverged,
    per-column in ``column_errors``), ``wall_per_sim_s``, ``diverged`` and its ``reason``."""

    case: str
    group: str
    integrator: str
    timestep: float
    error: float
    unit: str
    reference: str
    wall_per_sim_s: float
    diverged: bool
    reason: str | None
    column_errors: list[float] = field(default_factory=list)

    def row(self) -> dict:
        r = dataclasses.asdict(self)
        r.pop("column_errors")
        return r


def _errors(case: Case, tr: Trace, ref: Trace | None) -> np.ndarray:
    """Per-column max |obs - reference| x scale over the run [K]."""
    if case.exact is not None:
        want = np.asarray(case.exact(tr.t), np.float64).reshape(len(tr.t), -1)
    else:
        assert ref is not None
        want = np.stack([np.interp(tr.t, ref.t, ref.obs[:, k]) for k in range(ref.obs.shape[1])], axis=1)
    diff = np.abs(tr.obs - want) * case.scale
    return diff.max(axis=0) if len(diff) else np.zeros(len(case.columns))


def reference_trace(case: Case) -> Trace | None:
    """The fine RK4 run the case's cells are compared with (None with a closed form). Raises
    when the reference itself diverges: the case then has no trustworthy answer."""
    if case.exact is not None or case.rejected:
        return None
    ref = simulate_case(case, "rk4", REF_TIMESTEP)
    if ref.reason is not None:
        raise InputError(f"stability case {case.name}: the RK4 {REF_TIMESTEP:g} s reference diverged ({ref.reason})")
    return ref


def run_cell(case: Case, integrator: str, timestep: float, ref: Trace | None) -> Cell:
    if case.rejected:
        return Cell(case.name, case.group, integrator, timestep, math.inf, case.unit, case.reference, math.nan, True,
                    f"rejected: {case.rejected}", [math.inf] * len(case.columns))
    tr = simulate_case(case, integrator, timestep)
    wall = tr.wall / tr.sim
    if tr.reason is not None:
        return Cell(case.name, case.group, integrator, timestep, math.inf, case.unit, case.reference, wall, True,
                    tr.reason, [math.inf] * len(case.columns))
    errs = _errors(case, tr, ref)
    return Cell(case.name, case.group, integrator, timestep, float(errs.max()), case.unit, case.reference, wall,
                False, None, errs.tolist())


@dataclass
class Choice:
    """The integrator and the largest timestep stable with error <= ``tolerance`` on every
    nominal cell, or None when none is. Ties at that timestep go to the cheaper integrator by
    :data:`PREFERENCE` (a fixed cost order, never the measured wall time, so the choice does
    not depend on the machine): every passing integrator is within the tolerance, and the
    extra accuracy of RK4 costs four evaluations a step. ``candidates``: every passing
    (integrator, timestep) in that order, with its error and summed wall time per simulated
    second."""

    integrator: str | None
    timestep: float | None
    tolerance: float
    nominal_error: float | None
    wall_per_sim_s: float | None
    candidates: list[dict]


def choose(cells: Sequence[Cell], tolerance: float) -> Choice:
    """Pick the twin's simulation default from the nominal cells (class doc)."""
    nominal = [c for c in cells if c.group == "nominal"]
    if not nominal:
        raise InputError("stability: no nominal case to choose from")
    by: dict[tuple[str, float], list[Cell]] = {}
    for c in nominal:
        by.setdefault((c.integrator, c.timestep), []).append(c)
    ok = []
    for (integ, dt), cs in by.items():
        if all(not c.diverged and c.error <= tolerance for c in cs):
            ok.append({"integrator": integ, "timestep": dt, "error": max(c.error for c in cs),
                       "wall_per_sim_s": sum(c.wall_per_sim_s for c in cs)})
    ok.sort(key=lambda r: (-r["timestep"], PREFERENCE.index(r["integrator"]), r["error"]))
    if not ok:
        return Choice(None, None, tolerance, None, None, [])
    best = ok[0]
    return Choice(best["integrator"], best["timestep"], tolerance, best["error"], best["wall_per_sim_s"], ok)


REMEDY_ARMATURE = (1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)
REMEDY_DAMPING = (1e-2, 1e-1, 1.0, 10.0, 100.0)


def remedy(case: Case, integrator: str, timestep: float) -> dict:
    """For an extreme case the choice does not run stably: the smallest armature, and the
    smallest damping, added to every dof that make it stable (no divergence signal) at
    (``integrator``, ``timestep``); None where nothing in the grids does. Stability only: the
    remedied case is a different system, its error is not compared with the original's."""
    if case.rejected:
        return {"armature": None, "damping": None, "note": f"rejected by MuJoCo: {case.rejected}"}
    out = {}
    for key, grid in (("armature", REMEDY_ARMATURE), ("damping", REMEDY_DAMPING)):
        out[key] = next((v for v in grid if simulate_case(case, integrator, timestep, **{key: v}).reason is None), None)
    return out


# ---------------------------------------------------------------- cases


def hinge_case(name: str, h: Hinge, duration: float, axis: Sequence[float] = (0.0, 0.0, 1.0), servo: bool = False,
               note: str | None = None) -> Case:
    """A :class:`Hinge` as a case: its closed form is the reference. ``servo``: the spring and
    damper are a position actuator's kp / kv instead of the joint's."""
    ax = " ".join(f"{float(a):.17g}" for a in axis)
    joint = (f'stiffness="{h.stiffness:.17g}" damping="{h.damping:.17g}"' if not servo else "")
    act = (f'<actuator><position joint="hinge" kp="{h.stiffness:.17g}" kv="{h.damping:.17g}"/></actuator>'
           if servo else "")
    xml = f"""<mujoco><option gravity="0 0 0"/><worldbody><body name="link">
      <inertial pos="0 0 0" mass="1" diaginertia="{h.inertia:.17g} {h.inertia:.17g} {h.inertia:.17g}"/>
      <joint name="hinge" type="hinge" axis="{ax}" armature="{h.armature:.17g}" {joint}/>
      <geom type="sphere" size="0.01" contype="0" conaffinity="0" mass="0"/></body></worldbody>{act}</mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)

    def setup(m, d):
        d.qpos[0] = h.q0

    w0 = math.sqrt(max(h.stiffness, 1e-300) / (h.inertia + h.armature))
    return Case(name, "extreme", m, duration, lambda m, d: d.qpos[:1].copy(), "rad", np.ones(1), ["q"],
                exact=lambda t: h.exact(t)[:, None], setup=setup, passive=not servo,
                vmax=100.0 * max(w0, h.damping / (h.inertia + h.armature), 1.0) * abs(h.q0), note=note)


def _mass_ratio_case() -> Case:
    xml = """<mujoco><option gravity="0 0 -9.81"/><worldbody>
      <body name="hinge_body"><joint name="j1" type="hinge" axis="1 0 0" damping="0.05"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.005" mass="0.03" contype="0" conaffinity="0"/>
        <body name="door" pos="0 0 -0.1"><joint name="j2" type="hinge" axis="1 0 0" damping="5"/>
          <geom type="box" pos="0 0 -0.3" size="0.01 0.25 0.3" mass="30" contype="0" conaffinity="0"/>
        </body></body></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)

    def setup(m, d):
        d.qpos[:] = [0.4, -0.2]

    return Case("mass_ratio", "extreme", m, 1.0, lambda m, d: d.qpos[:2].copy(), "rad", np.ones(2),
                ["q_hinge_body", "q_door"], setup=setup, passive=True, vmax=1e3,
                note="a 30 kg door on a 30 g hinge body, two hinges in gravity")


def _contact_case(drive_tau: float = 0.02, speed: float = 0.5) -> Case:
    blocks = "".join(
        f"""<body name="b{k}" pos="{-0.12 + 0.06 * k:.3f} {0.05 * (-1) ** k:.3f} 0.041">
          <freejoint/><geom type="box" size="0.02 0.02 0.02" mass="0.1" friction="0.6 0.005 0.0001"/></body>"""
        for k in range(5))
    mass = 2.0
    xml = f"""<mujoco><option gravity="0 0 -9.81"/><worldbody>
      <body name="drawer"><joint name="slide" type="slide" axis="1 0 0" range="0 0.3" damping="10"
          armature="0.05" solreflimit="0.004 1"/>
        <inertial pos="0 0 0.05" mass="{mass}" diaginertia="0.02 0.02 0.02"/>
        <geom type="box" pos="0 0 0.01" size="0.2 0.15 0.01"/>
        <geom type="box" pos="-0.21 0 0.06" size="0.01 0.15 0.06"/><geom type="box" pos="0.21 0 0.06" size="0.01 0.15 0.06"/>
        <geom type="box" pos="0 -0.16 0.06" size="0.22 0.01 0.06"/><geom type="box" pos="0 0.16 0.06" size="0.22 0.01 0.06"/>
      </body>{blocks}</worldbody>
      <actuator><velocity joint="slide" kv="{(mass + 0.05) / drive_tau:.6g}" ctrlrange="{-speed} {speed}"
        ctrllimited="true" forcerange="-150 150" forcelimited="true"/></actuator></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)

    def setup(m, d):
        d.ctrl[0] = speed

    def observe(m, d):
        return d.xpos[2:7].ravel().copy()

    def fail(m, d):
        z = d.xpos[2:7, 2]
        return f"a block fell through the drawer (z = {z.min():.3f} m)" if z.min() < 0.0 else None

    return Case("contact_rich", "extreme", m, 1.0, observe, "m", np.ones(15),
                [f"b{k}_{a}" for k in range(5) for a in "xyz"], setup=setup, vmax=50.0, fail=fail,
                note="five 0.1 kg blocks in a 2 kg drawer driven open at 0.5 m/s")


def _zero_range_case(drive_tau: float = 0.02, speed: float = 0.5) -> Case:
    body = """<mujoco><worldbody><body name="drawer"><joint name="slide" type="slide" axis="1 0 0" limited="true" range="0 {hi}"
        damping="10" armature="0.05" solreflimit="0.004 1"/><geom type="box" size="0.2 0.15 0.1" mass="2"/></body>
      </worldbody><actuator><velocity joint="slide" kv="{kv}" ctrlrange="-{v} {v}" ctrllimited="true"
        forcerange="-150 150" forcelimited="true"/></actuator></mujoco>"""
    kv = (2.0 + 0.05) / drive_tau
    try:
        mujoco.MjModel.from_xml_string(body.format(hi=0, kv=kv, v=speed))
        note = "MuJoCo accepts range [0, 0]"
    except ValueError as e:
        note = "MuJoCo refuses range [0, 0] (" + str(e).splitlines()[0].removeprefix("Error: ") + "); run at [0, 1e-9] m"
    m = mujoco.MjModel.from_xml_string(body.format(hi=1e-9, kv=kv, v=speed))

    def setup(m, d):
        d.ctrl[0] = speed

    return Case("zero_range", "extreme", m, 0.5, lambda m, d: d.qpos[:1].copy(), "m", np.ones(1), ["q"],
                exact=lambda t: np.zeros((len(t), 1)), setup=setup, vmax=50.0, note=note)


def _robot_grasp_case(duration: float = 0.6) -> Case:
    from drawer_lib.robot.ik import PandaIK
    from drawer_lib.robot.panda import FINGER_KP, FINGER_MAX, HOME, BasePose, attach_robot, robot_index

    z, proud, half = 0.7, 0.035, 0.007  # the bar's height, its face's standoff, its half thickness (m)
    xml = f"""<mujoco><option gravity="0 0 -9.81"/><worldbody>
      <body name="drawer"><joint name="slide" type="slide" axis="0 -1 0" range="0 0.4" damping="10"
          armature="0.05" frictionloss="1" solreflimit="0.004 1"/>
        <inertial pos="0 0.2 {z}" mass="3" diaginertia="0.05 0.05 0.05"/>
        <geom type="box" pos="0 0.01 {z}" size="0.25 0.01 0.1" contype="2" conaffinity="12"/>
        <geom type="box" pos="0 {-(proud - half):.4f} {z}" size="0.08 {half} {half}" contype="2" conaffinity="12"/>
      </body></worldbody></mujoco>"""
    spec = mujoco.MjSpec.from_string(xml)
    base = BasePose((0.0, -(proud - half) - 0.6, z - 0.55), math.pi / 2)
    attach_robot(spec, base, pedestal=False)
    m = spec.compile()
    ik = PandaIK()
    T = np.eye(4)
    T[:3, :3] = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])  # x, y (closing: +z), z (approach: +y)
    T[:3, 3] = [0.0, -(proud - half), z]
    Binv = np.linalg.inv(base.matrix())
    q_grip, _, _ = ik.solve(Binv @ T, HOME, iters=200)
    T[1, 3] -= 0.05
    q_pull, _, _ = ik.solve(Binv @ T, q_grip, iters=200)
    ix = robot_index(m)
    slide = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "slide")

    def setup(m, d):
        d.qpos[ix.arm_qpos] = q_grip
        d.qpos[ix.finger_qpos] = FINGER_MAX
        d.ctrl[ix.arm_act] = q_pull
        d.ctrl[ix.finger_act] = -40.0 / FINGER_KP

    def observe(m, d):
        return np.concatenate([d.qpos[m.jnt_qposadr[slide]: m.jnt_qposadr[slide] + 1], d.site_xpos[ix.tcp]])

    return Case("robot_grasp", "extreme", m, duration, observe, "m", np.ones(4), ["drawer_q", "tcp_x", "tcp_y", "tcp_z"],
                setup=setup, vmax=50.0, note="the Panda squeezing a bar handle (40 N a finger) and pulling a 3 kg "
                                             "drawer 5 cm by a step of its joint targets")


def extreme_cases() -> list[Case]:
    """The extreme cases of the module doc."""
    tiny = Hinge(inertia=1e-5, stiffness=1.0, damping=1.0, armature=1e-6, q0=0.5)
    return [
        hinge_case("stiff_joint", Hinge(inertia=1e-3, stiffness=1e4, damping=0.0), 0.2,
                   note="w = 3162 rad/s, undamped"),
        hinge_case("heavy_damping", Hinge(inertia=1e-3, stiffness=10.0, damping=1e3), 0.5,
                   note="b / I = 1e6 1/s"),
        hinge_case("tiny_armature", tiny, 0.5, note="the twin's hinge damping on a 1e-5 kg·m^2 link"),
        _mass_ratio_case(),
        hinge_case("stiff_servo", Hinge(inertia=1e-2, stiffness=1e4, damping=20.0), 0.2, servo=True,
                   note="position servo kp 1e4, kv 20 (critically damped)"),
        _contact_case(),
        _zero_range_case(),
        _robot_grasp_case(),
        hinge_case("axis_near_x", Hinge(inertia=0.35, stiffness=10.0, damping=1.0), 1.0, axis=(1e-9, 0.0, 1.0),
                   note="axis (1e-9, 0, 1)"),
        hinge_case("axis_non_unit", Hinge(inertia=0.35, stiffness=10.0, damping=1.0), 1.0, axis=(0.0, 0.0, 2.5),
                   note="axis (0, 0, 2.5)"),
    ]


def twin_case(m: mujoco.MjModel, parts: Sequence, duration: float | None = None) -> Case:
    """The twin's own parts, nominal: every articulated part of the compiled twin ``m`` driven
    open at once through its actuator (its drives turned on) (its ``ctrlrange`` top speed) with contacts off
    (neighbours opened all at once would meet, which no user does; contacts are the
    ``contact_rich`` and ``robot_grasp`` cases and the twin's checks), for ``duration`` s (default: until
    the slowest reaches its upper limit, + 0.2 s). Observed: each part's joint, scaled to metres
    at its front's farthest point from the axis (a prismatic joint is already in metres), so
    the error is how far a point of the front strays. ``parts``: :class:`drawer_lib.io.parts.Part`."""
    from drawer_lib.metrics.motion import front_grid
    from drawer_lib.sim.mjcf import part_index, set_drives

    if not parts:
        raise InputError("stability: the twin has no articulated part")
    m = set_drives(copy.copy(m), True)  # the twin loads passive; the case drives its parts
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    ixs, scale, t_open = [], [], 0.0
    for p in parts:
        ix = part_index(m, p.id)
        if min(ix["joint"], ix["actuator"]) < 0:
            raise InputError(f"stability: the twin has no joint and actuator for part {p.id!r}")
        speed = float(m.actuator_ctrlrange[ix["actuator"], 1])
        t_open = max(t_open, float(p.limits[1]) / speed)
        ixs.append(ix)
        if p.kind == "revolute":
            pts = front_grid(p.front, 3)
            o, u = np.asarray(p.axis.origin, np.float64), np.asarray(p.axis.direction, np.float64)
            u = u / np.linalg.norm(u)
            r = pts - o
            scale.append(float(np.linalg.norm(r - np.outer(r @ u, u), axis=1).max()))
        else:
            scale.append(1.0)
    qadr = np.array([ix["qpos"] for ix in ixs])
    acts = [ix["actuator"] for ix in ixs]

    def setup(m, d):
        d.ctrl[:] = 0.0
        d.ctrl[acts] = m.actuator_ctrlrange[acts, 1]

    return Case("twin_parts", "nominal", m, duration if duration is not None else t_open + 0.2,
                lambda m, d: d.qpos[qadr].copy(), "m", np.asarray(scale), [p.id for p in parts], setup=setup,
                vmax=100.0, note=f"{len(parts)} parts driven open at once, contacts off")
