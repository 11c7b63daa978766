"""Differential inverse kinematics of the Panda with ``mink`` (a QP per step, solved by DAQP):
a frame task on the TCP site, a light posture task toward :data:`~drawer_lib.robot.panda.HOME`
(which picks one arm configuration out of the redundant seventh joint's family) and the joint
limits as constraints.

The solver works on the robot alone, base at the origin; a world target is brought into the
base frame first (``inv(base) @ target``), so one compiled model serves every base pose.
"""

import mink
import mujoco
import numpy as np
from jaxtyping import Float

from drawer_lib.geometry.rotations import rotation_angle
from drawer_lib.robot.panda import FINGER_MAX, HOME, TCP, panda_spec


class PandaIK:
    """``solve(target, q0)``: arm joints that put the TCP at ``target`` (4x4, base frame)."""

    def __init__(self, posture_cost: float = 1e-3, damping: float = 1e-4, dt: float = 0.01):
        self.model = panda_spec().compile()
        self.data = mujoco.MjData(self.model)
        self.conf = mink.Configuration(self.model)
        self.tcp = mink.FrameTask(TCP, "site", position_cost=1.0, orientation_cost=0.5, lm_damping=1.0)
        self.posture = mink.PostureTask(self.model, cost=posture_cost)
        self.limits = [mink.ConfigurationLimit(self.model)]
        self.damping, self.dt = damping, dt
        self.site = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, TCP)
        q = np.concatenate([HOME, [FINGER_MAX, FINGER_MAX]])
        self.conf.update(q)
        self.posture.set_target(q)

    def fk(self, q_arm: Float[np.ndarray, "7"]) -> Float[np.ndarray, "4 4"]:
        """The TCP pose (base frame) at arm joints ``q_arm``."""
        self.data.qpos[:7] = q_arm
        self.data.qpos[7:9] = FINGER_MAX
        mujoco.mj_kinematics(self.model, self.data)
        T = np.eye(4)
        T[:3, :3] = self.data.site_xmat[self.site].reshape(3, 3)
        T[:3, 3] = self.data.site_xpos[self.site]
        return T

    def solve(self, target: Float[np.ndarray, "4 4"], q0: Float[np.ndarray, "7"], iters: int = 60,
              tol_m: float = 2e-4, tol_rad: float = 2e-3) -> tuple[np.ndarray, float, float]:
        """(arm joints [7], position error m, rotation error rad) after at most ``iters`` QP
        steps from ``q0``, stopping once within ``tol_m`` and ``tol_rad``."""
        q = np.concatenate([np.asarray(q0, np.float64), [FINGER_MAX, FINGER_MAX]])
        self.conf.update(q)
        self.tcp.set_target(mink.SE3.from_matrix(np.asarray(target, np.float64)))
        for _ in range(iters):
            T = self.fk(self.conf.q[:7])
            ep = float(np.linalg.norm(T[:3, 3] - target[:3, 3]))
            er = float(rotation_angle(T[:3, :3], target[:3, :3]))
            if ep < tol_m and er < tol_rad:
                break
            try:
                v = mink.solve_ik(self.conf, [self.tcp, self.posture], self.dt, "daqp", damping=self.damping,
                                  limits=self.limits)
            except mink.NoSolutionFound:
                break
            self.conf.integrate_inplace(v, self.dt)
        T = self.fk(self.conf.q[:7])
        return (self.conf.q[:7].copy(), float(np.linalg.norm(T[:3, 3] - target[:3, 3])),
                float(rotation_angle(T[:3, :3], target[:3, :3])))
