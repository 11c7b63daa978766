#!/usr/bin/env python
"""Benchmark of the capture stage: wall time and peak memory per scene, and the time of a no-op
`dvc repro`. Run from the project root with the virtual environment active (`make bench-capture`).

    python scripts/bench_capture.py                         # kitchen_small
    python scripts/bench_capture.py kitchen_small kitchen_medium kitchen_large --repeat 3
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run(cmd, **kw):
    t = time.perf_counter()
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{r.stderr[-3000:]}")
    return time.perf_counter() - t, r


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=["kitchen_small"])
    ap.add_argument("--repeat", type=int, default=1, help="capture runs per scene (the median is reported)")
    ap.add_argument("--noop", type=int, default=5, help="no-op `dvc repro` runs")
    a = ap.parse_args()
    env = dict(os.environ)
    print(f"{'scene':<16} {'frames':>6} {'size':>9} {'stage wall s':>12} {'process s':>10} {'peak MiB':>9}")
    with tempfile.TemporaryDirectory(prefix="bench_capture_") as tmp:
        for scene in a.scenes:
            walls, procs, peaks = [], [], []
            for k in range(a.repeat):
                out = Path(tmp) / f"r{k}"
                dt, _ = run([sys.executable, "-m", "stages.capture", f"scene={scene}", f"paths.out={out}"], env=env)
                m = json.loads((out / scene / "capture" / "metrics.json").read_text())
                man = json.loads((out / scene / "capture" / "manifest.json").read_text())
                walls.append(m["wall_s"]), procs.append(dt), peaks.append(m["peak_rss_mb"])
            w, h = man["image_size"]
            print(f"{scene:<16} {m['n_frames']:>6} {f'{w}x{h}':>9} {statistics.median(walls):>12.2f} "
                  f"{statistics.median(procs):>10.2f} {max(peaks):>9.0f}")
    run(["dvc", "repro"], env=env)  # bring the workspace up to date first
    times = [run(["dvc", "repro"], env=env)[0] for _ in range(a.noop)]
    print(f"no-op `dvc repro` ({a.noop} runs): median {statistics.median(times):.2f} s, "
          f"min {min(times):.2f} s, max {max(times):.2f} s")


if __name__ == "__main__":
    main()
