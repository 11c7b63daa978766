"""Interaction checks a robot-learning user relies on, run on the twin's MJCF (the ``simulate``
stage): a cup in an opened drawer rides along when the drawer closes; a hand pulling a part's
handle (a mocap body welded to it, moved along the opening) opens it, with the force it took;
an object dropped from 20 cm comes to rest on the counter without passing through.

Each adds probe bodies to the twin with ``MjSpec`` (the twin's own files are not changed),
simulates with the twin's options and returns what it measured; a probe that cannot be placed
(no drawer, no counter found) returns ``None`` with the reason.
"""

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from drawer_lib.geometry.joints import joint_transform
from drawer_lib.io.parts import Part
from drawer_lib.sim.checks import health
from drawer_lib.sim.mjcf import BIT_PART, BIT_RIGID, BIT_STATIC, DRIVE_GROUP, INTEGRATOR_ENUM, part_index

PROBE = "probe"


@dataclass
class Probe:
    """What one interaction measured (SI units) and whether it passed; ``reason`` when it could
    not run."""

    name: str
    part: str | None
    passed: bool | None
    values: dict
    reason: str | None = None


def _spec(xml: Path, option: tuple[str, float] | None = None) -> mujoco.MjSpec:
    """The twin's spec with the parts' drives on; ``option`` = (integrator, timestep) overrides
    its own (the stability study's choice)."""
    spec = mujoco.MjSpec.from_file(str(xml))
    spec.option.disableactuator = int(spec.option.disableactuator) & ~(1 << DRIVE_GROUP)  # the probes drive parts
    if option is not None:
        spec.option.integrator = INTEGRATOR_ENUM[option[0]]
        spec.option.timestep = float(option[1])
    return spec


def _add_block(spec: mujoco.MjSpec, pos, half, mass: float) -> None:
    """A free box (MuJoCo's box-box contacts are steadier than its cylinders')."""
    hx, hy, hz = map(float, half)
    b = spec.worldbody.add_body(name=PROBE, pos=list(map(float, pos)))
    b.explicitinertial = True  # the twin's compiler takes inertias from the bodies, not the geoms
    b.mass = mass
    b.ipos, b.iquat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]
    b.inertia = [mass * (hy ** 2 + hz ** 2) / 3, mass * (hx ** 2 + hz ** 2) / 3, mass * (hx ** 2 + hy ** 2) / 3]
    b.add_freejoint(name=PROBE)
    b.add_geom(name=PROBE, type=mujoco.mjtGeom.mjGEOM_BOX, size=[hx, hy, hz], friction=[0.8, 0.005, 0.0001],
               contype=BIT_RIGID, conaffinity=BIT_STATIC | BIT_PART | BIT_RIGID)


def _ray_down(m: mujoco.MjModel, d: mujoco.MjData, start, body: int | None = None, exclude: int = -1
              ) -> tuple[float, int]:
    """(distance, geom) of the first geom below ``start`` (on ``body`` when given), -1 when none."""
    geomid = np.array([-1], np.int32)
    dist = mujoco.mj_ray(m, d, np.asarray(start, np.float64), np.array([0.0, 0.0, -1.0]), None, 1, exclude, geomid)
    g = int(geomid[0])
    if g >= 0 and body is not None and m.geom_bodyid[g] != body:
        return -1.0, -1
    return float(dist), g


