"""Pick and place: the Panda takes a small rigid block from the counter above a drawer and puts
it into the opened drawer.

The twin's own rigid objects are reconstructed as solids of their full extent (a kettle, a
bowl: 14-19 cm across), wider than the Panda hand's 8 cm opening, so the task brings its own
object: a box of ``size`` (m, full extents) and ``mass`` (kg), which the stage adds to the twin
(and, for the transfer, to the ground-truth kitchen) as a free body that collides with
everything, the robot included.

Where (world frame of the twin, m, +z up): the drawer's front gives the outward normal n (made
horizontal), the in-plane axis u and the front's top edge. The object stands on the counter:
for each ``setback`` behind the front and each lateral offset along u, a ray cast down from
``probe_height`` above the front's top edge must hit the static scene's collision within
[top - 3 cm, top + ``probe_height``]; the first such point is the counter top. The drawer is
set open at q_open (``open_fraction`` x its stop), and the object is put down over the
middle of the drawer's exposed interior (between the opened front's inner face and the closed
front's plane, centred along u); a ray cast down there must hit the drawer itself (its bottom),
else there is nowhere to place.

The path (:func:`pick_place_path`) is top-down (TCP z = world -z, the fingers closing along u),
at ``fps``: ``approach`` (from ``pregrasp`` above the grasp), ``grip``, ``lift`` to the carry
height (``lift`` above the higher of the counter top and the drawer's top edge), ``carry``
(horizontal), ``lower`` (to ``drop`` above the drawer's bottom), ``release``, ``retreat`` (up by
``pregrasp``). The base search, IK and kinematic collision checks are those of the opening
task (:mod:`drawer_lib.robot.plan`), with the drawer held at q_open.

Success: at the end, with the drawer still open, the object's centre lies inside the bounding
box, in the drawer's body frame, of the drawer's collision geoms, below the counter top. In the
ground-truth kitchen the object stands at the same (x, y) on the real counter (a ray cast there;
none is a failure), the matched part is opened to the same q (clipped to its range) and the
same actions are replayed.
"""

import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
from jaxtyping import Float

from drawer_lib.io.parts import Part
from drawer_lib.robot.panda import BIT_ROBOT, FINGER_KP, FINGER_MAX
from drawer_lib.robot.plan import PickPlaceConfig, RobotConfig, Tick, smoothstep
from drawer_lib.sim.mjcf import BIT_PART, BIT_RIGID, BIT_STATIC, GROUP_COLLISION, part_index

OBJECT = "task_object"
PICK_PHASES = ("approach", "grip", "lift", "carry", "lower", "release", "retreat")
_COLLISION_ONLY = np.array([int(g == GROUP_COLLISION) for g in range(6)], np.uint8)


@dataclass(frozen=True)
class Site:
    """Where a pick-and-place runs: the object's start (its centre, m), the counter top's height,
    the place point (the object's centre when put down), the drawer's opening q_open, the
    front's horizontal outward normal and its in-plane axis u (the fingers close along u)."""

    pick: Float[np.ndarray, "3"]
    counter_z: float
    place: Float[np.ndarray, "3"]
    q_open: float
    normal: Float[np.ndarray, "3"]
    u: Float[np.ndarray, "3"]


def ray_down(m: mujoco.MjModel, d: mujoco.MjData, xy: np.ndarray, z0: float) -> tuple[float, int]:
    """The height of the first collision surface below (xy, z0) and its geom (-1, nan when
    none); the block (:data:`OBJECT`) is not seen."""
    geom = np.array([-1], np.int32)
    dist = mujoco.mj_ray(m, d, np.array([xy[0], xy[1], z0], np.float64), np.array([0.0, 0.0, -1.0]),
                         _COLLISION_ONLY, 1, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, OBJECT), geom)
    return (z0 - dist, int(geom[0])) if dist >= 0 else (math.nan, -1)


def front_frame(part: Part) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(centre, horizontal outward normal, horizontal u, top edge height) of the part's front."""
    f = part.front
    c = np.asarray(f.center, np.float64)
    n = np.asarray(f.normal, np.float64) * [1.0, 1.0, 0.0]
    n /= max(np.linalg.norm(n), 1e-12)
    u = np.array([-n[1], n[0], 0.0])
    corners = f.corners()
    return c, n, u, float(corners[:, 2].max())


def object_clear(m: mujoco.MjModel, d: mujoco.MjData, pos: np.ndarray, clearance: float = 0.002) -> bool:
    """Whether the block of ``m`` (a model with :data:`OBJECT`), moved to ``pos`` (its centre, m,
    upright), is at least ``clearance`` m from every other collision geom, its support below
    excepted (contacts whose normal is within 30 deg of vertical under the block). ``d`` keeps the
    block there."""
    b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, OBJECT)
    adr = m.jnt_qposadr[m.body_jntadr[b]]
    d.qpos[adr:adr + 3] = pos
    d.qpos[adr + 3:adr + 7] = [1.0, 0.0, 0.0, 0.0]
    margin = m.geom_margin.copy()
    obj = m.geom_bodyid == b
    m.geom_margin[obj] = clearance
    try:
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        for c in d.contact[: d.ncon]:
            g1, g2 = int(c.geom[0]), int(c.geom[1])
            if not (obj[g1] or obj[g2]) or c.dist >= clearance:
                continue
            n = np.asarray(c.frame[:3]) * (1.0 if obj[g2] else -1.0)  # from the other geom into the block
            other_z = d.geom_xpos[g1 if obj[g2] else g2][2]
            if n[2] > math.cos(math.radians(30)) and c.dist > -0.002 and other_z < pos[2]:
                continue  # the surface it stands on
            return False
        return True
    finally:
        m.geom_margin[:] = margin


