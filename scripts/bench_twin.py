#!/usr/bin/env python
"""The twin of every benchmark kitchen of a split, built and checked in MuJoCo: each kitchen's
own capture, SDF and decompose output (the ``bench_kitchen`` stages' outputs) articulated with
the fitted weights, completed and exported as the pipeline does, with the params changed by
``-S key=value``. Reports per kitchen and pooled: the twins whose physical checks all pass,
the failures by check, the parts a person's pull opens on the file as it loads, the parts
stopped by a neighbour or the carcass before their limit, the overlaps repaired, the handle
boxes and grasp kinds, the static collision's size and the simulation speed.

    python scripts/bench_twin.py --out /tmp/bench_twin/default
    python scripts/bench_twin.py --out /tmp/bench_twin/no_contacts -S sim.contact.part_static=false -S sim.contact.part_part=false

Writes ``<out>/summary.json`` and prints a table. The kitchens have no appearance model, so the
twins carry no Gaussians and no renders are scored.
"""

import argparse
import json
import time
from collections import Counter
from pathlib import Path

import yaml
from joblib import Parallel, delayed

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.pipeline import run_articulate
from drawer_lib.articulation.weights import resolve_weights
from drawer_lib.bench.config import BenchConfig
from drawer_lib.complete.config import CompleteConfig
from drawer_lib.complete.pipeline import CompleteInputs, run_complete
from drawer_lib.config.compose import set_param
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.capture import load_capture
from drawer_lib.paths import BenchPaths, ScenePaths
from drawer_lib.runner import stage_run
from drawer_lib.sim.config import SimConfig
from drawer_lib.twin.config import TwinConfig
from drawer_lib.twin.pipeline import run_twin

ROOT = Path(__file__).resolve().parent.parent


def override(tree: dict, assignment: str) -> None:
    """:func:`~drawer_lib.config.compose.set_param`, a bad assignment a one-line exit."""
    try:
        set_param(tree, assignment)
    except ConfigError as e:
        raise SystemExit(str(e)) from None


