"""The robot: a Franka Emika Panda as MuJoCo models it, from a registry package.

The arm's MJCF and meshes come from ``gymnasium-robotics`` (the package is MIT; its Franka
kitchen assets, ``envs/assets/kitchen_franka/franka_assets/``, are Vikash Kumar's
``vikashplus/franka`` model under Apache-2.0). They are read from the installed package, never
downloaded, and the package is located without importing it (its import pulls in gymnasium).

What this module adds to the package's model, and why:

* a ``tcp`` site on the hand, 23 cm along the flange's z (the middle of the finger pads; the
  package's ``end_effector`` site sits at their root): the point that closes on a handle. Its z
  axis is the approach direction, its y axis the fingers' closing axis;
* gravity compensation on every link (``gravcomp = 1``), as the real arm's controller does, so
  the joint position servos track their targets instead of sagging;
* finger servos that can squeeze: position servos of gain :data:`FINGER_KP` whose target may
  go below closed (to :data:`FINGER_MIN_CTRL`), so a command of ``-F / FINGER_KP`` holds a
  handle with about ``F`` newtons per finger (the package's servos stop at closed and hold a
  14 mm bar with ~4 N);
* contact bits of its own (:data:`BIT_ROBOT`): the robot collides with the static scene, the
  parts and the rigid objects of a twin, and not with itself.

Names in a scene keep the package's (``robot:panda0_joint1`` ...) behind :data:`PREFIX`.
"""

import importlib.util
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from jaxtyping import Float

from drawer_lib.errors import ConfigError
from drawer_lib.sim.mjcf import BIT_PART, BIT_RIGID, BIT_STATIC

PACKAGE = "gymnasium_robotics"
ASSETS = ("envs", "assets", "kitchen_franka", "franka_assets")
PREFIX = "robot/"
BASE = "panda0_link0"
ARM = tuple(f"robot:panda0_joint{i}" for i in range(1, 8))
FINGERS = ("robot:panda0_finger_joint1", "robot:panda0_finger_joint2")
ARM_ACTUATORS = tuple(f"panda0_joint{i}" for i in range(1, 8))
FINGER_ACTUATORS = ("r_gripper_finger_joint", "l_gripper_finger_joint")
TCP = "tcp"
TCP_Z = 0.23  # m along the flange (link 7) z: the middle of the finger pads
FINGER_MAX = 0.04  # m, each finger's travel (the gripper opens 8 cm)
FINGER_KP = 1000.0  # N/m: each finger's position servo (the package's 500 squeezes a bar with ~4 N)
FINGER_MIN_CTRL = -0.06  # m: a target below closed is how the gripper squeezes (force = kp x gap)
BIT_ROBOT = 8
# a posture with the hand level and forward at the height of the shoulder: IK starts here
HOME = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, math.pi / 4])


