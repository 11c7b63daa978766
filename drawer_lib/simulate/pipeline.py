"""What the ``simulate`` stage does: ``twin/scene.xml`` + ``parts.json`` -> ``simulate/``.

Every articulated part is driven open through its velocity actuator (DRAWER's 50°/s and
0.5 m/s), one at a time from the rest state, with the integrator and timestep the
``stability`` study chose (``choice.json``; or the twin's own with ``use_stability: false``); the ``grid`` x ``grid`` points of its front are recorded when its joint first reaches
each of ``samples`` values spread evenly over its range (``tracks.npz``: per part ``<id>/q``
[K], ``<id>/time`` [K] s, ``<id>/points`` [K, P, 3] m, world; a value never reached keeps the
last pose reached, and ``<id>/reached`` [K] says which were). ``evaluate`` compares them with
the GT (motion EMD). ``metrics.json``: how far the simulation strays from the part's own
kinematics (``kinematic_dev_max_m``: the largest distance between a simulated point and where
the joint puts it at the same q; ~0 unless the physics fights the joint), the parts that did
not reach their upper limit or diverged, the simulated and wall time; then the interaction
probes of :mod:`drawer_lib.simulate.interact` (a cup in each drawer, a hand on each part, a block
dropped on the counter: ``motion.json``'s ``probes``, ``<probe>_passed`` / ``_n`` and the worst
value). Every file it writes is a declared DVC output (an undeclared one is not pushed to a
remote, and a clone that pulls then sees ``out/`` differ and reruns what depends on it).
"""

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.images import write_json
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.motion import front_grid, kinematic_tracks
from drawer_lib.runner import StageRun
from drawer_lib.simulate.interact import cup_rides_along, drop_on_counter, pull_handle
from drawer_lib.sim.mjcf import INTEGRATOR_ENUM, load_twin, set_drives
from drawer_lib.simulate.drive import drive_open
from drawer_lib.stability.pipeline import choice_option


@dataclass(frozen=True)
class SimulateConfig:
    """``grid``: n x n points per front; ``samples``: joint values recorded per part;
    ``max_time``: simulated seconds per part (None: 2 x range / drive speed + 1 s);
    ``interactions``: run the probes of :mod:`drawer_lib.simulate.interact`; ``use_stability``: run
    with the integrator and timestep of the ``stability`` stage's ``choice.json`` (else the
    twin's own, from ``scene.xml``)."""

    grid: int = 8
    samples: int = 200
    max_time: float | None = None
    interactions: bool = True
    use_stability: bool = True

    def __post_init__(self):
        if not (1 <= self.grid <= 64 and 2 <= self.samples <= 100_000):
            raise ConfigError(f"simulate: need 1 <= grid <= 64 and 2 <= samples, got {self.grid}, {self.samples}")
        if self.max_time is not None and not self.max_time > 0:
            raise ConfigError(f"simulate.max_time = {self.max_time} must be > 0 s or null")


