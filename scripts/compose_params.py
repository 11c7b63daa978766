#!/usr/bin/env python
"""Write params.yaml from conf/ (what `dvc exp run` does), or check it is up to date.

    python scripts/compose_params.py                 # write params.yaml
    python scripts/compose_params.py --check         # exit 1 with a diff when params.yaml is stale
    python scripts/compose_params.py 'scenes=[kitchen_tiny]' capture/detections=perfect   # overrides
"""

import argparse
import sys
from pathlib import Path

from drawer_lib.config.compose import compose_if_changed, params_diff

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("overrides", nargs="*", help="Hydra overrides, as for `dvc exp run -S`")
    ap.add_argument("--check", action="store_true", help="only check that params.yaml is up to date")
    ap.add_argument("--out", type=Path, default=ROOT / "params.yaml")
    a = ap.parse_args()
    if a.check:
        diff = params_diff(ROOT / "conf", a.out, a.overrides)
        if diff:
            sys.stdout.write(diff)
            print(f"\n{a.out} is out of date with conf/: run `python scripts/compose_params.py`", file=sys.stderr)
            return 1
        print(f"{a.out} is up to date with conf/")
        return 0
    stamp = ROOT / ".dvc" / "tmp" / f"compose_params-{a.out.name}.json"
    if compose_if_changed(ROOT / "conf", a.out, stamp, a.overrides):
        print(f"wrote {a.out}")
    else:
        print(f"{a.out} is up to date with conf/ (nothing changed since it was written)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