def franka_dir() -> Path:
    """The folder of the package's Franka MJCF files; a clear error when it is not installed."""
    spec = importlib.util.find_spec(PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise ConfigError(f"the robot stage needs the Panda model of {PACKAGE}: pip install gymnasium-robotics==1.4.2")
    d = Path(list(spec.submodule_search_locations)[0]).joinpath(*ASSETS)
    if not (d / "chain.xml").is_file():
        raise ConfigError(f"{d}: no Franka model (chain.xml) in the installed {PACKAGE}")
    return d


def panda_spec(light: bool = False) -> mujoco.MjSpec:
    """The Panda alone (base link at the origin, facing +x), with the additions of the module
    docstring. Its actuators: 7 joint position servos and one per finger (ctrl -0.06..0.04 m).
    ``light``: draw the links with their collision meshes (a few hundred faces each) instead of
    the detailed visual ones, for cheap software-GL cameras."""
    d = franka_dir()
    xml = (f'<mujoco model="panda"><include file="{d / "assets.xml"}"/>'
           f'<compiler angle="radian" meshdir="{d / "meshes"}"/>'
           f'<include file="{d / "actuator.xml"}"/>'
           f'<worldbody><include file="{d / "chain.xml"}"/></worldbody></mujoco>')
    spec = mujoco.MjSpec.from_string(xml)
    spec.nuser_actuator = -1  # as a twin's (the package's 5 user values stay on its actuators)
    if light:
        for mesh in spec.meshes:
            if mesh.name.endswith("_viz") and mesh.file.startswith("visual/"):
                mesh.file = "collision/" + mesh.file.removeprefix("visual/")
    hand = spec.body("panda0_link7")
    hand.add_site(name=TCP, pos=[0.0, 0.0, TCP_Z], euler=[0.0, 0.0, -math.pi / 4], size=[0.005, 0.0, 0.0])
    for b in spec.bodies:
        if b.name and b.name != "world":
            b.gravcomp = 1.0
    for a in spec.actuators:
        if a.name in FINGER_ACTUATORS:
            a.set_to_position(kp=FINGER_KP)
            a.ctrlrange = [FINGER_MIN_CTRL, FINGER_MAX]
    for g in spec.geoms:
        if g.contype or g.conaffinity:
            g.contype, g.conaffinity = BIT_ROBOT, BIT_STATIC | BIT_PART | BIT_RIGID
    return spec


@dataclass(frozen=True)
class BasePose:
    """Where the robot's base link stands: ``pos`` (m, world) and ``yaw`` (rad about +z; 0
    faces +x)."""

    pos: tuple[float, float, float]
    yaw: float

    def matrix(self) -> Float[np.ndarray, "4 4"]:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        T = np.eye(4)
        T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        T[:3, 3] = self.pos
        return T

    def quat(self) -> list[float]:
        return [math.cos(self.yaw / 2), 0.0, 0.0, math.sin(self.yaw / 2)]


PEDESTAL = "robot_pedestal"


def attach_robot(spec: mujoco.MjSpec, base: BasePose, pedestal: bool = True, light: bool = False) -> None:
    """Attach the Panda to ``spec`` (in place) with its base at ``base``, its names behind
    :data:`PREFIX` (``light``: see :func:`panda_spec`); with ``pedestal``, a visual column from the floor to the base (the lift a
    mobile base or a table gives; it does not collide)."""
    frame = spec.worldbody.add_frame(pos=list(base.pos), quat=base.quat())
    with warnings.catch_warnings():  # the robot's meshes are files, the twin's in spec.assets: both resolve
        warnings.filterwarnings("ignore", message="Attaching a child without asset dict")
        spec.attach(panda_spec(light), prefix=PREFIX, frame=frame)
    if pedestal and base.pos[2] > 0.02:
        h = base.pos[2] / 2
        spec.worldbody.add_geom(name=PEDESTAL, type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.09, 0.09, h],
                                pos=[base.pos[0], base.pos[1], h], contype=0, conaffinity=0, group=2,
                                rgba=[0.3, 0.3, 0.32, 1.0])


@dataclass(frozen=True)
class RobotIndex:
    """MuJoCo ids of the attached robot in a compiled model: qpos / dof addresses of the arm and
    the fingers, actuator ids, the TCP site and the set of the robot's geoms."""

    arm_qpos: np.ndarray
    arm_dof: np.ndarray
    finger_qpos: np.ndarray
    arm_act: np.ndarray
    finger_act: np.ndarray
    tcp: int
    geoms: frozenset[int]
    hand_geoms: frozenset[int]  # hand and fingers: allowed to touch the part they grasp


def robot_index(m: mujoco.MjModel, prefix: str = PREFIX) -> RobotIndex:
    def jid(n):
        i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, prefix + n)
        if i < 0:
            raise KeyError(f"no joint {prefix + n} in the model")
        return i

    def aid(n):
        return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, prefix + n)

    arm = [jid(n) for n in ARM]
    fing = [jid(n) for n in FINGERS]
    bodies = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, prefix + b) for b in
              [BASE] + [f"panda0_link{i}" for i in range(1, 8)] + ["panda0_leftfinger", "panda0_rightfinger"]}
    hand = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, prefix + b) for b in
            ("panda0_link7", "panda0_leftfinger", "panda0_rightfinger")}
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] in bodies and m.geom_contype[g]]
    return RobotIndex(np.array([m.jnt_qposadr[j] for j in arm]), np.array([m.jnt_dofadr[j] for j in arm]),
                      np.array([m.jnt_qposadr[j] for j in fing]), np.array([aid(n) for n in ARM_ACTUATORS]),
                      np.array([aid(n) for n in FINGER_ACTUATORS]),
                      mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, prefix + TCP), frozenset(geoms),
                      frozenset(g for g in geoms if m.geom_bodyid[g] in hand))