def cup_rides_along(xml: Path, part: Part, open_fraction: float = 0.8, close_speed: float = 0.1, settle: float = 0.5,
                    tol: float = 0.01, option: tuple[str, float] | None = None) -> Probe:
    """A cup (a block 8 x 8 x 6 cm, 0.2 kg) set on the bottom of drawer ``part`` opened to
    ``open_fraction`` of its range; the drawer then driven closed at ``close_speed`` (m/s; a
    gentle hand: the velocity servo's 20 ms ramp at DRAWER's 0.5 m/s is 25 m/s^2, which tips
    any cup). Passes when the cup's travel along the drawer's axis is the drawer's within ``tol``
    and it is still in the drawer."""
    spec = _spec(xml, option)
    m0 = spec.compile()
    ix = part_index(m0, part.id)
    d0 = mujoco.MjData(m0)
    q_open = part.limits[0] + open_fraction * (part.limits[1] - part.limits[0])
    d0.qpos[ix["qpos"]] = q_open
    mujoco.mj_forward(m0, d0)
    n, ax = np.asarray(part.front.normal), np.asarray(part.axis.direction) / np.linalg.norm(part.axis.direction)
    top = np.asarray(part.front.center) + q_open * ax + np.array([0.0, 0.0, part.front.size[1] / 2 + 0.05])
    hit = None
    for back in (0.15, 0.1, 0.2, 0.06, 0.25):  # a spot inside the box, behind the front panel
        start = top - back * n
        dist, g = _ray_down(m0, d0, start, body=ix["body"])
        if g >= 0:
            hit = start - np.array([0.0, 0.0, dist])
            break
    if hit is None:
        return Probe("cup_rides_along", part.id, None, {}, "no drawer bottom found below the front's top")
    _add_block(spec, hit + np.array([0.0, 0.0, 0.03 + 0.002]), (0.04, 0.04, 0.03), 0.2)
    m = spec.compile()
    d = mujoco.MjData(m)
    ix = part_index(m, part.id)
    d.qpos[ix["qpos"]] = q_open
    cup = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, PROBE)
    d.ctrl[:] = 0.0
    mujoco.mj_step(m, d, nstep=math.ceil(settle / m.opt.timestep))  # the drawer held open, the cup settles
    x0, q0 = d.xpos[cup].copy(), float(d.qpos[ix["qpos"]])
    d.ctrl[ix["actuator"]] = -close_speed
    steps, max_close = 0, 1.5 * (q_open - part.limits[0]) / close_speed + 1.0
    while float(d.qpos[ix["qpos"]]) > part.limits[0] + 1e-3 and steps * m.opt.timestep < max_close:
        mujoco.mj_step(m, d)
        steps += 1
    d.ctrl[:] = 0.0
    mujoco.mj_step(m, d, nstep=math.ceil(settle / m.opt.timestep))
    q1 = float(d.qpos[ix["qpos"]])
    moved = float((d.xpos[cup] - x0) @ ax)
    problem, _ = health(m, d)
    err = abs(moved - (q1 - q0))
    ok = bool(problem is None and err <= tol and float(d.xpos[cup][2]) > hit[2] - tol)
    return Probe("cup_rides_along", part.id, ok, {"drawer_travel_m": q1 - q0, "cup_travel_m": moved,
                                                  "error_m": err, "problem": problem})


def _settled(m: mujoco.MjModel, d: mujoco.MjData, body: int, seconds: float) -> float:
    """Simulate ``seconds``; the body's speed at the end (m/s)."""
    mujoco.mj_step(m, d, nstep=math.ceil(seconds / m.opt.timestep))
    v = np.zeros(6)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, body, v, 0)
    return float(np.linalg.norm(v[3:]))


