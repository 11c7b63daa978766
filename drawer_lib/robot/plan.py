"""Planning a demonstration in the twin: where the robot stands, and the TCP path that grasps a
part and opens (then closes) it along the part's inferred joint.

Frames and units: world frame of the twin (m, rad, +z up). A grasp (``twin.json``'s ``grasp``,
at q = 0) gives the TCP frame: z = ``approach`` (into the front), y = ``closing_axis``, x = y × z.
While the part moves, the TCP rides rigidly with the part: at joint value q its pose is
``joint_transform(q) @ grasp pose``. Because the gripper is symmetric, the frame turned half a
turn about the approach is the same grasp; and a bar can be taken at a pitch about its own
long axis (the TCP x of a handle, y of a free edge), which is how a floor-standing arm reaches
a low drawer's bar from above. Both are free choices of the base search.

The path (:func:`task_path`) is a list of control ticks at ``fps``: ``approach`` (from
``pregrasp`` m behind the grasp, gripper open), ``grip`` (fingers close), ``open`` (the joint
from 0 to ``open_fraction`` x the upper limit, smoothstep, at most ``speed_m`` / ``speed_rad``),
``hold``; then ``close`` (back to 0), ``release`` (fingers open), ``retreat``.

The base search (:func:`find_base`) tries base poses in front of the part (distance, lateral
offset, height, grasp pitch and flip, nearest first) and keeps the first where the IK reaches
every key pose of the path within ``ik_tol_m`` / ``ik_tol_deg`` and the arm, at those poses,
touches nothing deeper than ``collision_depth``: neither the static scene, another part, nor,
with its fingers open, the part it is about to grasp (a pose whose fingers sit inside the front
would be stopped there in simulation). A pose whose deepest contact is within
``collision_margin`` of that limit is held back (the first such is kept) and the search goes
on for one that clears the limit by the margin; the held-back one is taken only when none
does, and the part is flagged. The static collision is boxes of 4 cm cells of the field, so a
contact's depth moves by millimetres when the field moves by less than one (another machine's
arithmetic): without the margin the search took another base pose there.
"""

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
from jaxtyping import Float

from drawer_lib.errors import ConfigError
from drawer_lib.geometry.joints import joint_transform
from drawer_lib.geometry.rotations import axis_angle_to_matrix
from drawer_lib.io.parts import Part
from drawer_lib.robot.ik import PandaIK
from drawer_lib.robot.panda import FINGER_KP, FINGER_MAX, HOME, BasePose

PHASES = ("approach", "grip", "open", "hold", "close", "release", "retreat")


@dataclass(frozen=True)
class BaseSearch:
    """Candidate base poses, tried in this order of nesting (outermost first): ``heights`` (m,
    the grasp's height above the base, the base clipped to the floor and to ``max_base_z``),
    ``distances`` (m, horizontal, from the grasp back along the approach), ``lateral`` (m,
    sideways; for a hinged part, positive is away from the hinge), ``pitches_deg`` (the grasp
    turned about the handle's long axis)."""

    heights: tuple[float, ...] = (0.55, 0.7, 0.4, 0.25)
    distances: tuple[float, ...] = (0.6, 0.5, 0.7, 0.8)
    lateral: tuple[float, ...] = (0.0, 0.15, -0.15, 0.3, -0.3)
    pitches_deg: tuple[float, ...] = (0.0, 35.0, -35.0, 60.0)
    max_base_z: float = 1.4
    floor_z: float = 0.0


