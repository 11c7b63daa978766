#!/usr/bin/env python
"""Do a scene's kinds and hinge sides hold across SDF seeds and thread counts? Rebuilds the
geometry of the scene's own capture (sdf -> mesh -> decompose -> articulate, the pipeline's
stages and params.yaml) with other seeds and thread counts in a scratch folder, and compares
every run's parts with the pipeline's own (seed in params.yaml, the threads `make run` gave it)
part by part (drawer_lib/articulation/robustness.py).

    python scripts/sdf_seed_stability.py [--scene kitchen_small] [--runs 1:1 2:1 0:2] [--json out.json] [--reuse]

A run is SEED:THREADS. Takes one SDF training per run (about 6 min each on this machine);
``--reuse`` keeps the geometry of an earlier call and articulates it again (after a change of
the articulation alone).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import yaml

from drawer_lib.metrics.articulation import compare_parts
from drawer_lib.io.parts import read_parts
from drawer_lib.paths import ScenePaths

ROOT = Path(__file__).resolve().parent.parent
STAGES = ("sdf", "mesh", "decompose", "articulate")


def rebuild(scene: str, seed: int, threads: int, work: Path, out: Path, reuse: bool = False) -> Path:
    """The scene's parts.json rebuilt from its capture with ``seed`` and ``threads`` under
    ``work`` (``reuse``: only articulate again, on the decompose output already there)."""
    root = work / f"seed{seed}_threads{threads}"
    src, dst = ScenePaths(out, scene), ScenePaths(root, scene)
    stages = STAGES
    if reuse and dst.stage_dir("decompose").is_dir():
        stages = ("articulate",)
    else:
        if root.exists():
            shutil.rmtree(root)
        dst.root.mkdir(parents=True)
        for d in (src.capture, src.detect, src.priors):  # the capture and what detect and priors give it
            (dst.root / d.name).symlink_to(d.resolve())
    env = {**os.environ, "OMP_NUM_THREADS": str(threads), "MKL_NUM_THREADS": str(threads),
           "NUMBA_NUM_THREADS": str(threads)}
    for st in stages:
        t = time.time()
        subprocess.run([sys.executable, "-m", f"stages.{st}", "-cn", "dvc_stage", f"scene={scene}", f"seed={seed}",
                        f"paths.out={root}"], cwd=ROOT, env=env, check=True, stdout=subprocess.DEVNULL)
        print(f"  seed {seed}, {threads} thread(s): {st} {time.time() - t:.0f} s", flush=True)
    return dst.parts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--runs", nargs="+", default=["1:1", "2:1", "0:2"], help="SEED:THREADS")
    ap.add_argument("--work", type=Path, default=Path("/tmp/drawer_sdf_seeds"))
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--reuse", action="store_true", help="articulate the geometry of an earlier call again")
    a = ap.parse_args()
    p = yaml.safe_load((ROOT / "params.yaml").read_text())
    out = ROOT / p["paths"]["out"]
    ref_path = ScenePaths(out, a.scene).parts
    ref = read_parts(ref_path)
    runs = {}
    for r in a.runs:
        seed, threads = (int(x) for x in r.split(":"))
        runs[r] = compare_parts(ref, read_parts(rebuild(a.scene, seed, threads, a.work, out, a.reuse)))
    parts = [row["part"] for row in next(iter(runs.values()))] if runs else []
    print(f"\n{a.scene}: the pipeline's parts (seed {p['seed']}) against rebuilds at SEED:THREADS\n")
    print("| part | kind | margin | " + " | ".join(runs) + " |\n|---|---|---|" + "---|" * len(runs))
    for i, pid in enumerate(parts):
        r0 = runs[a.runs[0]][i]
        m = r0["margin"]
        print(f"| {pid} | {r0['kind']} | {'–' if m is None else f'{m:.2f}'} | "
              + " | ".join("same" if rs[i]["kept"] else rs[i]["now"] for rs in runs.values()) + " |")
    flips = sum(not row["kept"] for rs in runs.values() for row in rs)
    print(f"\nchanged: {flips} of {len(parts) * len(runs)} part-runs")
    if a.json:
        a.json.write_text(json.dumps({"scene": a.scene, "reference_seed": p["seed"], "runs": runs, "changed": flips},
                                     indent=1))


if __name__ == "__main__":
    main()
