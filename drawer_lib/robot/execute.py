"""Running a planned demonstration in a kitchen model with the Panda, and recording it.

:class:`PlanningScene` is the kitchen with the robot on a movable base (three slides and a
yaw hinge) for kinematic collision checks of many base poses with one compiled model.
:func:`run_episode` compiles the kitchen with the robot fixed at the chosen base and simulates
the plan: at every control tick the arm's joint servos get the tick's IK solution and the
fingers the tick's command (held between ticks, physics at the kitchen's timestep), and each
tick records one frame (the robot's state, the action sent, the TCP pose, the part's joint and,
optionally, a camera image). The same actions replayed in another kitchen (the ground truth)
is the transfer.
"""

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from drawer_lib.robot.panda import FINGER_MAX, PREFIX, BasePose, RobotIndex, attach_robot, panda_spec, robot_index
from drawer_lib.robot.plan import Tick, arm_collisions
from drawer_lib.sim.checks import health
from drawer_lib.sim.mjcf import part_index

MOUNT = "robot_mount"
_MOUNT_JOINTS = ("robot_mount_x", "robot_mount_y", "robot_mount_z", "robot_mount_yaw")


class PlanningScene:
    """A kitchen spec with the robot on a movable base, for kinematic checks
    (:meth:`collisions`); ``spec_factory()`` returns a fresh spec of the kitchen."""

    def __init__(self, spec_factory: Callable[[], mujoco.MjSpec]):
        spec = spec_factory()
        mount = spec.worldbody.add_body(name=MOUNT)
        for name, axis, kind in zip(_MOUNT_JOINTS, ([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1]),
                                    ("slide", "slide", "slide", "hinge")):
            mount.add_joint(name=name, axis=axis, type=mujoco.mjtJoint.mjJNT_SLIDE if kind == "slide"
                            else mujoco.mjtJoint.mjJNT_HINGE)
        spec.attach(panda_spec(), prefix=PREFIX, frame=mount.add_frame())
        self.m = spec.compile()
        self.d = mujoco.MjData(self.m)
        self.ix = robot_index(self.m)
        self.mount = np.array([self.m.jnt_qposadr[mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_JOINT, n)]
                               for n in _MOUNT_JOINTS])

    def collisions(self, base: BasePose, q_arm: np.ndarray, part_id: str, q_part: float, depth: float,
                   finger: float = FINGER_MAX) -> list[tuple[str, str, float]]:
        """The robot's contacts deeper than ``depth`` with the arm at ``q_arm`` (fingers open by
        ``finger`` m each),
        its base at ``base`` and part ``part_id`` at ``q_part`` (every other joint at 0), the
        part itself included."""
        d = self.d
        d.qpos[:] = self.m.qpos0
        d.qpos[self.mount] = [*base.pos, base.yaw]
        d.qpos[self.ix.arm_qpos] = q_arm
        d.qpos[self.ix.finger_qpos] = finger
        pix = part_index(self.m, part_id)
        if pix["qpos"] >= 0:
            d.qpos[pix["qpos"]] = q_part
        mujoco.mj_kinematics(self.m, d)
        mujoco.mj_collision(self.m, d)
        return arm_collisions(self.m, d, self.ix.geoms, self.ix.hand_geoms, -1, depth)

    def deepest_contact(self, base: BasePose, part_id: str, poses: Iterable[tuple[np.ndarray, float, float]]) -> float:
        """The robot's deepest contact (m, 0 when none) over ``poses`` ((arm joints, the part's
        joint, each finger's opening m), as :meth:`collisions` takes them) with its base at ``base``."""
        return max((c[2] for q_arm, q_part, finger in poses
                    for c in self.collisions(base, q_arm, part_id, q_part, 0.0, finger)), default=0.0)