@dataclass(frozen=True)
class PickPlaceConfig:
    """``robot.pick_place`` (:mod:`drawer_lib.robot.pick_place`). Lengths m, mass kg. ``max_drawers``: pick-and-place
    demonstrations per scene, on the drawers (prismatic parts of the drawer kind) highest first
    (nearest the counter); 0 turns the task off. ``friction``: the block's sliding friction.
    ``base_heights``, ``base_distances``: the base search's heights and distances (m, below and
    back from the middle of the pick and the place; the lateral offsets are the opening task's
    ``base``)."""

    max_drawers: int = 1
    size: tuple[float, ...] = (0.04, 0.04, 0.05)
    mass: float = 0.15
    friction: float = 1.0
    setback: tuple[float, ...] = (0.15, 0.22, 0.3)
    lateral: tuple[float, ...] = (0.0, -0.1, 0.1)
    probe_height: float = 0.35
    lift: float = 0.1
    drop: float = 0.01
    settle: float = 0.5
    base_heights: tuple[float, ...] = (0.25, 0.15, 0.35, 0.45)
    base_distances: tuple[float, ...] = (0.5, 0.4, 0.6, 0.7)

    def __post_init__(self):
        if self.max_drawers < 0:
            raise ConfigError(f"robot.pick_place.max_drawers = {self.max_drawers} must be >= 0")
        if len(self.size) != 3 or not all(math.isfinite(s) and s > 0 for s in self.size):
            raise ConfigError(f"robot.pick_place.size = {self.size} must be 3 lengths > 0 (m)")
        if self.size[1] >= 2 * FINGER_MAX:
            raise ConfigError(f"robot.pick_place.size = {self.size}: the block's width {self.size[1]} m must be "
                              f"below the gripper's opening {2 * FINGER_MAX} m")
        for k in ("mass", "friction", "probe_height", "lift", "settle"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"robot.pick_place.{k} = {v} must be finite and > 0")
        if not (self.setback and self.lateral and self.base_heights and self.base_distances) or self.drop < 0:
            raise ConfigError("robot.pick_place: setback and lateral need at least one value, drop >= 0")


@dataclass(frozen=True)
class RobotConfig:
    """The robot stage (``robot`` group). Speeds m/s or rad/s, times s, lengths m.

    ``open_fraction``: the opening asked of each part, of its upper limit; a part ``opened``
    when its joint reaches ``success_fraction`` x that target, ``closed`` when it is back below
    (1 - ``success_fraction``) x it. ``fps``: control ticks and recorded frames per second.
    ``grip_force``: what each finger squeezes with (N; the Panda hand's continuous force is
    70 N); ``finger_clearance``: the open fingers stand this far from the handle's sides (an
    8 cm open gripper would strike the fronts above and below a drawer's bar); ``camera``: width x height of the recorded stream (0 turns it off).
    ``collision_depth``, ``collision_margin``: the base search's contact limit and its margin
    (module doc). ``transfer``: replay every demonstration in the ground-truth kitchen when the
    scene has one. ``max_parts``: at most this many parts per scene (None: all). ``pick_place``: the
    pick-and-place task (:class:`PickPlaceConfig`)."""

    open_fraction: float = 0.8
    success_fraction: float = 0.85
    pregrasp: float = 0.1
    approach_speed: float = 0.1
    speed_m: float = 0.15
    speed_rad: float = 0.5
    grip_time: float = 0.6
    hold_time: float = 0.4
    fps: int = 25
    grip_force: float = 40.0
    finger_clearance: float = 0.015
    ik_tol_m: float = 0.005
    ik_tol_deg: float = 3.0
    collision_depth: float = 0.005
    collision_margin: float = 0.0015
    camera: tuple[int, ...] = (96, 72)
    transfer: bool = True
    max_parts: int | None = None
    base: BaseSearch = field(default_factory=BaseSearch)
    pick_place: PickPlaceConfig = field(default_factory=PickPlaceConfig)

    def __post_init__(self):
        if not (0 < self.open_fraction <= 1 and 0 < self.success_fraction <= 1):
            raise ConfigError("robot: open_fraction and success_fraction must be in (0, 1]")
        for k in ("pregrasp", "approach_speed", "speed_m", "speed_rad", "grip_time", "hold_time", "grip_force",
                  "finger_clearance",
                  "ik_tol_m", "ik_tol_deg", "collision_depth"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"robot.{k} = {v} must be finite and > 0")
        if not 1 <= self.fps <= 1000:
            raise ConfigError(f"robot.fps = {self.fps} must be in [1, 1000]")
        if not (math.isfinite(self.collision_margin) and 0 <= self.collision_margin < self.collision_depth):
            raise ConfigError(f"robot.collision_margin = {self.collision_margin} must be in [0, collision_depth = "
                              f"{self.collision_depth}) (m)")
        if len(self.camera) != 2 or min(self.camera) < 0:
            raise ConfigError(f"robot.camera = {self.camera} must be [width, height] >= 0")