def drop_on_counter(xml: Path, parts: list[Part], height: float = 0.2, rest: float = 2.0, tol: float = 0.01,
                    option: tuple[str, float] | None = None) -> Probe:
    """A block (8 x 8 x 6 cm, 0.2 kg) dropped from ``height`` above the counter: found by a ray
    cast down 15 cm behind the front of a base cabinet (a part whose front's top is below 1.2 m),
    from 45 cm above that front, hitting the static scene within 20 cm above the front's top.
    Passes when after ``rest`` seconds it moves < 1 cm/s and its bottom is within ``tol`` of
    the counter's surface (it neither sank in nor passed through)."""
    spec = _spec(xml, option)
    m0 = spec.compile()
    d0 = mujoco.MjData(m0)
    mujoco.mj_forward(m0, d0)
    static = mujoco.mj_name2id(m0, mujoco.mjtObj.mjOBJ_BODY, "static")
    base = sorted((p for p in parts if p.articulated and p.front.corners()[:, 2].max() < 1.2),
                  key=lambda p: -p.front.size[0])
    for p in base:
        f_top = float(p.front.corners()[:, 2].max())
        start = np.asarray(p.front.center) - 0.15 * np.asarray(p.front.normal)
        start[2] = f_top + 0.45
        dist, g = _ray_down(m0, d0, start, body=static)
        if g >= 0 and f_top - 0.02 <= start[2] - dist <= f_top + 0.2:
            surface = start - np.array([0.0, 0.0, dist])
            break
    else:
        return Probe("drop_on_counter", None, None, {}, "no counter found above a base cabinet's front")
    _add_block(spec, surface + np.array([0.0, 0.0, height + 0.03]), (0.04, 0.04, 0.03), 0.2)
    m = spec.compile()
    d = mujoco.MjData(m)
    blk = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, PROBE)
    speed = _settled(m, d, blk, rest)
    bottom = float(d.xpos[blk][2]) - 0.03
    problem, _ = health(m, d)
    gap = bottom - float(surface[2])
    ok = bool(problem is None and speed < 0.01 and abs(gap) <= tol)
    return Probe("drop_on_counter", p.id, ok, {"counter_z_m": float(surface[2]), "rest_gap_m": gap,
                                                "rest_speed_m_s": speed, "problem": problem})


def pull_handle(xml: Path, part: Part, speed_rad: float = 0.5, speed_m: float = 0.2, fraction: float = 0.9,
                proud: float = 0.03, stiffness: float = 1000.0, damping: float = 60.0,
                option: tuple[str, float] | None = None) -> Probe:
    """A hand pulling the part at its handle (``proud`` in front of its front's centre) along
    its opening path to ``fraction`` of its range, smoothly (smoothstep), at most at
    ``speed_m`` (m/s, drawers) or ``speed_rad`` (rad/s, hinges), actuators off. The hand is a
    spring-damper (``stiffness`` N/m, ``damping`` N·s/m) between the grip point and the moving
    target, applied as a force at the grip (a weld to a mocap body would also damp the motion
    it follows: mocap bodies have no velocity). Passes when the part follows to within 2 % of
    its range; records the peak force the hand applied (N)."""
    m = _spec(xml, option).compile()
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    ix = part_index(m, part.id)
    b = ix["body"]
    grip = np.asarray(part.front.center) + proud * np.asarray(part.front.normal)
    local = d.xmat[b].reshape(3, 3).T @ (grip - d.xpos[b])
    lo, hi = part.limits
    goal = lo + fraction * (hi - lo)
    v = speed_rad if part.kind == "revolute" else speed_m
    o, ax = np.asarray(part.axis.origin), np.asarray(part.axis.direction)
    dur = 1.5 * (goal - lo) / v  # smoothstep: its peak speed is 1.5 x the mean
    dt = m.opt.timestep
    peak, x_prev, tgt_prev = 0.0, grip.copy(), grip.copy()
    for k in range(math.ceil(dur / dt) + math.ceil(0.5 / dt)):  # the path, then 0.5 s held at the goal
        s_ = min((k + 1) * dt / dur, 1.0)
        T = joint_transform(part.kind, o, ax, lo + (goal - lo) * s_ * s_ * (3 - 2 * s_))
        tgt = T[:3, :3] @ grip + T[:3, 3]
        x = d.xmat[b].reshape(3, 3) @ local + d.xpos[b]
        f = stiffness * (tgt - x) + damping * ((tgt - tgt_prev) - (x - x_prev)) / dt
        d.qfrc_applied[:] = 0.0
        mujoco.mj_applyFT(m, d, f, np.zeros(3), x, b, d.qfrc_applied)
        mujoco.mj_step(m, d)
        peak = max(peak, float(np.linalg.norm(f)))
        x_prev, tgt_prev = x, tgt
    q_end = float(d.qpos[ix["qpos"]])
    problem, _ = health(m, d)
    ok = bool(problem is None and abs(q_end - goal) <= 0.02 * (hi - lo))
    return Probe("pull_handle", part.id, ok, {"goal_q": goal, "reached_q": q_end, "peak_force_n": peak,
                                              "problem": problem})