def light_visuals(spec: mujoco.MjSpec, max_faces: int) -> int:
    """Replace every visual mesh of ``spec`` (named ``<owner>/vis<k>``) that has more than
    ``max_faces`` faces by its quadric decimation (in place): a software-GL camera spends its
    time on triangles (a 200k-face kitchen: ~60 ms a frame at 96 x 72; 10k: a few ms). Returns
    the number of meshes replaced."""
    import trimesh

    from drawer_lib.mesh.clean import fast_quadric

    root = Path(spec.modelfiledir or ".") / (spec.meshdir or "")
    n = 0
    for mesh in spec.meshes:
        if "/vis" not in mesh.name or not mesh.file:
            continue
        tm = trimesh.load(root / mesh.file, process=False, force="mesh")
        if len(tm.faces) <= max_faces:
            continue
        v, f = fast_quadric(np.asarray(tm.vertices), np.asarray(tm.faces), max_faces)
        mesh.file = ""
        mesh.uservert = v.ravel().tolist()
        mesh.userface = f.ravel().tolist()
        n += 1
    return n


def episode_model(spec_factory: Callable[[], mujoco.MjSpec], base: BasePose, option: tuple[int, float] | None,
                  camera: tuple[int, int], look_at: np.ndarray, camera_faces: int = 10_000) -> mujoco.MjModel:
    """The kitchen with the robot fixed at ``base``; ``option`` = (integrator enum, timestep)
    overrides the kitchen's; with a camera size, a camera ``robot_view`` over the robot's
    shoulder looking at ``look_at``, and the visual meshes cut to ``camera_faces`` faces
    (:func:`light_visuals`)."""
    spec = spec_factory()
    attach_robot(spec, base, light=camera[0] > 0)
    if option is not None:
        spec.option.integrator, spec.option.timestep = int(option[0]), float(option[1])
    if camera[0] > 0:
        light_visuals(spec, camera_faces)
        B = base.matrix()
        eye = B[:3, 3] + B[:3, :3] @ np.array([-0.45, 0.0, 0.0])
        eye[2] = float(look_at[2]) + 0.45
        f = np.asarray(look_at, np.float64) - eye
        f /= np.linalg.norm(f)
        right = np.cross(f, [0.0, 0.0, 1.0])
        right /= max(np.linalg.norm(right), 1e-9)
        up = np.cross(right, f)
        cam = spec.worldbody.add_camera(name="robot_view", pos=eye.tolist())
        cam.alt.type = mujoco.mjtOrientation.mjORIENTATION_XYAXES
        cam.alt.xyaxes = [*right.tolist(), *up.tolist()]
        cam.fovy = 60.0
        spec.visual.global_.offwidth = max(int(spec.visual.global_.offwidth), camera[0])
        spec.visual.global_.offheight = max(int(spec.visual.global_.offheight), camera[1])
    return spec.compile()


@dataclass
class Recording:
    """One simulated demonstration, a frame per control tick. Arrays: ``time`` [T] s,
    ``state`` [T, 9] (arm joints rad, finger openings m), ``action`` [T, 8] (arm joint targets
    rad, finger command m), ``tcp`` [T, 7] (TCP position m and quaternion wxyz, world),
    ``part_q`` [T] (the part's joint, rad or m), ``phase`` [T] (index into PHASES), ``images``
    [T, H, W, 3] uint8 or None; ``touch`` [T] bool: a finger touches the part; ``collision``
    [T] m: the deepest contact of the arm with anything but the part in its hand; ``problem``:
    a MuJoCo warning or a non-finite state, else None."""

    time: np.ndarray
    state: np.ndarray
    action: np.ndarray
    tcp: np.ndarray
    part_q: np.ndarray
    phase: np.ndarray
    touch: np.ndarray
    collision: np.ndarray
    images: np.ndarray | None
    problem: str | None
    sim_steps: int = 0
    extra: dict = field(default_factory=dict)


def _finger_touch(m: mujoco.MjModel, d: mujoco.MjData, ix: RobotIndex, part_body: int) -> bool:
    for c in d.contact[: d.ncon]:
        g1, g2 = int(c.geom1), int(c.geom2)
        if (g1 in ix.hand_geoms and m.geom_bodyid[g2] == part_body) or (
                g2 in ix.hand_geoms and m.geom_bodyid[g1] == part_body):
            return True
    return False


