#!/usr/bin/env python
"""``dvc repro`` with independent stages side by side on the cores (what ``make run`` calls).

Plans the out-of-date stages with one ``dvc status`` and runs each as its own
``dvc repro --single-item`` once what it needs has finished, ``--jobs`` at a time with
``--threads`` threads each (default cores // jobs; the thread count is part of a result, so it
never depends on timing). Logs per stage in ``logs/repro/``. See drawer_lib/schedule.py.

    python scripts/repro.py [--jobs 2] [--threads N] [--dry] [--force] [--launcher CMD] [stage ...]
    python scripts/repro.py --jobs 16 --launcher "srun --partition=cpu --cpus-per-task=1" fit_decisions bench_eval
"""

import argparse
import shlex
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stages", nargs="*", help="only these stages and what they need (default: all)")
    ap.add_argument("--jobs", type=int, default=2, help="stages at once (default 2)")
    ap.add_argument("--threads", type=int, default=None, help="threads per stage (default: cores // jobs)")
    ap.add_argument("--dry", action="store_true", help="print the plan, run nothing")
    ap.add_argument("--force", action="store_true", help="run every stage, restore none from the run-cache (dvc repro -f)")
    ap.add_argument("--log-dir", type=Path, default=ROOT / "logs" / "repro")
    ap.add_argument("--launcher", default="", help="a command each stage runs under, e.g. 'srun --partition=cpu "
                    "--cpus-per-task=1' (a SLURM cluster sharing this workspace; see docs/sweeps.md)")
    args = ap.parse_args()
    if args.jobs < 1 or (args.threads is not None and args.threads < 1):
        ap.error("--jobs and --threads must be at least 1")
    from drawer_lib.schedule import repro

    try:
        return repro(ROOT, jobs=args.jobs, threads=args.threads, targets=args.stages or None,
                     log_dir=args.log_dir, dry=args.dry, force=args.force, report=lambda m: print(m, flush=True),
                     launcher=shlex.split(args.launcher) or None)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
