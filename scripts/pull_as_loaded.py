#!/usr/bin/env python
"""A person's pull on every part of a twin's ``scene.xml`` exactly as the file loads: 20 N
along a drawer's axis, 10 N·m about a hinge (``sim.checks.pull_force`` / ``pull_torque``) for
3 s from rest, as the twin's checks do. Prints per part how far it opened and whether it
reached 90 % of its range, and the count; ``--drives on`` turns the drives on first (what a
twin whose drives act as it loads gives).

    python scripts/pull_as_loaded.py out/kitchen_small/twin [--drives on|as-loaded] [--json out.json]
"""

import argparse
import json
from pathlib import Path

import mujoco

from drawer_lib.errors import InputError
from drawer_lib.sim.checks import pull
from drawer_lib.sim.config import SimConfig
from drawer_lib.sim.mjcf import SCENE, drives_on, part_index, set_drives


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("twin", type=Path, help="a twin folder (scene.xml, twin.json)")
    ap.add_argument("--drives", choices=("as-loaded", "on"), default="as-loaded")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    xml = a.twin / SCENE
    if not xml.is_file():
        raise SystemExit(f"{xml}: missing (run the twin stage first)")
    try:
        m = mujoco.MjModel.from_xml_path(str(xml))
    except ValueError as e:
        raise InputError(f"{xml}: MuJoCo cannot load it ({e})") from e
    if a.drives == "on":
        set_drives(m, True)
    c = SimConfig().checks
    parts = [p for p in json.loads((a.twin / "twin.json").read_text())["parts"] if p["kind"] != "rigid"]
    rows = []
    for p in parts:
        ix = part_index(m, p["id"])
        revolute = p["kind"] == "revolute"
        lo, hi = (float(x) for x in m.jnt_range[ix["joint"]])
        q, _ = pull(m, ix, c.pull_torque if revolute else c.pull_force, c.open_time)
        frac = (float(q.max()) - lo) / (hi - lo)
        rows.append({"id": p["id"], "kind": p["kind"], "opened_fraction": round(frac, 4),
                     "opened": frac >= c.pull_fraction})
        print(f"{p['id']:>12} {p['kind']:>9}: {frac:6.1%} of its range in {c.open_time:g} s")
    n = sum(r["opened"] for r in rows)
    print(f"\n{xml} (drives {'on' if drives_on(m) else 'off'}): {n} of {len(rows)} parts opened to "
          f">= {c.pull_fraction:.0%} by a {c.pull_force:g} N / {c.pull_torque:g} N·m pull in {c.open_time:g} s")
    if a.json:
        a.json.write_text(json.dumps({"scene": str(xml), "drives_on": drives_on(m), "opened": n, "total": len(rows),
                                      "parts": rows}, indent=1))


if __name__ == "__main__":
    main()
