"""Driven motion of the twin's parts in MuJoCo (the ``simulate`` stage's physics).

:func:`drive_open` opens one part through its velocity actuator (every other actuator holds
its part at rest), as DRAWER drives its doors and drawers (50°/s, 0.5 m/s), and records where
given points on the part are when its joint first reaches each of a list of values: the
*simulated* tracks the motion EMD compares with the GT (:mod:`drawer_lib.metrics.motion`).
"""

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from jaxtyping import Float

from drawer_lib.errors import InputError
from drawer_lib.sim.checks import health
from drawer_lib.sim.mjcf import drives_on, part_index


@dataclass
class DrivenTrack:
    """``points`` [T, P, 3] (m, world) where the part's points were when its joint first reached
    each target (linear interpolation between the two steps around it; NaN for a target never
    reached), ``q`` [T] the joint value there (= the target when reached), ``time`` [T] (s),
    ``reached`` [T] bool, and the simulation's ``problem`` (a MuJoCo warning, or "diverged: ..."
    when the state went non-finite: the drive stops there, everything recorded is finite) or
    None."""

    points: np.ndarray
    q: np.ndarray
    time: np.ndarray
    reached: np.ndarray
    problem: str | None
    steps: int


def drive_open(m: mujoco.MjModel, pid: str, points: Float[np.ndarray, "P 3"], targets: Float[np.ndarray, "T"],
               max_time: float | None = None) -> DrivenTrack:
    """Drive part ``pid`` of the compiled twin ``m`` open at its actuator's top speed (its
    ``ctrlrange``), from the model's rest state, until its joint passes the last of the
    increasing ``targets`` (rad or m) or ``max_time`` simulated seconds (default: twice the time
    the last target needs at top speed, plus 1 s) pass. ``points`` [P, 3]: world points on the
    part at q = 0. The model's drives must be on (:func:`~drawer_lib.sim.mjcf.set_drives`)."""
    ix = part_index(m, pid)
    if min(ix["body"], ix["joint"], ix["actuator"]) < 0:
        raise InputError(f"part {pid!r}: the model has no body, joint and actuator of that name")
    if not drives_on(m):
        raise InputError(f"part {pid!r}: the model's drives are off (the twin loads passive): turn them on with "
                         "drawer_lib.sim.mjcf.set_drives(m, True)")
    targets = np.asarray(targets, np.float64)
    if len(targets) == 0 or np.any(np.diff(targets) <= 0) or not np.isfinite(targets).all():
        raise InputError(f"part {pid!r}: targets must be finite and increasing, got {targets}")
    speed = float(m.actuator_ctrlrange[ix["actuator"], 1])
    if not speed > 0:
        raise InputError(f"part {pid!r}: its actuator's top speed {speed} must be > 0")
    if max_time is None:
        max_time = 2.0 * targets[-1] / speed + 1.0
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    b, qa = ix["body"], ix["qpos"]
    q0 = float(d.qpos[qa])
    R0, p0 = d.xmat[b].reshape(3, 3).copy(), d.xpos[b].copy()
    local = (np.asarray(points, np.float64) - p0) @ R0  # body frame at q = 0
    d.ctrl[:] = 0.0
    d.ctrl[ix["actuator"]] = speed
    T = len(targets)
    out = np.full((T, len(local), 3), np.nan)
    qs, ts = np.full(T, np.nan), np.full(T, np.nan)
    prev_q, prev_x, prev_t = q0, local @ R0.T + p0, 0.0
    k, n = 0, 0
    n_max = math.ceil(max_time / m.opt.timestep)
    while k < T and n < n_max:  # one step at a time: the targets are crossed within a step
        mujoco.mj_step(m, d)
        n += 1
        q = float(d.qpos[qa]) - q0
        x = local @ d.xmat[b].reshape(3, 3).T + d.xpos[b]
        while k < T and q >= targets[k]:
            a = (targets[k] - prev_q) / (q - prev_q) if q > prev_q else 1.0
            out[k] = (1 - a) * prev_x + a * x
            qs[k], ts[k] = targets[k], (1 - a) * prev_t + a * d.time
            k += 1
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            break
        prev_q, prev_x, prev_t = q, x, d.time
    problem, nonfinite = health(m, d)
    if nonfinite:  # what was recorded before is finite; the caller reports the divergence
        problem = f"diverged: {problem}"
    return DrivenTrack(out, qs, ts, np.isfinite(qs), problem, n)
