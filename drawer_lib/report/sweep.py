"""One table of a Hydra multirun: every job's overrides and metrics side by side.

A stage run with ``-m`` writes each job into ``<hydra.sweep.dir>/<override_dirname>/`` (the
overrides of that job, ``k=v`` joined by commas, ``conf/config.yaml``) with the usual layout
below it (``<scene>/<stage>/metrics.json``). :class:`CollectSweep`, a Hydra callback
(``hydra.callbacks`` in ``conf/config.yaml``), runs after the last job on the machine that
launched the sweep (whatever the launcher: basic, joblib, submitit local or SLURM) and writes
``sweep.md``, ``sweep.json`` and ``sweep.png`` into the sweep folder; ``python -m
drawer_lib.report.sweep <sweep dir>`` does the same by hand.
"""

import json
import math
import os
import sys
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback

from drawer_lib.paths import LAYOUT
from drawer_lib.report.markdown import md_table

_SKIP = {"peak_rss_mb"}


def _overrides(name: str) -> dict[str, str]:
    """``a=1,b.c=x`` -> {"a": "1", "b.c": "x"} (a value may itself hold commas: ``l=[1,2]``)."""
    out: dict[str, str] = {}
    key = None
    for piece in name.split(","):
        if "=" in piece and not (key and out[key].count("[") > out[key].count("]")):
            key, val = piece.split("=", 1)
            out[key] = val
        elif key is not None:
            out[key] += "," + piece
    return out


def collect_sweep(sweep_dir: Path) -> list[dict]:
    """Rows ``{"job", "overrides", "metrics"}`` of every job folder holding metrics: metrics
    flattened to ``<scene>/<stage>:<key>`` (numbers and booleans only)."""
    sweep_dir = Path(sweep_dir)
    rows = []
    for job in sorted(p for p in sweep_dir.iterdir() if p.is_dir() and not p.name.startswith(".")):
        mets: dict[str, Any] = {}
        for f in sorted(job.rglob(LAYOUT["metrics"])):
            try:
                m = json.loads(f.read_text())
            except ValueError:
                continue
            where = f.parent.relative_to(job).as_posix()
            for k, v in m.items():
                if isinstance(v, (bool, int, float)) and k not in _SKIP:
                    mets[f"{where}:{k}"] = v
        if mets:
            rows.append({"job": job.name, "overrides": _overrides(job.name), "metrics": mets})
    return rows


def varying(rows: list[dict]) -> tuple[list[str], list[str]]:
    """(override keys, metric keys) that differ between jobs (all of them for a single job);
    ``wall_s`` keys last."""
    def keys(part: str) -> list[str]:
        ks = list(dict.fromkeys(k for r in rows for k in r[part]))
        if len(rows) > 1:
            ks = [k for k in ks if len({json.dumps(r[part].get(k)) for r in rows}) > 1]
        return sorted(ks, key=lambda k: (k.endswith(":wall_s"), k))

    return keys("overrides"), keys("metrics")


def _fmt(v) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool) or not isinstance(v, float):
        return str(v)
    return f"{v:.4g}" if math.isfinite(v) else str(v)


def sweep_markdown(rows: list[dict], max_metrics: int = 24) -> str:
    ok, mk = varying(rows)
    mk = mk[:max_metrics]
    head = ["job", *ok, *mk]
    return md_table(head, ([i, *(r["overrides"].get(k, "–") for k in ok), *(_fmt(r["metrics"].get(k)) for k in mk)]
                           for i, r in enumerate(rows)))


def sweep_plot(rows: list[dict], path: Path, max_metrics: int = 6) -> None:
    """One panel per varying metric (up to ``max_metrics``, wall times last): its value per job."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    _, mk = varying(rows)
    mk = [k for k in mk if all(isinstance(r["metrics"].get(k), (int, float)) for r in rows)][:max_metrics]
    n = max(len(mk), 1)
    fig, axs = plt.subplots(1, n, figsize=(3.2 * n, 3.2), squeeze=False)
    x = list(range(len(rows)))
    for ax, k in zip(axs[0], mk):
        ax.bar(x, [float(r["metrics"][k]) for r in rows], color="tab:blue")
        ax.set_xticks(x, [str(i) for i in x])
        ax.set_title(k, fontsize=7)
        ax.set_xlabel("job (sweep.md)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_sweep(sweep_dir: Path) -> list[dict]:
    """``sweep.md``, ``sweep.json`` and ``sweep.png`` of the jobs in ``sweep_dir``."""
    sweep_dir = Path(sweep_dir)
    rows = collect_sweep(sweep_dir)
    (sweep_dir / "sweep.json").write_text(json.dumps(rows, indent=1, sort_keys=True))
    if not rows:
        (sweep_dir / "sweep.md").write_text("no job wrote metrics\n")
        return rows
    (sweep_dir / "sweep.md").write_text(sweep_markdown(rows))
    sweep_plot(rows, sweep_dir / "sweep.png")
    return rows


def sweep_threads(launcher, cpu_count: int | None = None) -> int | None:
    """Threads for one job of a multirun whose ``launcher`` config runs ``n_jobs`` jobs side by
    side on this machine (joblib): ``cpu_count // n_jobs``, at least 1. None for a launcher
    without ``n_jobs`` (basic: one job at a time; submitit / SLURM: ``cpus_per_task``)."""
    n_jobs = launcher.get("n_jobs") if launcher is not None else None
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs < 1:
        return None
    return max(1, (cpu_count or os.cpu_count() or 1) // n_jobs)


class CapThreads(Callback):
    """Hydra callback: in each job of a local parallel multirun, cap torch and numba threads to
    :func:`sweep_threads` so ``n_jobs`` jobs do not oversubscribe the cores (runs in the job's
    own process, before the stage)."""

    def on_job_start(self, config, **kwargs) -> None:
        from hydra.core.hydra_config import HydraConfig
        from hydra.types import RunMode

        hc = HydraConfig.get() if HydraConfig.initialized() else None
        if hc is None or hc.mode != RunMode.MULTIRUN:
            return
        n = sweep_threads(hc.get("launcher"))
        if n is None:
            return
        import numba
        import torch

        torch.set_num_threads(n)
        numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))


class CollectSweep(Callback):
    """Hydra callback: :func:`write_sweep` after the last job of a multirun."""

    def on_multirun_end(self, config, **kwargs) -> None:
        d = Path(config.hydra.sweep.dir)
        if d.is_dir():
            rows = write_sweep(d)
            print(f"[sweep] {len(rows)} jobs -> {d / 'sweep.md'}", file=sys.stderr)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python -m drawer_lib.report.sweep <sweep dir>")
    print(sweep_markdown(write_sweep(Path(sys.argv[1]))) if collect_sweep(Path(sys.argv[1])) else "no job wrote metrics")
