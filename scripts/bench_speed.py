#!/usr/bin/env python
"""The speed figures of the pipeline, each measured side by side for the code now and for a
reference commit (default: the code before the speed work), in one run, alternating
reference / now so that the machine's noise hits both alike.

The reference is a ``git worktree`` of ``--ref`` (made under ``--ref-dir`` once, reused); every
figure runs in a fresh subprocess with that tree first on ``sys.path``, the same thread count
and the same inputs (the default scene's outputs in ``out/``: ``dvc repro`` first). Outputs go
to a scratch directory, never to ``out/``.

Figures (``--only`` picks some):

- ``noop``: a no-op ``dvc repro`` of the workspace (the reference column is the same DVC with
  ruamel's pure-Python YAML parser, i.e. without ``ruamel.yaml.clib``);
- ``raster``: ``scripts/bench_splat.py`` (forward + backward vs gsplat's pure-PyTorch path) at
  20k Gaussians, 128x96 and 256x192, from each tree;
- ``step``: ms per training step of the paper's method (movable_gs_ste) once density control has
  grown the Gaussians to their cap (~50k on kitchen_small, 200x150), mean of the last 100 of 300
  steps;
- ``mesh``: the ``mesh`` stage on the ``sdf`` stage's field (wall time, and the mesh's F@2cm);
- ``sdf``: training seconds until the quick mesh's F@2cm reaches 0.95 (eval every 50 steps;
  the stage's own curve evaluates every 250), and the stage's wall time to that point;
- ``sdf4x``: the same on a capture of the scene with 4x the pixels (400x300; now only: the
  capture is rendered once into the scratch directory).

    python scripts/bench_speed.py [--ref e1246f9] [--only noop step mesh] [--threads 2]
"""

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REF = "e1246f9"  # the code before the speed work (docs/speed.md)
SCENE = "kitchen_small"
FIGURES = ("noop", "raster", "step", "mesh", "sdf", "sdf4x")


def sh(cmd: list[str], cwd: Path, env: dict | None = None, check: bool = True) -> subprocess.CompletedProcess:
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    if check and r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} (in {cwd}) failed with exit {r.returncode}:\n{r.stderr[-3000:]}")
    return r


def worktree(ref: str, where: Path) -> Path:
    """A detached worktree of ``ref`` at ``where`` (made once; reset to ``ref`` when it exists)."""
    if not (where / ".git").exists():
        sh(["git", "worktree", "add", "--detach", "--force", str(where), ref], ROOT)
    else:
        sh(["git", "checkout", "--detach", "--force", ref], where)
    return where


def env_for(tree: Path, threads: int) -> dict:
    t = str(threads)
    return {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": t, "MKL_NUM_THREADS": t,
            "NUMBA_NUM_THREADS": t, "PATH": f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}",
            "DVC_NO_ANALYTICS": "1"}


def py(tree: Path, code: str, threads: int) -> dict:
    """Run ``code`` in ``tree``; its last stdout line is a JSON object."""
    r = sh([sys.executable, "-c", code], tree, env_for(tree, threads))
    return json.loads(r.stdout.strip().splitlines()[-1])


def stage(tree: Path, module: str, overrides: list[str], threads: int) -> float:
    """Wall seconds of ``python -m <module> -cn dvc_stage scene=... <overrides>`` in ``tree``."""
    t0 = time.perf_counter()
    sh([sys.executable, "-m", module, "-cn", "dvc_stage", f"scene={SCENE}", *overrides], tree, env_for(tree, threads))
    return time.perf_counter() - t0


def scratch_scene(base: Path, links: list[str]) -> Path:
    """``base/<scene>`` with symlinks to the workspace's ``out/<scene>/<name>`` for ``links``
    (those the workspace has)."""
    d = base / SCENE
    d.mkdir(parents=True, exist_ok=True)
    for name in links:
        if not (d / name).exists() and (ROOT / "out" / SCENE / name).exists():
            (d / name).symlink_to(ROOT / "out" / SCENE / name)
    return base


def row(name: str, ref, now, unit: str, target: str = "") -> None:
    f = lambda v: f"{v:.3g}" if isinstance(v, float) else str(v)  # noqa: E731
    ratio = f"{ref / now:.2f}x" if isinstance(ref, float) and isinstance(now, float) and now > 0 else ""
    print(f"{name:<44} {f(ref):>12} {f(now):>12} {unit:<8} {ratio:>7}  {target}", flush=True)


# ---------------------------------------------------------------- figures


def fig_noop(trees: dict, threads: int) -> None:
    r = sh(["dvc", "status", "-q"], ROOT, env_for(ROOT, threads), check=False)
    if r.returncode != 0 or r.stdout.strip():
        print("noop: skipped, the workspace is not up to date (`dvc repro` first)")
        return
    pure = "import sys; sys.modules['_ruamel_yaml'] = None; from dvc.cli import main; sys.exit(main(['repro', '-q']))"
    fast = "import sys; from dvc.cli import main; sys.exit(main(['repro', '-q']))"
    ts = {"ref": [], "now": []}
    for _ in range(3):
        for k, code in (("ref", pure), ("now", fast)):
            t0 = time.perf_counter()
            sh([sys.executable, "-c", code], ROOT, env_for(ROOT, threads))
            ts[k].append(time.perf_counter() - t0)
    row("no-op dvc repro (median of 3)", statistics.median(ts["ref"]), statistics.median(ts["now"]), "s", "<= 2 s")


