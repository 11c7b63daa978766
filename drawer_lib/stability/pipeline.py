"""What the ``stability`` stage does: ``twin/scene.xml`` + ``parts.json`` -> ``stability/``.

Runs the matrix of :mod:`drawer_lib.stability.study` (the twin's own parts, nominal, and the extreme
cases) over ``integrators`` x ``timesteps`` and writes

* ``matrix.csv``: one row per case x integrator x timestep (the twin's parts one row each,
  ``twin_parts/<id>``): error, its unit and reference, wall time per simulated second,
  diverged and why;
* ``heatmap.png``: log10(error / tolerance) per row and cell, diverged cells marked;
* ``choice.json``: the integrator and the largest timestep stable with error <= ``tolerance``
  on every nominal case (the twin's simulation default, which ``simulate`` uses), the twin
  config's own default and whether it agrees, the full twin's real-time factor at both, and
  every extreme case the choice does not handle (diverged, or error above the tolerance) with
  the armature and the damping that make it stable (:func:`drawer_lib.stability.study.remedy`);
* ``metrics.json``: the choice and its figures.
"""

import copy
import csv
import json
import math
import multiprocessing as mp
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.images import write_json
from drawer_lib.io.parts import read_parts
from drawer_lib.runner import StageRun
from drawer_lib.stability.hinge import INTEGRATORS
from drawer_lib.sim.mjcf import INTEGRATOR_ENUM, load_twin
from drawer_lib.stability.study import Cell, choose, extreme_cases, reference_trace, remedy, run_cell, twin_case




def _default_timesteps() -> list[float]:
    return [1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2e-2]


@dataclass(frozen=True)
class StabilityConfig:
    """``integrators`` / ``timesteps`` (s) of the matrix; ``tolerance``: the largest error a
    cell may have to pass (m of a front point for the twin's parts; each extreme case in its
    own unit, rad or m); ``extremes``: run the extreme cases; ``rtf_time``: simulated seconds
    of the full twin (contacts on, at rest) stepped to measure its real-time factor;
    ``workers``: processes the matrix's cases are spread over (0 = one per core). The cells
    do not depend on it (each case runs whole in one process; cells keep the case order),
    only their wall times do."""

    integrators: list[str] = field(default_factory=lambda: list(INTEGRATORS))
    timesteps: list[float] = field(default_factory=_default_timesteps)
    tolerance: float = 1e-3
    extremes: bool = True
    rtf_time: float = 1.0
    workers: int = 0

    def __post_init__(self):
        bad = [i for i in self.integrators if i not in INTEGRATORS]
        if bad or not self.integrators:
            raise ConfigError(f"stability.integrators {self.integrators}: each must be one of {INTEGRATORS}")
        if not self.timesteps or any(not (math.isfinite(t) and 1e-6 <= t <= 0.1) for t in self.timesteps):
            raise ConfigError(f"stability.timesteps {self.timesteps}: each must be in [1e-6, 0.1] s")
        if not (math.isfinite(self.tolerance) and self.tolerance > 0):
            raise ConfigError(f"stability.tolerance = {self.tolerance} must be > 0")
        if not self.rtf_time > 0:
            raise ConfigError(f"stability.rtf_time = {self.rtf_time} must be > 0 s")
        if self.workers < 0:
            raise ConfigError(f"stability.workers = {self.workers} must be >= 0 (0 = one per core)")


def realtime_factor(m: mujoco.MjModel, integrator: str, timestep: float, duration: float) -> float:
    """Simulated / wall seconds of ``m`` at rest (controls 0, contacts as the model has them)
    stepped ``duration`` s with ``integrator`` and ``timestep``."""
    m = copy.copy(m)
    m.opt.integrator, m.opt.timestep = INTEGRATOR_ENUM[integrator], timestep
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    n = max(1, int(round(duration / timestep)))
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nstep=n)
    return n * timestep / max(time.perf_counter() - t0, 1e-9)


def _rows(cells: list[Cell], names: dict[str, list[str]]) -> list[dict]:
    """matrix.csv rows: a nominal case's cell becomes one row per observed part."""
    rows = []
    for c in cells:
        r = c.row()
        if c.group == "nominal" and len(names[c.case]) > 1:
            for col, e in zip(names[c.case], c.column_errors):
                rows.append(r | {"case": f"{c.case}/{col}", "error": e})
        else:
            rows.append(r)
    return rows


def write_matrix(path: Path, rows: list[dict]) -> None:
    cols = ["case", "group", "integrator", "timestep", "error", "unit", "reference", "wall_per_sim_s", "diverged",
            "reason"]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.6g}" if isinstance(r[k], float) else ("" if r[k] is None else r[k])) for k in cols})


