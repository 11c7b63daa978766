"""Building blocks of the stability study (the ``stability`` stage): one hinge with a
torsional spring and damper, whose motion has a closed form, simulated by each MuJoCo
integrator at a given timestep, with its error against the closed form, its wall time per
simulated second and every divergence signal MuJoCo gives (non-finite state, its warning
counters — MuJoCo resets a diverging state instead of leaving NaN, so the counters are checked
explicitly — and energy growth).

The hinge: a link of inertia ``inertia`` (kg·m^2) about the joint, joint ``stiffness`` k
(N·m/rad), ``damping`` b (N·m·s/rad), ``armature`` a (kg·m^2), no gravity, released from
``q0`` at rest: (I + a) q'' + b q' + k q = 0.
"""

import math
import time
from dataclasses import dataclass

import mujoco
import numpy as np

from drawer_lib.sim.mjcf import INTEGRATOR_ENUM

INTEGRATORS = tuple(INTEGRATOR_ENUM)


@dataclass(frozen=True)
class Hinge:
    inertia: float = 0.35
    stiffness: float = 10.0
    damping: float = 1.0
    armature: float = 0.0
    q0: float = 0.5

    def exact(self, t: np.ndarray) -> np.ndarray:
        """q(t) of (I + a) q'' + b q' + k q = 0 from (q0, 0): the closed form of each regime."""
        m = self.inertia + self.armature
        t = np.asarray(t, np.float64)
        if self.stiffness == 0.0:
            return np.full_like(t, self.q0)
        w0 = math.sqrt(self.stiffness / m)
        z = self.damping / (2.0 * math.sqrt(self.stiffness * m))
        if z < 1.0 - 1e-9:
            wd = w0 * math.sqrt(1.0 - z * z)
            return self.q0 * np.exp(-z * w0 * t) * (np.cos(wd * t) + z * w0 / wd * np.sin(wd * t))
        if z > 1.0 + 1e-9:
            s = w0 * math.sqrt(z * z - 1.0)
            r1, r2 = -z * w0 + s, -z * w0 - s
            return self.q0 * (r2 * np.exp(r1 * t) - r1 * np.exp(r2 * t)) / (r2 - r1)
        return self.q0 * (1.0 + w0 * t) * np.exp(-w0 * t)

    def model(self, integrator: str, timestep: float) -> mujoco.MjModel:
        """The hinge as a MuJoCo model (a point-like link: its inertia about the joint is
        ``inertia``; mass 1 kg at the axis so only the rotation matters)."""
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator {integrator!r} must be one of {INTEGRATORS}")
        spec = mujoco.MjSpec()
        spec.option.timestep = timestep
        spec.option.gravity = [0.0, 0.0, 0.0]
        spec.option.integrator = INTEGRATOR_ENUM[integrator]
        b = spec.worldbody.add_body(name="link")
        b.explicitinertial = True
        b.mass = 1.0
        b.ipos, b.iquat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]
        b.inertia = [self.inertia, self.inertia, self.inertia]
        b.add_joint(name="hinge", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 0.0, 1.0], stiffness=self.stiffness,
                    damping=self.damping, armature=self.armature)
        b.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01, 0, 0], contype=0, conaffinity=0, mass=0.0)
        return spec.compile()


@dataclass
class Cell:
    """One integrator x timestep run: ``error`` (max |q - q_exact| over the run, rad; inf when
    diverged), ``wall_per_sim_s`` (s of wall time per simulated s), ``diverged`` and why
    (``reason``: non-finite state, a warning counter, or the energy growing above its start)."""

    integrator: str
    timestep: float
    error: float
    wall_per_sim_s: float
    diverged: bool
    reason: str | None


def run_cell(h: Hinge, integrator: str, timestep: float, duration: float = 1.0, energy_tol: float = 0.5) -> Cell:
    """Simulate ``duration`` s of the hinge released from q0 and compare with
    :meth:`Hinge.exact` at every step. The system is passive, so its energy can only fall; a
    stable integrator still lets it oscillate a little above its start (semi-implicit Euler
    conserves a nearby energy, not this one), so divergence is the energy exceeding
    (1 + ``energy_tol``) x its start."""
    m = h.model(integrator, timestep)
    d = mujoco.MjData(m)
    d.qpos[0] = h.q0
    mujoco.mj_forward(m, d)
    n = int(round(duration / timestep))
    q = np.empty(n)
    e0 = 0.5 * h.stiffness * h.q0 ** 2
    reason = None
    t0 = time.perf_counter()
    for i in range(n):  # one step at a time: the state is checked at every step
        mujoco.mj_step(m, d)
        q[i] = d.qpos[0]
        if not (math.isfinite(q[i]) and math.isfinite(d.qvel[0])):
            reason = "non-finite state"
            break
        energy = 0.5 * (h.inertia + h.armature) * d.qvel[0] ** 2 + 0.5 * h.stiffness * q[i] ** 2
        if energy > e0 * (1.0 + energy_tol) + 1e-12:
            reason = f"energy grew to {energy / max(e0, 1e-300):.3g} x its start"
            break
    wall = time.perf_counter() - t0
    counts = np.asarray(d.warning.number)
    if reason is None and counts.any():
        reason = "MuJoCo warning " + ", ".join(mujoco.mjtWarning(int(i)).name for i in np.flatnonzero(counts))
    if reason is not None:
        return Cell(integrator, timestep, math.inf, wall / max(d.time, timestep), True, reason)
    t = timestep * np.arange(1, n + 1)
    return Cell(integrator, timestep, float(np.max(np.abs(q - h.exact(t)))), wall / duration, False, None)