def run_episode(m: mujoco.MjModel, ticks: list[Tick], actions: np.ndarray, part_id: str | None,
                phases: tuple[str, ...], camera: tuple[int, int] = (0, 0), start: dict[str, float] | None = None,
                probe: Callable[[mujoco.MjModel, mujoco.MjData], dict] | None = None) -> Recording:
    """Simulate ``actions`` [T, 8] (per tick: arm joint targets, finger command) in ``m`` (a
    model of :func:`episode_model`), one tick per ``1 / fps`` of ``ticks``' times; the arm
    starts at the first action's joints and finger command, the hinge and slide joints named in
    ``start`` at those values (rad or m; every other joint at its rest). ``part_id``: the part
    whose joint is recorded (None: none, its column is NaN). ``probe(m, d)`` at the end: its
    dict goes to the recording's ``extra``."""
    d = mujoco.MjData(m)
    ix = robot_index(m)
    for name, value in (start or {}).items():
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j < 0:
            raise KeyError(f"run_episode: no joint {name!r} to start at {value}")
        d.qpos[m.jnt_qposadr[j]] = value
    d.qpos[ix.arm_qpos] = actions[0, :7]
    d.qpos[ix.finger_qpos] = np.clip(actions[0, 7], 0.0, FINGER_MAX)
    d.ctrl[:] = 0.0
    mujoco.mj_forward(m, d)
    pix = part_index(m, part_id) if part_id is not None else {"qpos": -1, "body": -2}
    renderer = mujoco.Renderer(m, camera[1], camera[0]) if camera[0] > 0 else None
    cam = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "robot_view") if renderer else -1
    T = len(ticks)
    rec = {k: [] for k in ("state", "tcp", "part_q", "touch", "collision", "images")}
    times = np.array([tk.t for tk in ticks])
    steps = 0
    t_prev = 0.0
    problem = None
    try:
        for k in range(T):
            d.ctrl[ix.arm_act] = actions[k, :7]
            d.ctrl[ix.finger_act] = actions[k, 7]
            n = max(0, math.floor((times[k] - t_prev) / m.opt.timestep + 1e-9)) if k else 0
            for _ in range(n):
                mujoco.mj_step(m, d)
            steps += n
            t_prev += n * m.opt.timestep
            if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
                problem = "NaN or inf in qpos / qvel"
                break
            xq = np.empty(4)
            mujoco.mju_mat2Quat(xq, d.site_xmat[ix.tcp])
            rec["state"].append(np.concatenate([d.qpos[ix.arm_qpos], d.qpos[ix.finger_qpos]]))
            rec["tcp"].append(np.concatenate([d.site_xpos[ix.tcp], xq]))
            rec["part_q"].append(float(d.qpos[pix["qpos"]]) if pix["qpos"] >= 0 else math.nan)
            rec["touch"].append(_finger_touch(m, d, ix, pix["body"]))
            col = arm_collisions(m, d, ix.geoms, ix.hand_geoms, pix["body"], 0.0)
            rec["collision"].append(max((c[2] for c in col), default=0.0))
            if renderer is not None:
                renderer.update_scene(d, camera=cam)
                for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                             mujoco.mjtRndFlag.mjRND_SKYBOX):
                    renderer.scene.flags[flag] = 0  # software GL: shadows cost most of a frame
                rec["images"].append(renderer.render().copy())
    finally:
        if renderer is not None:
            renderer.close()
    if problem is None:
        problem, _ = health(m, d)
    extra = probe(m, d) if probe is not None and problem is None else {}
    n = len(rec["state"])
    return Recording(times[:n], np.array(rec["state"]).reshape(n, 9), actions[:n], np.array(rec["tcp"]).reshape(n, 7),
                     np.array(rec["part_q"]), np.array([phases.index(tk.phase) for tk in ticks[:n]]),
                     np.array(rec["touch"], bool), np.array(rec["collision"]),
                     np.array(rec["images"]) if rec["images"] else None, problem, steps, extra)
