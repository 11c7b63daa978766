#!/usr/bin/env python
"""The README's results table from the tracked metrics of the last run (drawer_lib/report/results.py):
print it, or with ``--write`` replace the README's results block.

    make run && python scripts/readme_results.py --write
"""

import argparse
from pathlib import Path

import yaml

from drawer_lib.report.results import Run, replace_block, results_block, seed_runs

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="replace the block in README.md")
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--no-seeds", action="store_true", help="leave out the spread over the seed experiments")
    a = ap.parse_args()
    p = yaml.safe_load((ROOT / "params.yaml").read_text())
    run = Run(ROOT, ROOT / p["paths"]["out"], ROOT / p["paths"]["reports"], ROOT / p["paths"]["bench"], a.scene)
    seeds = [] if a.no_seeds else seed_runs(run, p)
    block = results_block(run, p["appearance_variants"], p["geometry_variants"], seeds, p["seed"])
    if a.write:
        readme = ROOT / "README.md"
        readme.write_text(replace_block(readme.read_text(), block))
        print(f"wrote the results block of {readme}")
    else:
        print(block)


if __name__ == "__main__":
    main()
