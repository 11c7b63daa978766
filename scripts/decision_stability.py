#!/usr/bin/env python
"""Do a scene's kinds and hinge sides hold when its mesh moves by fractions of a millimetre (what
another machine, SDF seed or thread count changes)? Articulates the scene again on its own
decompose output with the mesh's vertices jittered (drawer_lib/articulation/robustness.py) and
prints, per part, its kind, margin and how many runs kept it.

    python scripts/decision_stability.py [--scene kitchen_small] [--sigmas 0.0003 0.001] [--runs 3]
"""

import argparse
import json
from pathlib import Path

import yaml

from drawer_lib.articulation.robustness import jitter_run
from drawer_lib.articulation.weights import resolve_weights
from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.articulation import compare_parts
from drawer_lib.paths import BenchPaths, ScenePaths

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--sigmas", type=float, nargs="+", default=[0.0003, 0.001], help="vertex noise (m)")
    ap.add_argument("--runs", type=int, default=3, help="jittered runs per sigma")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    a = ap.parse_args()
    p = yaml.safe_load((ROOT / "params.yaml").read_text())
    cfg = to_typed(ArticulateConfig, p["articulate"], "articulate")
    sp = ScenePaths(ROOT / p["paths"]["out"], a.scene)
    cap = load_capture(sp.capture, check_files=False)
    weights = resolve_weights(cfg.types, BenchPaths(ROOT / p["paths"]["bench"]).weights)
    ref = read_parts(sp.parts)
    kept: dict[str, list[bool]] = {}
    rows = {}
    for sigma in a.sigmas:
        for k in range(a.runs):
            for r in compare_parts(ref, jitter_run(cfg, cap, sp.decompose, weights, sigma, seed=k)):
                rows[r["part"]] = r
                kept.setdefault(r["part"], []).append(r["kept"])
                if not r["kept"]:
                    print(f"sigma {sigma * 1000:.1f} mm run {k}: {r['part']} {r['kind']} -> {r['now']}")
    print(f"\n{a.scene}: {len(a.sigmas)} sigmas x {a.runs} runs (mm: {[s * 1000 for s in a.sigmas]})")
    print("| part | kind | margin | runs that kept it |\n|---|---|---|---|")
    for pid, r in rows.items():
        m = r["margin"]
        print(f"| {pid} | {r['kind']} | {'–' if m is None else f'{m:.2f}'} | {sum(kept[pid])} / {len(kept[pid])} |")
    flips = sum(not x for v in kept.values() for x in v)
    print(f"\nflips: {flips} of {sum(len(v) for v in kept.values())} part-runs")
    if a.json:
        a.json.write_text(json.dumps({"sigmas": a.sigmas, "runs": a.runs, "flips": flips,
                                      "parts": [{**r, "kept_runs": sum(kept[p]), "n_runs": len(kept[p])}
                                                for p, r in rows.items()]}, indent=1))


if __name__ == "__main__":
    main()
