#!/usr/bin/env python
"""Profile one DVC stage in place: runs the stage's own ``cmd`` (read from dvc.yaml through DVC,
so the profile is of exactly what ``dvc repro`` runs) under cProfile (``python -m cProfile -m
stages.<name>`` in the project root), prints the stage's wall time and its top functions by own
and by cumulative time, and keeps the raw profile (``--out``, for snakeviz / ``pstats``).

The stage writes its outputs where it always does. Afterwards they are restored from the DVC
cache (``dvc checkout``) unless ``--keep``, so the workspace stays what ``dvc.lock`` records
(``metrics.json`` holds a wall time, which a profile run changes). The stage must be up to date
before (``dvc repro <target>``), otherwise there is nothing to restore.

    python scripts/profile_stage.py mesh@kitchen_small [--top 30] [--out /tmp/profiles] [--keep]
    python scripts/profile_stage.py sdf@kitchen_small sdf.neural.steps=200   # Hydra overrides
    python scripts/profile_stage.py geometry@kitchen_small-neural_mono --cmd 0 sdf.neural.steps=100

Only the stage's main thread is profiled; time spent in numba's or torch's worker threads shows up as the
call that launched them. Numba compiles on the first call of a kernel in a fresh process (cached
on disk afterwards): run twice when compile time would blur the picture.
"""

import argparse
import io
import os
import pstats
import shlex
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def stage_cmd(target: str, k: int | None) -> list[str]:
    """argv of ``target``'s cmd (``python -m <module> args...``) as DVC resolves it; command
    ``k`` of a stage with a list of commands."""
    from dvc.repo import Repo

    with Repo(str(ROOT)) as repo:
        stages = repo.stage.collect(target)
        if len(stages) != 1:
            raise SystemExit(f"{target}: names {len(stages)} stages; name one (e.g. mesh@kitchen_small)")
        cmd = stages[0].cmd
    if not isinstance(cmd, str):
        if k is None or not 0 <= k < len(cmd):
            raise SystemExit(f"{target}: cmd is a list of {len(cmd)} commands ({cmd}); choose one with --cmd K")
        cmd = cmd[k]
    argv = shlex.split(cmd)
    if len(argv) < 3 or argv[0] != "python" or argv[1] != "-m":
        raise SystemExit(f"{target}: cmd {cmd!r} is not `python -m <module> ...`; cannot profile it in process")
    return argv[2:]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("target", help="a stage as `dvc repro` names it, e.g. sdf@kitchen_small")
    ap.add_argument("overrides", nargs="*", help="Hydra overrides appended to the stage's command "
                    "(a shorter run; the outputs are restored afterwards either way)")
    ap.add_argument("--cmd", type=int, help="which command of a stage whose cmd is a list (0-based)")
    ap.add_argument("--top", type=int, default=30, help="rows of each table")
    ap.add_argument("--out", type=Path, default=Path("/tmp/profiles"), help="where <target>.prof goes")
    ap.add_argument("--keep", action="store_true", help="keep the profile run's outputs (no dvc checkout)")
    args = ap.parse_intermixed_args()

    module, *stage_args = stage_cmd(args.target, args.cmd)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"{args.target.replace('/', '_')}.prof"
    t0 = time.perf_counter()
    code = subprocess.run([sys.executable, "-m", "cProfile", "-o", str(path), "-m", module, *stage_args,
                           *args.overrides], cwd=ROOT).returncode
    wall = time.perf_counter() - t0
    for key in ("tottime", "cumulative"):
        buf = io.StringIO()
        pstats.Stats(str(path), stream=buf).strip_dirs().sort_stats(key).print_stats(args.top)
        body = buf.getvalue()
        print(f"\n== {args.target}: top {args.top} by {key} ==\n" + body[body.find("   ncalls"):])
    print(f"{args.target}: {wall:.1f} s under the profiler (exit {code}); profile in {path}")
    if not args.keep:
        env = {**os.environ, "PATH": f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}"}
        r = subprocess.run(["dvc", "checkout", "-f", args.target], cwd=ROOT, env=env, capture_output=True, text=True)
        print(f"dvc checkout -f {args.target}: {'restored' if r.returncode == 0 else r.stderr.strip()}")
    sys.exit(code)


if __name__ == "__main__":
    main()