def grasp_pose(grasp: dict, pitch: float = 0.0, flip: bool = False) -> Float[np.ndarray, "4 4"]:
    """The TCP pose (world, q = 0) of a ``twin.json`` grasp, turned by ``pitch`` (rad) about the
    handle's long axis and, with ``flip``, half a turn about the approach."""
    z = np.asarray(grasp["approach"], np.float64)
    z /= np.linalg.norm(z)
    y = np.asarray(grasp["closing_axis"], np.float64)
    y = y - (y @ z) * z
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    R = np.column_stack([x, y, z])
    if pitch:
        long_axis = x if grasp.get("kind", "handle") == "handle" else y
        R = axis_angle_to_matrix(long_axis, pitch) @ R
    if flip:
        R = R @ np.diag([-1.0, -1.0, 1.0])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = grasp["position"]
    return T


def smoothstep(s: float | np.ndarray) -> float | np.ndarray:
    """3 s^2 - 2 s^3 on [0, 1] (clipped): 0 to 1 with zero slope at both ends."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3 - 2 * s)


@dataclass
class Tick:
    """One control tick: time (s), phase, the TCP target (4x4 world), the gripper command
    (m, each finger's opening) and the part's joint value the plan expects."""

    t: float
    phase: str
    tcp: np.ndarray
    finger: float
    q_part: float


def open_width(grasp: dict, cfg: RobotConfig) -> float:
    """Each finger's opening (m) before it closes on ``grasp``: half the handle's width plus the
    clearance, at least 1 cm, at most the gripper's travel."""
    return float(min(FINGER_MAX, max(0.01, float(grasp.get("width") or 0.0) / 2 + cfg.finger_clearance)))


def task_path(part: Part, grasp_T: np.ndarray, cfg: RobotConfig, finger_open: float = FINGER_MAX,
              q_goal: float | None = None) -> list[Tick]:
    """The control ticks of the open-then-close demonstration of ``part`` (module docstring);
    the fingers open to ``finger_open`` (m each, :func:`open_width`); the joint is taken to
    ``q_goal`` (rad or m; default ``open_fraction`` x the upper limit)."""
    dt = 1.0 / cfg.fps
    if q_goal is None:
        q_goal = cfg.open_fraction * part.limits[1]
    speed = cfg.speed_rad if part.kind == "revolute" else cfg.speed_m
    approach = grasp_T[:3, 2]
    ticks: list[Tick] = []
    t = 0.0

    def seg(phase: str, duration: float, pose_of, finger_of, q_of):
        nonlocal t
        n = max(1, math.ceil(duration / dt))
        for k in range(1, n + 1):
            s = k / n
            ticks.append(Tick(t + k * dt, phase, pose_of(s), finger_of(s), q_of(s)))
        t += n * dt

    def at_q(q):
        return joint_transform(part.kind, np.asarray(part.axis.origin), np.asarray(part.axis.direction), q) @ grasp_T

    pre = grasp_T.copy()
    pre[:3, 3] -= cfg.pregrasp * approach
    closed = -cfg.grip_force / FINGER_KP  # below closed: the finger servos squeeze (panda.py)
    fo = finger_open
    ticks.append(Tick(0.0, "approach", pre, fo, 0.0))

    def lerp_pose(a, b):
        return lambda s: np.block([[a[:3, :3], (a[:3, 3] + smoothstep(s) * (b[:3, 3] - a[:3, 3]))[:, None]],
                                   [np.zeros((1, 3)), np.ones((1, 1))]])

    seg("approach", 1.5 * cfg.pregrasp / cfg.approach_speed, lerp_pose(pre, grasp_T), lambda s: fo, lambda s: 0.0)
    seg("grip", cfg.grip_time, lambda s: grasp_T, lambda s: fo + (closed - fo) * min(1.0, 2 * s),
        lambda s: 0.0)
    t_move = 1.5 * q_goal / speed  # smoothstep's peak speed is 1.5 x its mean
    seg("open", t_move, lambda s: at_q(q_goal * smoothstep(s)), lambda s: closed, lambda s: q_goal * smoothstep(s))
    seg("hold", cfg.hold_time, lambda s: at_q(q_goal), lambda s: closed, lambda s: q_goal)
    seg("close", t_move, lambda s: at_q(q_goal * (1 - smoothstep(s))), lambda s: closed,
        lambda s: q_goal * (1 - smoothstep(s)))
    seg("release", cfg.grip_time, lambda s: grasp_T, lambda s: closed + (fo - closed) * min(1.0, 2 * s),
        lambda s: 0.0)
    seg("retreat", 1.5 * cfg.pregrasp / cfg.approach_speed, lerp_pose(grasp_T, pre), lambda s: fo,
        lambda s: 0.0)
    return ticks


def key_ticks(ticks: list[Tick], n_path: int = 5) -> list[int]:
    """Indices of the ticks the base search checks: the pregrasp, the grasp and ``n_path``
    poses along the opening."""
    first = {ph: next(i for i, tk in enumerate(ticks) if tk.phase == ph) for ph in ("grip", "open", "hold")}
    opening = np.linspace(first["open"], first["hold"], n_path).round().astype(int).tolist()
    return sorted({0, first["grip"], *opening})


def solve_path(ik: PandaIK, base: BasePose, ticks: list[Tick], idx: list[int], q0: np.ndarray | None = None,
               give_up: tuple[float, float] | None = None) -> tuple[np.ndarray, float, float]:
    """Arm joints [len(idx), 7] at the ticks ``idx`` (each solve warm-started from the last);
    the worst position (m) and rotation (rad) error. ``give_up`` = (m, rad): stop at the first
    tick beyond it (the joints returned are then fewer)."""
    Binv = np.linalg.inv(base.matrix())
    q = HOME.copy() if q0 is None else q0
    out, ep_max, er_max = [], 0.0, 0.0
    for k, i in enumerate(idx):
        q, ep, er = ik.solve(Binv @ ticks[i].tcp, q, iters=100 if k == 0 else 40)
        out.append(q)
        ep_max, er_max = max(ep_max, ep), max(er_max, er)
        if give_up is not None and (ep > give_up[0] or er > give_up[1]):
            break
    return np.array(out), ep_max, er_max


def base_candidates(part: Part, grasp: dict, cfg: BaseSearch, q_goal: float = 0.0):
    """(BasePose, pitch rad, flip) in the order of :class:`BaseSearch`, facing the part; heights
    are counted from the middle of the grasp's path to ``q_goal`` (a flap's handle rises)."""
    a = np.asarray(grasp["approach"], np.float64)
    a_h = np.array([a[0], a[1], 0.0])
    if np.linalg.norm(a_h) < 1e-6:
        return
    a_h /= np.linalg.norm(a_h)
    side = np.array([-a_h[1], a_h[0], 0.0])
    if part.kind == "revolute" and part.axis is not None:  # lateral + is away from the hinge
        rel = np.asarray(grasp["position"]) - np.asarray(part.axis.origin)
        if rel @ side < 0:
            side = -side
    g = np.asarray(grasp["position"], np.float64)
    g_end = joint_transform(part.kind, np.asarray(part.axis.origin), np.asarray(part.axis.direction), q_goal)
    z_mid = 0.5 * (g[2] + (g_end[:3, :3] @ g + g_end[:3, 3])[2])
    yaw = math.atan2(a_h[1], a_h[0])
    seen = set()
    for h in cfg.heights:
        z = min(max(z_mid - h, cfg.floor_z), cfg.max_base_z)
        for d in cfg.distances:
            for s in cfg.lateral:
                p = g - d * a_h + s * side
                key = (round(z, 3), d, s)
                if key in seen:
                    continue
                seen.add(key)
                for pitch in cfg.pitches_deg:
                    for flip in (False, True):
                        yield BasePose((float(p[0]), float(p[1]), float(z)), yaw), math.radians(pitch), flip


def arm_collisions(m: mujoco.MjModel, d: mujoco.MjData, robot_geoms: frozenset[int], hand_geoms: frozenset[int],
                   part_body: int, depth: float) -> list[tuple[str, str, float]]:
    """Contacts of the robot with the scene deeper than ``depth`` (m) in ``d``'s current
    contacts: (robot geom, other geom, penetration m); the hand touching body ``part_body`` (the
    part it holds) is allowed (pass -1 to count it: a planned pose, fingers open, must not be
    inside the part it is about to grasp)."""
    out = []
    for c in d.contact[: d.ncon]:
        g1, g2 = int(c.geom1), int(c.geom2)
        if (g1 in robot_geoms) == (g2 in robot_geoms):
            continue
        r, o = (g1, g2) if g1 in robot_geoms else (g2, g1)
        if r in hand_geoms and m.geom_bodyid[o] == part_body:
            continue
        if -float(c.dist) > depth:
            out.append((mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, r) or str(r),
                        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, o) or str(o), -float(c.dist)))
    return out