def counter_spot(m: mujoco.MjModel, d: mujoco.MjData, part: Part, cfg: PickPlaceConfig
                 ) -> tuple[np.ndarray, float] | None:
    """The object's start above ``part`` (module doc): (its centre [3] m, the counter top's
    height m), or None when no counter is found. ``m``: the kitchen with the block
    (:func:`add_object`); ``d`` holds every joint at 0 and is left with the block there. A spot
    counts when the rays under the block's centre and its four corners all meet the static
    scene within 5 mm of each other and the block there is clear of everything else
    (:func:`object_clear`: another object on the counter, a wall cabinet)."""
    c, n, u, top = front_frame(part)
    static = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "static")
    half = np.asarray(cfg.size[:2]) / 2
    for s in cfg.setback:
        for lat in cfg.lateral:
            xy = (c - s * n + lat * u)[:2]
            zs = []
            for sx, sy in ((0, 0), (-1, -1), (-1, 1), (1, -1), (1, 1)):
                z, g = ray_down(m, d, xy + sx * half[0] * n[:2] + sy * half[1] * u[:2], top + cfg.probe_height)
                zs.append(z if g >= 0 and m.geom_bodyid[g] == static else math.nan)
            z = zs[0]
            if not (np.isfinite(zs).all() and top - 0.03 <= z <= top + cfg.probe_height - 0.01
                    and max(zs) - min(zs) < 0.005):
                continue
            pos = np.array([xy[0], xy[1], max(zs) + cfg.size[2] / 2 + 0.001])
            if object_clear(m, d, pos):
                return pos, float(max(zs))
    return None


def place_spot(m: mujoco.MjModel, d: mujoco.MjData, part: Part, q_open: float, counter_z: float,
               cfg: PickPlaceConfig) -> np.ndarray | None:
    """The object's centre when put down in ``part`` opened to ``q_open`` (module doc), or None
    when the ray does not find the drawer's bottom there. ``d`` is left with the part at
    ``q_open``."""
    c, n, u, top = front_frame(part)
    ix = part_index(m, part.id)
    d.qpos[:] = m.qpos0
    d.qpos[ix["qpos"]] = q_open
    mujoco.mj_kinematics(m, d)
    mujoco.mj_collision(m, d)
    axis = np.asarray(part.axis.direction, np.float64)
    axis /= np.linalg.norm(axis)
    c_open = c + q_open * axis
    mid = 0.5 * (c_open + c) - 0.01 * n  # between the opened front's inner face and the carcass
    z0 = min(counter_z, top + q_open * axis[2]) - 0.005
    z, g = ray_down(m, d, mid[:2], z0)
    if g < 0 or m.geom_bodyid[g] != ix["body"] or z0 - z < cfg.size[2] + 0.02:
        return None
    return np.array([mid[0], mid[1], z + cfg.size[2] / 2 + cfg.drop])


def add_object(spec: mujoco.MjSpec, pos: np.ndarray, cfg: PickPlaceConfig) -> None:
    """The block as a free body :data:`OBJECT` at ``pos`` (its centre, m) in ``spec``, colliding
    with the static scene, the parts, rigid objects and the robot (in place)."""
    body = spec.worldbody.add_body(name=OBJECT, pos=[float(x) for x in pos])
    body.add_freejoint(name=OBJECT)
    half = [s / 2 for s in cfg.size]
    a, b, c = cfg.size
    body.explicitinertial = True  # the twin's compiler takes no inertia from geoms
    body.mass = cfg.mass
    body.ipos, body.iquat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]
    body.inertia = [cfg.mass / 12 * (b * b + c * c), cfg.mass / 12 * (a * a + c * c), cfg.mass / 12 * (a * a + b * b)]
    g = body.add_geom(name=f"{OBJECT}/col0", type=mujoco.mjtGeom.mjGEOM_BOX, size=half,
                      rgba=[0.85, 0.2, 0.15, 1.0], group=GROUP_COLLISION)
    g.contype, g.conaffinity = BIT_RIGID, BIT_STATIC | BIT_PART | BIT_RIGID | BIT_ROBOT
    g.friction = [cfg.friction, 0.005, 0.0001]
    body.add_geom(name=f"{OBJECT}/vis0", type=mujoco.mjtGeom.mjGEOM_BOX, size=half, contype=0, conaffinity=0,
                  group=2, rgba=[0.85, 0.2, 0.15, 1.0])