def build(p: dict, src: ScenePaths, dst: ScenePaths, weights: dict) -> dict:
    """One kitchen's twin under ``dst``; what its stages measured."""
    ac = to_typed(ArticulateConfig, p["articulate"], "articulate")
    cc = to_typed(CompleteConfig, p["complete"], "complete")
    sim = to_typed(SimConfig, p["sim"], "sim")
    tc = to_typed(TwinConfig, p["twin"], "twin")
    cap = load_capture(src.capture, check_files=False)
    t = {}
    t0 = time.perf_counter()
    with stage_run("articulate", dst.stage_dir("articulate"), seed=0) as r:
        r.metrics.update(run_articulate(ac, cap, src.decompose, r, weights=weights))
    t["articulate_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    with stage_run("complete", dst.stage_dir("complete"), seed=0) as r:
        cm = run_complete(cc, cap, CompleteInputs(dst.parts, src.mesh, src.decompose, src.field, None), r,
                          sim.densities.part)
        r.metrics.update(cm)
    t["complete_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    with stage_run("twin", dst.stage_dir("twin"), seed=0) as r:
        tm = run_twin(tc, sim, cap, dst.parts, dst.stage_dir("complete"), r)
        r.metrics.update(tm)
    t["twin_s"] = time.perf_counter() - t0
    checks = json.loads((dst.stage_dir("twin") / "checks.json").read_text())
    twin = json.loads((dst.stage_dir("twin") / "twin.json").read_text())
    parts = checks.get("parts", {})
    return {"kitchen": src.scene, "n_parts": len(parts), "failures": checks.get("failures", []),
            "pull_opened": sum(v.get("pull_time_to_open_s") is not None for v in parts.values()),
            "n_stopped": sum(v.get("stopped_by") is not None for v in parts.values()),
            "n_repairs_part_part": sum(r["action"] == "carved" for r in checks.get("repairs", []) if "other" in r),
            "n_repairs_static": sum(r["action"] in ("carved", "removed") for r in checks.get("repairs", [])
                                    if "other" not in r),
            "n_handle_boxes": cm.get("n_handle_boxes"), "n_static_boxes": cm.get("n_static_boxes"),
            "grasp": dict(Counter(p["grasp"]["kind"] for p in twin["parts"] if p.get("grasp"))),
            "sim_realtime_factor": checks.get("sim_realtime_factor"), **t}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("-S", dest="set", action="append", default=[], help="params override key=value (repeatable)")
    ap.add_argument("--split", default="test", choices=("train", "test"))
    ap.add_argument("--bench", type=Path, default=None, help="the benchmark's folder (default: paths.bench)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--kitchens", type=int, nargs="*", default=None, help="a subset of the split's kitchens")
    a = ap.parse_args()
    p = yaml.safe_load((ROOT / "params.yaml").read_text())
    p["twin"]["recording"]["enabled"] = False  # the shareable page: not what this measures
    p["twin"]["renders"]["max_views"] = 1
    p["twin"]["renders"]["lpips"] = False
    for s in a.set:
        override(p, s)
    bc = to_typed(BenchConfig, p["bench"], "bench")
    kitchens = bc.kitchens if a.kitchens is None else a.kitchens
    bench = BenchPaths(a.bench or ROOT / p["paths"]["bench"])
    ac = to_typed(ArticulateConfig, p["articulate"], "articulate")
    weights = resolve_weights(ac.types, bench.weights)
    for k in kitchens:
        if not bench.kitchen(a.split, k).file("decompose", "segments").is_file():
            raise InputError(f"{bench.kitchen(a.split, k).root}: no decompose output (run the benchmark first)")
    t0 = time.perf_counter()
    rows = Parallel(n_jobs=a.jobs)(
        delayed(build)(p, bench.kitchen(a.split, k), ScenePaths(a.out / a.split, bench.kitchen(a.split, k).scene),
                       weights) for k in kitchens)
    by_check = Counter(f["check"] for r in rows for f in r["failures"])
    n_parts = sum(r["n_parts"] for r in rows)
    summary = {
        "overrides": a.set, "split": a.split, "n_kitchens": len(rows),
        "twins_passing": sum(not r["failures"] for r in rows), "failures_by_check": dict(by_check),
        "n_parts": n_parts, "pull_opened": sum(r["pull_opened"] for r in rows),
        "n_stopped": sum(r["n_stopped"] for r in rows),
        "n_repairs_part_part": sum(r["n_repairs_part_part"] for r in rows),
        "n_repairs_static": sum(r["n_repairs_static"] for r in rows),
        "n_handle_boxes": sum(r["n_handle_boxes"] or 0 for r in rows),
        "grasp": dict(sum((Counter(r["grasp"]) for r in rows), Counter())),
        "n_static_boxes_median": sorted(r["n_static_boxes"] for r in rows)[len(rows) // 2],
        "sim_realtime_factor_min": min(r["sim_realtime_factor"] or 0 for r in rows),
        "wall_s": time.perf_counter() - t0, "kitchens": rows}
    print(f"\n{' '.join(a.set) or '(params.yaml as it is)'}: {a.split} split\n")
    print("| kitchen | parts | checks failed | pull opens (as loaded) | handle boxes | static boxes | real-time factor |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        f = ", ".join(f"{x['id']}:{x['check']}" for x in r["failures"]) or "–"
        print(f"| {r['kitchen']} | {r['n_parts']} | {f} | {r['pull_opened']} / {r['n_parts']} | "
              f"{r['n_handle_boxes']} | {r['n_static_boxes']} | {r['sim_realtime_factor']:.1f} |")
    print(f"\ntwins passing every check: {summary['twins_passing']} / {len(rows)}; failures by check: "
          f"{dict(by_check) or 'none'}; pulled open as loaded: {summary['pull_opened']} / {n_parts}; handle boxes "
          f"{summary['n_handle_boxes']}; grasps {summary['grasp']}; parts stopped by a neighbour or the carcass "
          f"before their limit {summary['n_stopped']}; overlaps repaired part-part {summary['n_repairs_part_part']}, "
          f"part-static {summary['n_repairs_static']}")
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(f"{summary['wall_s']:.0f} s; {a.out / 'summary.json'}")


if __name__ == "__main__":
    main()
