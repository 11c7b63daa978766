#!/usr/bin/env python
"""Error against training time of the neural SDF's speed knobs, with the seed spread to judge
them by: the ``sdf`` stage of the default scene run once per variant (Hydra overrides of
``conf/sdf``) into a scratch directory (``out/`` is untouched; the capture is linked from it),
``--jobs`` at a time with ``--threads`` threads each, so every variant is timed alike.

The full runs' own clocks are not comparable when the machine's load changes between them, so
the time axis is ``step x seconds per step``, the cost per step of each variant measured side by
side afterwards (``--cost-steps`` steps per variant, the variants alternating, ``--cost-rounds``
rounds, the median taken). Writes ``<out>/sdf_tradeoff.csv`` (one row per variant and
evaluation: step, measured training seconds, comparable seconds, Chamfer-L1, F@1cm, F@2cm of the
quick mesh, test depth L1) and ``sdf_tradeoff.png`` (Chamfer and F@1cm against the comparable
seconds; the default's other seeds in grey), and prints the final row of each variant next to
the default's seed spread.

    python scripts/sdf_tradeoff.py [--jobs 2] [--threads 1] [--out reports/speed] [--only default_s1 cache_50]
"""

import argparse
import csv
import json
import os
import re
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENE = "kitchen_small"
VARIANTS = {
    "default_s0": [],
    "default_s1": ["seed=1"],
    "default_s2": ["seed=2"],
    "cache_every_50": ["sdf.neural.sampling.cache_every=50"],
    "samples_12": ["sdf.neural.sampling.fine=8", "sdf.neural.sampling.uniform=4"],
    "steps_800": ["sdf.neural.steps=800"],
    "steps_800_samples_12": ["sdf.neural.steps=800", "sdf.neural.sampling.fine=8", "sdf.neural.sampling.uniform=4"],
    **{f"default_s{k}": [f"seed={k}"] for k in range(3, 5)},
    **{f"steps_800_s{k}": ["sdf.neural.steps=800", f"seed={k}"] for k in range(1, 5)},
}


def run_stage(out: Path, overrides: list[str], threads: int, stage: str = "sdf") -> float:
    """The ``sdf`` (or ``mesh``) stage into ``out`` (the capture linked from out/); its wall seconds."""
    (out / SCENE).mkdir(parents=True, exist_ok=True)
    for d in ("capture", "priors"):  # the capture and the monocular maps the sdf stage reads
        if not (out / SCENE / d).exists():
            (out / SCENE / d).symlink_to(ROOT / "out" / SCENE / d)
    t = str(threads)
    env = {**os.environ, "OMP_NUM_THREADS": t, "MKL_NUM_THREADS": t, "NUMBA_NUM_THREADS": t, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", f"stages.{stage}", "-cn", "dvc_stage", f"scene={SCENE}", f"paths.out={out}",
                        *overrides], cwd=ROOT, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{out.name}: the {stage} stage failed (exit {r.returncode}):\n{r.stderr[-2000:]}")
    return time.perf_counter() - t0


def run_variant(name: str, overrides: list[str], scratch: Path, threads: int, reuse: bool = False,
                mesh: bool = False) -> dict:
    """One variant's sdf stage (and with ``mesh`` the mesh stage after it: the tracked metrics)."""
    out = scratch / name
    if not (reuse and (out / SCENE / "sdf" / "metrics.json").is_file()):
        run_stage(out, overrides, threads)
    if mesh and not (reuse and (out / SCENE / "mesh" / "metrics.json").is_file()):
        run_stage(out, [o for o in overrides if o.startswith("seed=")], threads, stage="mesh")
    return read_variant(name, out, None)


def read_variant(name: str, out: Path, wall: float | None) -> dict:
    with open(out / SCENE / "sdf" / "curve.csv") as f:
        rows = [dict(variant=name, **row) for row in csv.DictReader(f)]
    m = json.loads((out / SCENE / "sdf" / "metrics.json").read_text())
    mesh = out / SCENE / "mesh" / "metrics.json"
    if mesh.is_file():
        m["mesh"] = json.loads(mesh.read_text())
    wall = m["wall_s"] if wall is None else wall
    print(f"{name}: {m['steps']} steps, {m['train_s']:.0f} s training, {wall:.0f} s stage, "
          f"chamfer {1000 * m['quick_chamfer_l1']:.2f} mm, F@1cm {m['quick_fscore_1cm']:.3f}", flush=True)
    return {"rows": rows, "wall": wall, "metrics": m}


