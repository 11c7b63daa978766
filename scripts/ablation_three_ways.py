#!/usr/bin/env python
"""The paper's appearance ablation (Tab. 3: textured mesh, static, movable, movable + STE) run
three ways on the same code and params, with metrics and wall times side by side:

1. ``dvc repro``: the ``appearance`` matrix's four stages, one after the other (forced, so they
   run rather than come from the run-cache);
2. ``dvc exp run --queue`` with 2 workers: one experiment per variant (forced single stage),
   ``OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 dvc queue start -j 2`` (``queue_uncapped``: without
   the thread caps, the workers oversubscribe the cores), metrics from ``dvc exp show --json``;
3. a Hydra multirun of the stage app on the joblib launcher (``hydra/launcher=local``: 2
   processes, 1 thread each), metrics from the sweep's job folders; ``hydra_joblib_uncapped``:
   the same with 2 threads per job, as the other two ways run (the thread count changes the
   order of float sums, so only equal thread counts give bit-identical numbers).

Needs a committed, clean workspace whose upstream stages are built (``make run``); the first
way rewrites the workspace's appearance outputs with the same values. Prints a markdown table
and writes it with the raw numbers to ``--out``.

    python scripts/ablation_three_ways.py --out /work/abl3          # ~35 min on 2 cores
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path


from drawer_lib.report.markdown import md_table

ROOT = Path(__file__).resolve().parent.parent

VARIANTS = ("textured_mesh", "static_gs", "movable_gs", "movable_gs_ste")
KEYS = ("psnr", "ssim", "lpips", "n_gaussians", "train_s", "wall_s")


def sh(cmd: list[str], log: Path, extra_env: dict | None = None) -> float:
    """Run ``cmd`` in the project (its .venv first on PATH), output to ``log``; wall seconds."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}", **(extra_env or {})}
    t0 = time.perf_counter()
    with log.open("a") as f:
        f.write(f"$ {' '.join(cmd)}\n")
        f.flush()
        r = subprocess.run(cmd, cwd=ROOT, env=env, stdout=f, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        raise SystemExit(f"error: {' '.join(cmd)} failed (exit {r.returncode}); see {log}")
    return time.perf_counter() - t0


def _pick(m: dict) -> dict:
    return {k: m.get(k) for k in KEYS}


def way_repro(scene: str, log: Path) -> tuple[float, dict]:
    stages = [f"appearance@{scene}-{v}" for v in VARIANTS]
    wall = sh([sys.executable, "-m", "dvc", "repro", "-f", "-s", *stages], log)
    return wall, {v: _pick(json.loads((ROOT / f"out/{scene}/appearance/{v}/metrics.json").read_text()))
                  for v in VARIANTS}


THREAD_ENV = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def way_queue(scene: str, log: Path, jobs: int, threads: int | None) -> tuple[float, dict]:
    """``threads``: the torch / numba threads of each worker's stage (the workers inherit the
    environment of ``dvc queue start``); None leaves the default (every core, per worker)."""
    names = {v: f"abl3-{v}-{int(time.time())}" for v in VARIANTS}
    t0 = time.perf_counter()
    for v in VARIANTS:
        sh([sys.executable, "-m", "dvc", "exp", "run", "--queue", "-f", "-s", "-n", names[v],
            f"appearance@{scene}-{v}"], log)
    env = {k: str(threads) for k in THREAD_ENV} if threads else {}
    sh([sys.executable, "-m", "dvc", "queue", "start", "-j", str(jobs)], log, env)
    while True:
        st = subprocess.run([sys.executable, "-m", "dvc", "queue", "status"], cwd=ROOT, capture_output=True, text=True)
        if not any(w in st.stdout for w in ("Queued", "Running")):
            break
        time.sleep(10)
    wall = time.perf_counter() - t0
    with log.open("a") as f:
        f.write(st.stdout)
    shown = json.loads(subprocess.run([sys.executable, "-m", "dvc", "exp", "show", "--json"], cwd=ROOT,
                                      capture_output=True, text=True, check=True).stdout)
    out = {}
    for rev in shown:
        for exp in (rev.get("experiments") or []):
            for e in exp.get("revs", []):
                name = e.get("name")
                for v, n in names.items():
                    if name == n:
                        mfile = e["data"]["metrics"].get(f"out/{scene}/appearance/{v}/metrics.json", {})
                        out[v] = _pick(mfile.get("data", {}))
    missing = [v for v in VARIANTS if v not in out]
    if missing:
        raise SystemExit(f"error: the queue did not report {missing}; see `dvc queue status` and {log}")
    return wall, out


def way_hydra(scene: str, log: Path, sweep: Path, cap: bool = True) -> tuple[float, dict]:
    """``cap``: each job gets cores // n_jobs threads (CapThreads, as conf/config.yaml sets it);
    without it, each job keeps every core's thread, as a single run does."""
    cap_cb = ["++hydra.callbacks.cap_threads._target_=drawer_lib.report.sweep.CapThreads"] if cap else []
    wall = sh([sys.executable, "-m", "stages.appearance", "-cn", "dvc_stage", "-m", f"scene={scene}",
               f"appearance_variant={','.join(VARIANTS)}", "hydra/launcher=local", f"hydra.sweep.dir={sweep}",
               "hydra.sweep.subdir=${hydra.job.num}", *cap_cb], log)
    return wall, {v: _pick(json.loads(next(sweep.glob(f"*/{scene}/appearance/{v}/metrics.json")).read_text()))
                  for v in VARIANTS}


def table(res: dict[str, tuple[float, dict]]) -> str:
    ways = list(res)
    head = ["variant", *(f"{w}: PSNR / SSIM / LPIPS" for w in ways), *(f"{w}: stage wall (s)" for w in ways)]
    cells = [[v, *(f"{m['psnr']:.4f} / {m['ssim']:.4f} / {m['lpips']:.4f}" for m in (res[w][1][v] for w in ways)),
              *(f"{res[w][1][v]['wall_s']:.1f}" for w in ways)] for v in VARIANTS]
    cells.append(["**whole ablation, wall**", *("" for _ in ways), *(f"**{res[w][0]:.0f}**" for w in ways)])
    lines = [md_table(head, cells).rstrip("\n")]
    ref = ways[0]
    diffs = {w: max(abs(res[w][1][v][k] - res[ref][1][v][k]) for v in VARIANTS for k in ("psnr", "ssim", "lpips"))
             for w in ways[1:]}
    lines.append("")
    lines += [f"- largest |difference| of PSNR / SSIM / LPIPS, {w} against {ref}: {d:.3g}" for w, d in diffs.items()]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--out", type=Path, default=Path("/tmp/ablation_three_ways"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--ways", default="repro,hydra_joblib,queue")
    ap.add_argument("--reuse", action="store_true", help="keep the ways already in <out>/results.json")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    log = a.out / "log.txt"
    saved = a.out / "results.json"
    res = {}
    if a.reuse and saved.is_file():
        res = {w: (r["wall_s"], r["metrics"]) for w, r in json.loads(saved.read_text()).items()}
    for w in a.ways.split(","):
        print(f"{w} ...", flush=True)
        if w == "repro":
            res["dvc repro"] = way_repro(a.scene, log)
        elif w == "queue":
            res[f"dvc queue -j {a.jobs}, 1 thread each"] = way_queue(a.scene, log, a.jobs, 1)
        elif w == "queue_uncapped":
            res[f"dvc queue -j {a.jobs}, default threads"] = way_queue(a.scene, log, a.jobs, None)
        elif w == "hydra_joblib":
            res["Hydra joblib"] = way_hydra(a.scene, log, a.out / f"sweep_{int(time.time())}")
        elif w == "hydra_joblib_uncapped":
            res["Hydra joblib, 2 threads per job"] = way_hydra(a.scene, log, a.out / f"sweep_{int(time.time())}", False)
        else:
            raise SystemExit(f"error: unknown way {w!r}; choose from repro, queue, queue_uncapped, hydra_joblib, hydra_joblib_uncapped")
        print(f"  {list(res.values())[-1][0]:.0f} s", flush=True)
        saved.write_text(json.dumps({w: {"wall_s": r[0], "metrics": r[1]} for w, r in res.items()}, indent=1))
    text = table(res)
    (a.out / "table.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
