#!/usr/bin/env python
"""ms per appearance training step, the code now against a reference tree, interleaved (A, B, A, B,
...) in one run so that the machine's load hits both alike.

Each run is a fresh subprocess with its tree first on ``sys.path`` and the given thread count:
it trains ``--variant`` on the default scene's capture and mesh (``out/<scene>``: ``dvc repro
mesh@<scene>`` first) for ``--steps`` steps with density control from step 0 (the Gaussians reach
their cap, ~50k on kitchen_small, within ~200 steps), times every step, and prints the mean and
the median of the last ``--last`` steps, the Gaussian count and a SHA-1 of the final parameters
(equal digests: the two trees trained to the same bits). The reference tree is a ``git worktree``
(``git worktree add /tmp/step_ref HEAD``).

    python scripts/bench_step_ab.py [--ref /tmp/step_ref] [--rounds 3] [--steps 300] [--last 100] [--threads 1]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

_RUN_CODE = """
import hashlib, json, statistics, sys, time
import drawer_lib  # first, as a stage imports it: the library's settings that must precede torch
import torch, trimesh
from hydra import compose, initialize_config_dir
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.splat.config import AppearanceConfig
from drawer_lib.splat.train import prepare, train_gaussians
with initialize_config_dir(config_dir='{conf}', version_base='1.3'):
    cfg = compose(config_name='config', overrides=['scene={scene}', 'appearance_variant={variant}',
                  'appearance.steps={steps}', 'appearance.eval_every=1000000', 'appearance.strategy.refine_start=0'])
app = to_typed(AppearanceConfig, cfg.appearance, 'appearance')
cap = load_capture('{root}/out/{scene}/capture')
sc = prepare(cap, trimesh.load('{root}/out/{scene}/mesh/mesh.ply', process=False), app)
stamps = []
def progress(it, **kw):
    for x in it:
        stamps.append(time.perf_counter())
        yield x
st = train_gaussians(cap, sc, app, 0, progress)
stamps.append(time.perf_counter())
dt = [1000 * (b - a) for a, b in zip(stamps[:-1], stamps[1:])][-{last}:]
h = hashlib.sha1()
for name, t in sorted(st.params.trainable().items()):
    h.update(t.detach().contiguous().numpy().tobytes())
print(json.dumps({{'mean': statistics.fmean(dt), 'median': statistics.median(dt), 'n': int(st.params.face.shape[0]),
                  'sha1': h.hexdigest()[:12]}}))
"""


def step_code(root: Path, conf: Path, scene: str, variant: str, steps: int, last: int) -> str:
    """Python source that trains ``variant`` on ``root``'s out/<scene> with the config schema of
    ``conf`` and prints one JSON line: mean / median ms of the last ``last`` steps, the Gaussian
    count ``n`` and a SHA-1 of the final parameters (also ``scripts/bench_speed.py``'s step figure)."""
    return _RUN_CODE.format(root=root, conf=conf, scene=scene, variant=variant, steps=steps, last=last)


def run(tree: Path, code: str, threads: int) -> dict:
    t = str(threads)
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": t, "MKL_NUM_THREADS": t, "NUMBA_NUM_THREADS": t}
    r = subprocess.run([sys.executable, "-c", code], cwd=tree, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"run in {tree} failed with exit {r.returncode}:\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ref", type=Path, default=Path("/tmp/step_ref"), help="the reference tree (a git worktree)")
    ap.add_argument("--now", type=Path, default=ROOT, help="the tree measured as 'now' (default: this working tree; "
                    "a copy lets the code be edited while the benchmark runs)")
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--variant", default="movable_gs_ste")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--last", type=int, default=100)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    for tree in (args.ref, args.now):
        if not (tree / "drawer_lib").is_dir() or not (tree / "conf").is_dir():
            raise SystemExit(f"{tree}: not a tree of this project (git worktree add {tree} HEAD)")
    if not (ROOT / "out" / args.scene / "mesh" / "mesh.ply").is_file():
        raise SystemExit(f"out/{args.scene}/mesh/mesh.ply: missing (dvc repro mesh@{args.scene} first)")
    trees = {"ref": args.ref.resolve(), "now": args.now.resolve()}
    codes = {k: step_code(ROOT, tree / "conf", args.scene, args.variant, args.steps, args.last)
             for k, tree in trees.items()}  # each tree with its own config schema
    res: dict[str, list[dict]] = {k: [] for k in trees}
    for i in range(args.rounds):
        for k, tree in trees.items():
            r = run(tree, codes[k], args.threads)
            res[k].append(r)
            print(f"round {i + 1} {k}: mean {r['mean']:.1f} ms, median {r['median']:.1f} ms, {r['n']} Gaussians, "
                  f"params {r['sha1']}", flush=True)
    med = {k: statistics.median(r["median"] for r in v) for k, v in res.items()}
    mean = {k: statistics.median(r["mean"] for r in v) for k, v in res.items()}
    same = {r["sha1"] for v in res.values() for r in v}
    print(f"{args.variant}, {args.threads} thread(s), last {args.last} of {args.steps} steps, median over "
          f"{args.rounds} rounds: ref {med['ref']:.1f} ms (mean {mean['ref']:.1f}), now {med['now']:.1f} ms "
          f"(mean {mean['now']:.1f}), {med['ref'] / med['now']:.2f}x; final parameters "
          f"{'identical' if len(same) == 1 else 'DIFFER: ' + ', '.join(sorted(same))}")


if __name__ == "__main__":
    main()