def with_object(spec_factory: Callable[[], mujoco.MjSpec], pos: np.ndarray, cfg: PickPlaceConfig
                ) -> Callable[[], mujoco.MjSpec]:
    """A spec factory of ``spec_factory``'s kitchen with the block at ``pos``."""
    def make() -> mujoco.MjSpec:
        spec = spec_factory()
        add_object(spec, pos, cfg)
        return spec
    return make


def topdown_pose(p: np.ndarray, u: np.ndarray) -> Float[np.ndarray, "4 4"]:
    """The TCP pose at ``p`` pointing straight down, the fingers closing along ``u``."""
    z = np.array([0.0, 0.0, -1.0])
    y = np.asarray(u, np.float64) - (np.asarray(u) @ z) * z
    y /= np.linalg.norm(y)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    T[:3, 3] = p
    return T


def pick_place_path(site: Site, cfg: RobotConfig, pp: PickPlaceConfig, drawer_top: float) -> list[Tick]:
    """The control ticks of the pick-and-place (module doc); every tick's ``q_part`` is the
    drawer's q_open."""
    dt = 1.0 / cfg.fps
    fo = float(min(FINGER_MAX, pp.size[1] / 2 + cfg.finger_clearance))
    closed = -cfg.grip_force / FINGER_KP
    grasp = topdown_pose(site.pick + [0.0, 0.0, 0.01], site.u)
    carry_z = max(site.counter_z, drawer_top) + pp.lift + pp.size[2]
    above_pick = grasp.copy()
    above_pick[2, 3] = max(carry_z, grasp[2, 3] + cfg.pregrasp)
    place = topdown_pose(site.place + [0.0, 0.0, 0.01], site.u)
    above_place = place.copy()
    above_place[2, 3] = above_pick[2, 3]
    pre = grasp.copy()
    pre[2, 3] += cfg.pregrasp
    ticks = [Tick(0.0, "approach", pre, fo, site.q_open)]
    t = 0.0

    def move(phase: str, a: np.ndarray, b: np.ndarray, finger_of, speed: float, min_time: float = 0.0):
        nonlocal t
        dist = float(np.linalg.norm(b[:3, 3] - a[:3, 3]))
        n = max(1, math.ceil(max(min_time, 1.5 * dist / speed) / dt))
        for k in range(1, n + 1):
            s = k / n
            T = b.copy()
            T[:3, 3] = a[:3, 3] + smoothstep(s) * (b[:3, 3] - a[:3, 3])
            ticks.append(Tick(t + k * dt, phase, T, finger_of(s), site.q_open))
        t += n * dt

    move("approach", pre, grasp, lambda s: fo, cfg.approach_speed)
    move("grip", grasp, grasp, lambda s: fo + (closed - fo) * min(1.0, 2 * s), 1.0, cfg.grip_time)
    move("lift", grasp, above_pick, lambda s: closed, cfg.approach_speed)
    move("carry", above_pick, above_place, lambda s: closed, cfg.speed_m)
    move("lower", above_place, place, lambda s: closed, cfg.approach_speed)
    move("release", place, place, lambda s: closed + (fo - closed) * min(1.0, 2 * s), 1.0, cfg.grip_time)
    retreat = place.copy()
    retreat[2, 3] += cfg.pregrasp
    move("retreat", place, retreat, lambda s: fo, cfg.approach_speed)
    move("retreat", retreat, retreat, lambda s: fo, 1.0, pp.settle)
    return ticks


def pick_key_ticks(ticks: list[Tick]) -> list[int]:
    """The ticks the base search checks: the first, the grasp, the top of the lift, and every
    fifth of the carry and the lowering."""
    idx = {0}
    for ph in PICK_PHASES[1:5]:
        sel = [i for i, tk in enumerate(ticks) if tk.phase == ph]
        idx |= {sel[0], sel[-1], *sel[:: max(1, len(sel) // 5)]} if sel else set()
    return sorted(idx)


def object_in_part(m: mujoco.MjModel, d: mujoco.MjData, part_id: str, counter_z: float, margin: float = 0.01) -> bool:
    """Whether the block's centre lies inside the bounding box (in the part's body frame,
    widened by ``margin`` m) of part ``part_id``'s collision geoms, and below ``counter_z``."""
    ob = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, OBJECT)
    pb = part_index(m, part_id)["body"]
    if ob < 0 or pb < 0:
        return False
    R, p = d.xmat[pb].reshape(3, 3), d.xpos[pb]
    pts = []
    for g in np.flatnonzero((m.geom_bodyid == pb) & (m.geom_group == GROUP_COLLISION)):
        gR = d.geom_xmat[g].reshape(3, 3)
        gp = d.geom_xpos[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            h = m.geom_size[g]
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
        else:
            r = m.geom_rbound[g]
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * r
        pts.append((gp + corners @ gR.T - p) @ R)
    if not pts:
        return False
    pts = np.concatenate(pts)
    local = (d.xpos[ob] - p) @ R
    inside = bool(np.all(local >= pts.min(0) - margin) and np.all(local <= pts.max(0) + margin))
    return inside and float(d.xpos[ob][2]) < counter_z