def fig_raster(trees: dict, threads: int) -> None:
    for k, tree in trees.items():
        r = sh([sys.executable, str(tree / "scripts/bench_splat.py"), "--counts", "20000", "--sizes", "128x96",
                "256x192"], tree, env_for(tree, threads))
        print(f"-- bench_splat.py, {k} ({tree}); target >= 8x at 128x96, >= 10x at 256x192")
        print("\n".join(line for line in r.stdout.splitlines() if line.strip()), flush=True)




def fig_step(trees: dict, threads: int) -> None:
    from bench_step_ab import step_code  # the same run as the A/B script's (this file's folder is on sys.path)

    res = {k: py(tree, step_code(ROOT, tree / "conf", SCENE, "movable_gs_ste", 300, 100), threads)
           for k, tree in trees.items()}  # each tree with its own config schema
    row(f"train step, movable_gs_ste ({res['now']['n']} Gaussians)", res["ref"]["mean"], res["now"]["mean"], "ms",
        "<= 80 ms")


def fig_mesh(trees: dict, threads: int, tmp: Path) -> None:
    walls, fs = {}, {}
    for k, tree in trees.items():
        out = scratch_scene(tmp / f"mesh_{k}", ["capture", "sdf"])
        walls[k] = stage(tree, "stages.mesh", [f"paths.out={out}"], threads)
        fs[k] = float(json.loads((out / SCENE / "mesh" / "metrics.json").read_text())["fscore_2cm"])
    row("mesh stage wall", walls["ref"], walls["now"], "s", "<= 15 s")
    row("mesh stage F@2cm (same field)", fs["ref"], fs["now"], "")


def _time_to(curve: Path, key: str = "fscore_2cm", level: float = 0.95) -> tuple[float, int]:
    with open(curve) as f:
        for r in csv.DictReader(f):
            if r[key] not in ("", "nan") and float(r[key]) >= level:
                return float(r["wall_s"]), int(r["step"])
    return float("nan"), -1


def fig_sdf(trees: dict, threads: int, tmp: Path, steps: int = 400) -> None:
    res = {}
    for k, tree in trees.items():
        out = scratch_scene(tmp / f"sdf_{k}", ["capture", "priors"])  # (the reference commit reads no priors/)
        wall = stage(tree, "stages.sdf", [f"paths.out={out}", f"sdf.neural.steps={steps}", "sdf.neural.eval_every=50"],
                     threads)
        res[k] = (*_time_to(out / SCENE / "sdf" / "curve.csv"), wall)
    row(f"sdf: training s to F@2cm 0.95 (step {res['now'][1]})", res["ref"][0], res["now"][0], "s", "<= 60 s")
    row(f"sdf: stage wall for {steps} steps, evals every 50", res["ref"][2], res["now"][2], "s")


def fig_sdf4x(trees: dict, threads: int, tmp: Path) -> None:
    out = tmp / "sdf4x"
    cam = ["scene.synth.camera.width=400", "scene.synth.camera.height=300"]
    if not (out / SCENE / "capture" / "transforms.json").is_file():
        stage(ROOT, "stages.capture", [f"paths.out={out}", *cam], threads)
        stage(ROOT, "stages.priors", [f"paths.out={out}", *cam], threads)
    wall = stage(ROOT, "stages.sdf", [f"paths.out={out}", *cam, "sdf.neural.eval_every=50"], threads)
    t, step = _time_to(out / SCENE / "sdf" / "curve.csv")
    m = json.loads((out / SCENE / "sdf" / "metrics.json").read_text())
    row(f"sdf, 400x300 capture: training s to F@2cm 0.95 (step {step})", "-", t, "s", "<= 240 s")
    row(f"sdf, 400x300 capture: stage wall ({m['steps']} steps)", "-", wall, "s",
        f"F@2cm {m['quick_fscore_2cm']:.3f}, chamfer {1000 * m['quick_chamfer_l1']:.2f} mm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ref", default=REF, help="the reference commit")
    ap.add_argument("--ref-dir", type=Path, default=Path("/tmp/drawer_bench_ref"))
    ap.add_argument("--tmp", type=Path, default=Path("/tmp/drawer_bench_speed"), help="scratch outputs")
    ap.add_argument("--only", nargs="+", choices=FIGURES, default=list(FIGURES))
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 2)
    args = ap.parse_args()
    if not (ROOT / "out" / SCENE / "sdf").is_dir():
        raise SystemExit(f"out/{SCENE}: missing; run `dvc repro` first (the figures reuse its capture, field and mesh)")
    trees = {"ref": worktree(args.ref, args.ref_dir), "now": ROOT}
    args.tmp.mkdir(parents=True, exist_ok=True)
    print(f"reference {args.ref} in {args.ref_dir}; now = {ROOT}; {args.threads} threads\n")
    print(f"{'figure':<44} {'reference':>12} {'now':>12} {'unit':<8} {'ratio':>7}  target")
    for name in args.only:
        if name == "noop":
            fig_noop(trees, args.threads)
        elif name == "raster":
            fig_raster(trees, args.threads)
        elif name == "step":
            fig_step(trees, args.threads)
        elif name == "mesh":
            fig_mesh(trees, args.threads, args.tmp)
        elif name == "sdf":
            fig_sdf(trees, args.threads, args.tmp)
        elif name == "sdf4x":
            fig_sdf4x(trees, args.threads, args.tmp)


if __name__ == "__main__":
    main()