def read_matrix(path: Path) -> list[dict]:
    """matrix.csv back as dicts (floats parsed, ``diverged`` a bool)."""
    out = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            r = dict(r)
            for k in ("timestep", "error", "wall_per_sim_s"):
                r[k] = float(r[k]) if r[k] not in ("", None) else math.nan
            r["diverged"] = r["diverged"] == "True"
            r["reason"] = r["reason"] or None
            out.append(r)
    return out


def heatmap(rows: list[dict], tolerance: float, path: Path, choice: tuple[str, float] | None = None) -> None:
    """log10(error / tolerance) per row (case) and column (integrator x timestep): green passes,
    red fails, black x diverged, grey rejected; the choice boxed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm

    cases = list(dict.fromkeys(r["case"] for r in rows))
    cols = list(dict.fromkeys((r["integrator"], r["timestep"]) for r in rows))
    A = np.full((len(cases), len(cols)), np.nan)
    div = np.zeros_like(A, bool)
    rej = np.zeros_like(A, bool)
    for r in rows:
        i, j = cases.index(r["case"]), cols.index((r["integrator"], r["timestep"]))
        if r["diverged"]:
            div[i, j] = True
            rej[i, j] = str(r["reason"]).startswith("rejected")
        else:
            A[i, j] = math.log10(max(r["error"], 1e-16) / tolerance)
    fig, ax = plt.subplots(figsize=(0.32 * len(cols) + 3.5, 0.32 * len(cases) + 1.8))
    im = ax.imshow(np.clip(A, -6, 3), cmap="RdYlGn_r", norm=TwoSlopeNorm(0.0, -6, 3), aspect="auto")
    ys, xs = np.nonzero(div & ~rej)
    ax.scatter(xs, ys, marker="x", c="k", s=18, linewidths=1.2, label="diverged")
    ys, xs = np.nonzero(rej)
    ax.scatter(xs, ys, marker="s", c="0.6", s=30, label="rejected")
    ax.set_yticks(range(len(cases)), cases, fontsize=7)
    ax.set_xticks(range(len(cols)), [f"{dt:g}" for _, dt in cols], rotation=90, fontsize=7)
    ints = list(dict.fromkeys(i for i, _ in cols))
    for k, integ in enumerate(ints):
        js = [j for j, (i, _) in enumerate(cols) if i == integ]
        ax.text((js[0] + js[-1]) / 2, -0.8, integ, ha="center", va="bottom", fontsize=8)
        if k:
            ax.axvline(js[0] - 0.5, c="k", lw=1.0)
    if choice is not None and choice in cols:
        j = cols.index(choice)
        ax.add_patch(plt.Rectangle((j - 0.5, -0.5), 1, len(cases), fill=False, ec="b", lw=2))
    ax.set_xlabel("timestep (s)")
    fig.colorbar(im, ax=ax, label="log10(error / tolerance)", shrink=0.8)
    ax.legend(loc="upper left", bbox_to_anchor=(1.25, 1.0), fontsize=7, frameon=False)
    ax.set_title(f"stability: error against the reference (tolerance {tolerance:g})", fontsize=9, pad=24)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _cases(twin_dir: Path, parts_path: Path, extremes: bool) -> tuple[mujoco.MjModel, list, list]:
    """(the twin's model, its articulated parts, the matrix's cases): the twin's nominal case
    first when it has articulated parts, then the extreme cases."""
    _, m = load_twin(twin_dir, parts_path)
    parts = [p for p in read_parts(parts_path).parts if p.articulated]
    return m, parts, ([twin_case(m, parts)] if parts else []) + (extreme_cases() if extremes else [])


_WORKER: dict = {}  # what forked workers read: the cases (they hold closures, so are not pickled)


def _case_cells(k: int) -> tuple[list[Cell], float]:
    """Every integrator x timestep cell of case ``k`` and the seconds its reference took."""
    case = _WORKER["cases"][k]
    t0 = time.perf_counter()
    ref = reference_trace(case)
    t_ref = time.perf_counter() - t0
    return [run_cell(case, i, dt, ref) for i in _WORKER["integrators"] for dt in _WORKER["timesteps"]], t_ref


def run_matrix_parallel(cfg: StabilityConfig, cases: list, progress) -> tuple[list[Cell], float]:
    """The matrix's cells in case order, computed ``cfg.workers`` forked processes at a time
    (each case whole in one process, so the cells do not depend on the count), and the summed
    reference seconds. The workers only step MuJoCo and numpy: nothing of the parent's thread
    pools is used after the fork."""
    workers = min(cfg.workers or os.cpu_count() or 1, len(cases))
    _WORKER.update(cases=cases, integrators=list(cfg.integrators), timesteps=list(cfg.timesteps))
    try:
        if workers <= 1:
            done = [_case_cells(k) for k in progress(range(len(cases)), desc="cases", total=len(cases))]
        else:
            with mp.get_context("fork").Pool(workers) as pool:
                done = list(progress(pool.imap(_case_cells, range(len(cases))), desc="cases", total=len(cases)))
    finally:
        _WORKER.clear()
    return [c for cells, _ in done for c in cells], sum(t for _, t in done)


def run_stability(cfg: StabilityConfig, parts_path: Path, twin_dir: Path, twin_default: tuple[str, float],
                  run: StageRun) -> dict:
    """The stage (module doc); returns its metrics."""
    m, parts, cases = _cases(twin_dir, parts_path, cfg.extremes)
    if not parts:
        run.skip("nominal", "no articulated part: the twin's own default is kept")
    if not cfg.extremes:
        run.skip("extremes", "stability.extremes = false")
    names = {c.name: c.columns for c in cases}
    cells, t_ref = run_matrix_parallel(cfg, cases, run.progress)
    rows = _rows(cells, names)
    write_matrix(run.out("matrix"), rows)
    if parts:
        ch = choose(cells, cfg.tolerance)
    else:
        ch = None
    integ, dt = (ch.integrator, ch.timestep) if ch is not None and ch.integrator else twin_default
    source = "stability" if ch is not None and ch.integrator else "twin config (no nominal choice)"
    if ch is not None and not ch.integrator:
        run.skip("choice", f"no integrator x timestep keeps every part within {cfg.tolerance:g} m")
    heatmap(rows, cfg.tolerance, run.out("heatmap"), (integ, dt))
    outside = []
    for case in (c for c in cases if c.group == "extreme"):
        cell = next(c for c in cells if c.case == case.name and c.integrator == integ and c.timestep == dt) \
            if integ in cfg.integrators and dt in cfg.timesteps else run_cell(case, integ, dt, reference_trace(case))
        if cell.diverged or cell.error > cfg.tolerance:
            fix = remedy(case, integ, dt) if cell.diverged else {"armature": None, "damping": None,
                                                                 "note": "stable; only its error is above the tolerance"}
            stable_at = [c.timestep for c in cells if c.case == case.name and c.integrator == integ and not c.diverged]
            outside.append({"case": case.name, "note": case.note, "diverged": cell.diverged, "reason": cell.reason,
                            "error": None if math.isinf(cell.error) else cell.error, "unit": case.unit,
                            "largest_stable_timestep": max(stable_at) if stable_at else None, "remedy": fix})
    rtf = realtime_factor(m, integ, dt, cfg.rtf_time)
    rtf_default = realtime_factor(m, *twin_default, cfg.rtf_time)
    out = {"integrator": integ, "timestep": dt, "source": source, "tolerance": cfg.tolerance,
           "nominal_error": None if ch is None else ch.nominal_error, "realtime_factor": rtf,
           "twin_default": {"integrator": twin_default[0], "timestep": twin_default[1], "realtime_factor": rtf_default},
           "agrees_with_twin_default": (integ, dt) == tuple(twin_default), "outside": outside,
           "candidates": [] if ch is None else ch.candidates,
           "cases": {c.name: {"group": c.group, "reference": c.reference, "unit": c.unit, "note": c.note,
                              "duration_s": c.duration} for c in cases}}
    write_json(run.out("choice"), out)
    n_div = sum(c.diverged for c in cells)
    return {"integrator": integ, "timestep": dt, "nominal_error_m": out["nominal_error"],
            "realtime_factor": round(rtf, 2), "realtime_factor_twin_default": round(rtf_default, 2),
            "agrees_with_twin_default": out["agrees_with_twin_default"], "n_cells": len(cells),
            "n_cells_diverged": n_div, "n_extremes_outside": len(outside), "reference_wall_s": round(t_ref, 3)}


def choice_option(path: Path) -> tuple[str, float]:
    """(integrator, timestep s) of a stability run's ``choice.json``: what the simulating
    stages (``simulate``, ``robot``) run with."""
    ch = read_choice(path)
    return ch["integrator"], float(ch["timestep"])


def read_choice(path: Path) -> dict:
    """``choice.json`` of a stability run: at least ``integrator`` and ``timestep``."""
    try:
        ch = json.loads(Path(path).read_text())
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: cannot read the stability choice ({e})") from e
    if ch.get("integrator") not in INTEGRATORS or not (isinstance(ch.get("timestep"), (int, float))
                                                       and 0 < ch["timestep"] <= 0.1):
        raise InputError(f"{path}: integrator {ch.get('integrator')!r} / timestep {ch.get('timestep')!r} invalid")
    return ch

