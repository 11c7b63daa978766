#!/usr/bin/env python
"""An articulation ablation on the benchmark's kitchens without rebuilding them: every kitchen
of both splits articulated again from its own capture and decompose output (the
``bench_kitchen`` stages' outputs) with the params changed by ``-S key=value``, the decision
weights fitted again on the train split from those fronts (as ``fit_decisions`` does), and both
splits scored with them (as ``bench_eval`` does). Minutes instead of the benchmark's rebuild;
the same figures as a ``dvc exp run -S ...`` of the benchmark for a change that only touches
``articulate`` (or ``bench.fit``).

    python scripts/articulation_ablation.py --out /tmp/ablation/no_interaction -S articulate.interaction.enabled=false
    python scripts/articulation_ablation.py --out /tmp/ablation/best_lambda -S bench.fit.select=best

Writes ``<out>/summary.json`` (pooled and worst-kitchen figures per split, the confusion matrix
of kinds, the fit) and prints a table.
"""

import argparse
import json
import time
from pathlib import Path

import yaml
from joblib import Parallel, delayed

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.pipeline import run_articulate
from drawer_lib.bench.config import BenchConfig
from drawer_lib.bench.evaluate import confusion_matrix, score_kitchen, summarise
from drawer_lib.bench.fit import fit_decisions, labelled_fronts
from drawer_lib.config.compose import set_param
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.capture import load_capture
from drawer_lib.io.parts import read_parts
from drawer_lib.paths import BenchPaths, ScenePaths, capture_name
from drawer_lib.runner import stage_run

ROOT = Path(__file__).resolve().parent.parent
KEYS = ("precision", "recall", "ea_score", "emd", "precision_worst", "recall_worst", "ea_score_worst", "emd_worst")


def override(tree: dict, assignment: str) -> None:
    """:func:`~drawer_lib.config.compose.set_param`, a bad assignment a one-line exit."""
    try:
        set_param(tree, assignment)
    except ConfigError as e:
        raise SystemExit(str(e)) from None


def articulate(cfg: ArticulateConfig, src: ScenePaths, dst: ScenePaths, weights: dict) -> float:
    """One kitchen articulated into ``dst``; its wall time (s)."""
    t = time.perf_counter()
    with stage_run("articulate", dst.stage_dir("articulate"), seed=0) as r:
        r.metrics.update(run_articulate(cfg, load_capture(src.capture, check_files=False), src.decompose, r,
                                        weights=weights))
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True, help="folder for the re-articulated kitchens and summary.json")
    ap.add_argument("-S", dest="set", action="append", default=[], help="params override key=value (repeatable)")
    ap.add_argument("--bench", type=Path, default=None, help="the benchmark's folder (default: paths.bench)")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    p = yaml.safe_load((ROOT / "params.yaml").read_text())
    for s in a.set:
        override(p, s)
    cfg = to_typed(ArticulateConfig, p["articulate"], "articulate")
    bc = to_typed(BenchConfig, p["bench"], "bench")
    bench = BenchPaths(a.bench or ROOT / p["paths"]["bench"])
    kitchens = [(s, k) for s in ("train", "test") for k in bc.kitchens]
    for s, k in kitchens:
        if not bench.kitchen(s, k).file("decompose", "segments").is_file():
            raise InputError(f"{bench.kitchen(s, k).root}: no decompose output (run the benchmark first: make bench)")

    def run_all(sub: str, weights: dict) -> list[float]:
        return Parallel(n_jobs=a.jobs)(
            delayed(articulate)(cfg, bench.kitchen(s, k), ScenePaths(a.out / sub / s, bench.kitchen(s, k).scene), weights)
            for s, k in kitchens)

    t0 = time.perf_counter()
    times = run_all("prior", cfg.types.prior)
    rows = []
    for k in bc.kitchens:
        src = bench.kitchen("train", k)
        gt = read_parts(src.capture / capture_name("gt_parts"))
        rows += labelled_fronts(src.scene, ScenePaths(a.out / "prior" / "train", src.scene).file("articulate", "decisions"), gt)
    fit = fit_decisions(rows, cfg.types.prior, bc.fit.lambdas, bc.fit.folds, bc.fit.min_examples, select=bc.fit.select)
    run_all("fitted", fit.weights)
    summary = {"overrides": a.set, "fit": {"lambda": fit.lam, "train_accuracy": fit.train_accuracy, "n_fronts": len(rows)},
               "articulate_s_mean": sum(times) / len(times)}
    print(f"\n{' '.join(a.set) or '(params.yaml as it is)'}: fit lambda {fit.lam:g}, train accuracy "
          f"{fit.train_accuracy:.3f} on {len(rows)} fronts; articulate {summary['articulate_s_mean']:.1f} s per kitchen\n")
    print("| split | " + " | ".join(KEYS) + " | predicted / correct / GT |\n|---|" + "---|" * (len(KEYS) + 1))
    for split in ("train", "test"):
        per = [{"kitchen": k, "fitted": score_kitchen(bench.kitchen(split, k),
                                                      ScenePaths(a.out / "fitted" / split, bench.kitchen(split, k).scene).parts)}
               for k in bc.kitchens]
        s = summarise(per, "fitted")
        gt_kinds, pred_kinds, counts = confusion_matrix(per, "fitted")
        summary[split] = {**{k: s.get(k) for k in KEYS}, "n_pred": s["n_pred"], "n_correct": s["n_correct"],
                          "n_gt": s["n_gt"], "confusion": {"gt": gt_kinds, "pred": pred_kinds, "counts": counts.tolist()}}
        cells = [f"{s[k]:.3g}" if s.get(k) is not None else "–" for k in KEYS]
        print(f"| {split} | " + " | ".join(cells) + f" | {s['n_pred']} / {s['n_correct']} / {s['n_gt']} |")
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(f"\n{time.perf_counter() - t0:.0f} s; {a.out / 'summary.json'}")


if __name__ == "__main__":
    main()