def step_costs(names: list[str], scratch: Path, threads: int, steps: int, rounds: int) -> dict[str, float]:
    """Seconds per training step of each variant, measured alike: short runs (``steps`` steps, no
    evaluation), the variants alternating, ``rounds`` rounds, the median."""
    import statistics

    per: dict[str, list[float]] = {n: [] for n in names}
    for _ in range(rounds):
        for n in names:
            o = [x for x in VARIANTS[n] if not x.startswith("sdf.neural.steps=")]
            out = scratch / f"cost_{n}"
            run_stage(out, [*o, f"sdf.neural.steps={steps}", f"sdf.neural.eval_every={10 * steps}"], threads)
            m = json.loads((out / SCENE / "sdf" / "metrics.json").read_text())
            per[n].append(m["train_s"] / m["steps"])
    return {n: statistics.median(v) for n, v in per.items()}


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for name, res in results.items():
        t = [float(r["fair_s"]) for r in res["rows"]]
        seed = name.startswith("default_s") and name != "default_s0"
        kw = {"color": "0.6", "lw": 1, "label": "default, other seeds" if name == "default_s1" else None} if seed \
            else {"marker": "o", "ms": 3, "label": name}
        axes[0].plot(t, [1000 * float(r["chamfer_l1"]) for r in res["rows"]], **kw)
        axes[1].plot(t, [float(r["fscore_1cm"]) for r in res["rows"]], **kw)
    axes[0].set(xlabel="steps x s/step (measured side by side)", ylabel="Chamfer-L1 (mm)",
                title="quick mesh (2 cm cell) vs GT")
    axes[1].set(xlabel="steps x s/step (measured side by side)", ylabel="F@1cm")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--scratch", type=Path, default=Path("/tmp/drawer_sdf_tradeoff"))
    ap.add_argument("--out", type=Path, default=ROOT / "reports" / "speed")
    ap.add_argument("--cost-steps", type=int, default=60, help="steps of each cost run")
    ap.add_argument("--cost-rounds", type=int, default=2)
    ap.add_argument("--reuse", action="store_true", help="read a variant's finished run in --scratch instead of rerunning it")
    ap.add_argument("--only", nargs="+", choices=list(VARIANTS), default=list(VARIANTS))
    ap.add_argument("--mesh", action="store_true", help="also run the mesh stage per variant: the tracked metrics")
    args = ap.parse_args()
    if not (ROOT / "out" / SCENE / "capture" / "transforms.json").is_file():
        raise SystemExit(f"out/{SCENE}/capture: missing; run `dvc repro capture@{SCENE}` first")
    with ThreadPoolExecutor(args.jobs) as ex:
        futs = {n: ex.submit(run_variant, n, VARIANTS[n], args.scratch, args.threads, args.reuse, args.mesh) for n in args.only}
        results = {n: f.result() for n, f in futs.items()}
    cost = step_costs(list(results), args.scratch, args.threads, args.cost_steps, args.cost_rounds)
    for n, res in results.items():
        for r in res["rows"]:
            r["fair_s"] = round(int(r["step"]) * cost[n], 2)
    args.out.mkdir(parents=True, exist_ok=True)
    keys = ["variant", "step", "wall_s", "fair_s", "chamfer_l1", "fscore_1cm", "fscore_2cm", "test_depth_l1"]
    with open(args.out / "sdf_tradeoff.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keys, extrasaction="ignore")
        w.writeheader()
        for res in results.values():
            w.writerows(res["rows"])
    plot(results, args.out / "sdf_tradeoff.png")
    seeds = [r["metrics"] for n, r in results.items() if n.startswith("default_s")]
    print(f"\n{'variant':<24} {'steps':>5} {'ms/step':>8} {'steps x s/step':>14} {'chamfer mm':>10} {'F@1cm':>6} {'F@2cm':>6}")
    for n, r in results.items():
        m = r["metrics"]
        print(f"{n:<24} {m['steps']:>5} {1000 * cost[n]:>8.0f} {m['steps'] * cost[n]:>14.0f} {1000 * m['quick_chamfer_l1']:>10.2f} "
              f"{m['quick_fscore_1cm']:>6.3f} {m['quick_fscore_2cm']:>6.3f}")
    if len(seeds) > 1:
        for k in ("quick_chamfer_l1", "quick_fscore_1cm", "quick_fscore_2cm"):
            v = [m[k] for m in seeds]
            print(f"seed spread of {k}: {min(v):.4g} - {max(v):.4g} ({len(v)} seeds)")
    meshed = {n: r["metrics"]["mesh"] for n, r in results.items() if "mesh" in r["metrics"]}
    if meshed:
        keys = [k for k in ("chamfer_l1", "fscore_1cm", "fscore_2cm", "normal_consistency") if k in next(iter(meshed.values()))]
        print(f"\nthe mesh stage (tracked metrics)\n{'variant':<24} " + " ".join(f"{k:>18}" for k in keys))
        for n, mm in meshed.items():
            print(f"{n:<24} " + " ".join(f"{mm[k]:>18.5g}" for k in keys))
        for prefix, pattern in (("default", r"default_s\d+"), ("steps_800", r"steps_800(_s\d+)?")):
            group = [mm for n, mm in meshed.items() if re.fullmatch(pattern, n)]  # seeds only, not other variants
            if len(group) > 1:
                print(f"{prefix} ({len(group)} seeds): " + ", ".join(
                    f"{k} {min(g[k] for g in group):.5g} - {max(g[k] for g in group):.5g} (mean {sum(g[k] for g in group) / len(group):.5g})"
                    for k in keys))
    print(f"\n{args.out / 'sdf_tradeoff.csv'}, {args.out / 'sdf_tradeoff.png'}")


if __name__ == "__main__":
    main()