def run_simulate(cfg: SimulateConfig, parts_path: Path, twin_dir: Path, run: StageRun, choice_path: Path | None = None
                 ) -> dict:
    """Drive every articulated part open (module doc); write ``tracks.npz`` and ``motion.json``.
    ``choice_path``: the stability study's ``choice.json`` (used when ``cfg.use_stability``)."""
    xml, m = load_twin(twin_dir, parts_path)
    set_drives(m, True)  # the twin loads passive; this stage drives its parts
    option = None
    if cfg.use_stability:
        if choice_path is None or not Path(choice_path).is_file():
            raise InputError(f"{choice_path}: missing (run the stability stage, or set simulate.use_stability=false)")
        option = choice_option(choice_path)
        m.opt.integrator = INTEGRATOR_ENUM[option[0]]
        m.opt.timestep = option[1]
    parts = [p for p in read_parts(parts_path).parts if p.articulated]
    out: dict = {"n_parts": len(parts), "timestep": float(m.opt.timestep),
                 "integrator": mujoco.mjtIntegrator(int(m.opt.integrator)).name.removeprefix("mjINT_").lower()}
    arrays: dict[str, np.ndarray] = {}
    per: dict[str, dict] = {}
    if not parts:
        run.skip("tracks", "no articulated part")
    t0 = time.perf_counter()
    sim_s = 0.0
    for p in run.progress(parts, desc="drive", total=len(parts)):
        lo, hi = p.limits
        targets = np.linspace(lo, hi, cfg.samples + 1)[1:]  # q = lo is the rest pose: not a sample
        pts = front_grid(p.front, cfg.grid)
        tr = drive_open(m, p.id, pts, targets, cfg.max_time)  # the model's rest pose is q = 0
        reached = tr.reached
        last = int(np.flatnonzero(reached)[-1]) if reached.any() else -1
        points = tr.points.copy()
        points[~reached] = points[last] if last >= 0 else pts  # stuck: the last pose reached
        q = np.where(reached, tr.q, targets)
        kin = kinematic_tracks(p, pts, q[reached]) if reached.any() else np.zeros((0, len(pts), 3))
        dev = float(np.linalg.norm(points[reached] - kin, axis=-1).max()) if reached.any() else float("nan")
        arrays |= {f"{p.id}/q": q, f"{p.id}/time": tr.time, f"{p.id}/points": points, f"{p.id}/reached": reached,
                   f"{p.id}/front_points": pts}
        t_open = float(tr.time[last]) if last >= 0 else None
        per[p.id] = {"kind": p.kind, "upper": hi, "reached_fraction": float(reached.mean()),
                     "time_to_upper_s": t_open if reached.all() else None, "kinematic_dev_m": dev,
                     "steps": tr.steps, "problem": tr.problem}
        sim_s += tr.steps * m.opt.timestep
    wall = time.perf_counter() - t0
    np.savez_compressed(run.out("tracks"), **arrays)
    if parts:
        devs = [v["kinematic_dev_m"] for v in per.values() if np.isfinite(v["kinematic_dev_m"])]
        out.update(kinematic_dev_max_m=max(devs) if devs else None,
                   n_parts_not_opened=sum(v["reached_fraction"] < 1 for v in per.values()),
                   n_sim_warnings=sum(v["problem"] is not None for v in per.values()),
                   n_parts_diverged=sum(str(v["problem"]).startswith("diverged") for v in per.values()),
                   sim_time_s=round(sim_s, 4), drive_wall_s=round(wall, 4),
                   realtime_factor=round(sim_s / wall, 2) if wall > 0 else None)
    probes: list[dict] = []
    if cfg.interactions and parts:
        pm, probes = _interactions(xml, parts, run, option)
        out.update(pm)
    elif parts:
        run.skip("interactions", "simulate.interactions = false")
    write_json(run.out("motion"), {"parts": per, "probes": probes})
    return out


def _interactions(xml: Path, parts: list, run: StageRun, option: tuple[str, float] | None = None
                  ) -> tuple[dict, list[dict]]:
    """The probes (module :mod:`drawer_lib.simulate.interact`): a cup in every drawer, a hand on
    every part, a block dropped on the counter; (their metrics, every probe as a dict)."""
    t0 = time.perf_counter()
    drawers = [p for p in parts if p.kind == "prismatic"
               and abs(np.asarray(p.axis.direction) @ np.asarray(p.front.normal)) > 0.8]
    probes = [cup_rides_along(xml, p, option=option)
              for p in run.progress(drawers, desc="cup in drawer", total=len(drawers))]
    probes += [pull_handle(xml, p, option=option) for p in run.progress(parts, desc="pull handle", total=len(parts))]
    probes.append(drop_on_counter(xml, parts, option=option))
    m: dict = {}
    for name, key, metric, agg in (("cup_rides_along", "error_m", "error_max_m", max),
                                   ("pull_handle", "peak_force_n", "peak_force_max_n", max),
                                   ("drop_on_counter", "rest_gap_m", "rest_gap_max_m", lambda v: max(v, key=abs))):
        ran = [x for x in probes if x.name == name and x.passed is not None]
        if not ran:
            reasons = sorted({x.reason for x in probes if x.name == name and x.reason})
            run.skip(name, "; ".join(reasons) or ("no drawer" if name == "cup_rides_along" else "no part"))
            continue
        m[f"{name}_passed"] = sum(bool(x.passed) for x in ran)
        m[f"{name}_n"] = len(ran)
        m[f"{name}_{metric}"] = float(agg([x.values[key] for x in ran]))
    m["interactions_wall_s"] = round(time.perf_counter() - t0, 3)
    return m, [dataclasses.asdict(x) for x in probes]
