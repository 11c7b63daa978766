#!/usr/bin/env python
"""CI's metric dashboard (drawer_lib/report/ci.py): after `dvc repro` of the quick experiment,
print the headline metrics against the committed baseline, write `reports/ci/dashboard.md` and
copy the report page there; exit 1 when a gated metric regressed beyond its tolerance.

    python scripts/compose_params.py experiment=quick && dvc repro
    python scripts/ci_dashboard.py                        # compare with .ci/baseline_quick.json
    python scripts/ci_dashboard.py --write-baseline       # accept this run as the new baseline
"""

import argparse
import json
import shutil
import sys
from pathlib import Path

import yaml


from drawer_lib.paths import LAYOUT
from drawer_lib.report.ci import dashboard, headline

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", type=Path, default=ROOT / ".ci" / "baseline_quick.json")
    ap.add_argument("--params", type=Path, default=ROOT / "params.yaml")
    ap.add_argument("--write-baseline", action="store_true")
    a = ap.parse_args()
    p = yaml.safe_load(a.params.read_text())
    out, reports = ROOT / p["paths"]["out"], ROOT / p["paths"]["reports"]
    now = headline(out, p["scenes"], p["appearance_variants"], p["geometry_variants"])
    if not now:
        print(f"error: no metrics under {out}/ for {p['scenes']} (run dvc repro first)", file=sys.stderr)
        return 2
    if a.write_baseline:
        a.baseline.write_text(json.dumps(now, indent=1, sort_keys=True) + "\n")
        print(f"wrote {a.baseline} ({len(now)} metrics)")
        return 0
    base = json.loads(a.baseline.read_text()) if a.baseline.is_file() else {}
    md, bad = dashboard(now, base, f"Pipeline on {', '.join(p['scenes'])} (study: {p.get('study')}) "
                                   f"against {a.baseline.name}")
    ci = reports / "ci"
    ci.mkdir(parents=True, exist_ok=True)
    (ci / "dashboard.md").write_text(md)
    page = reports / LAYOUT["report"]["index"]
    if page.is_file():
        shutil.copy2(page, ci / "index.html")
    print(md)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
