#!/usr/bin/env python
"""The robot stage on every twin of a benchmark split that ``scripts/bench_twin.py`` built: the
Panda opens and closes each part in the twin, puts a block from the counter into an opened
drawer (``robot.pick_place``), and each demonstration is replayed in the kitchen's own model
(its ground truth). Reports success in the twin and after transfer, per task and per part kind
(GT kind of the matched part, or the twin's kind when unmatched), and the failure reasons.

    python scripts/bench_twin.py --out /tmp/bench_twin/default       # the twins first
    python scripts/bench_robot.py --twins /tmp/bench_twin/default --out /tmp/bench_robot
    python scripts/bench_robot.py --twins /tmp/bench_twin/default --out /tmp/bench_pick \
        -S robot.max_parts=0 -S robot.pick_place.max_drawers=3      # pick and place alone

Writes ``<out>/summary.json`` (and each kitchen's robot folder, ``--camera`` to record images)
and prints the tables.
"""

import argparse
import json
import time
from collections import Counter, defaultdict
from pathlib import Path

import yaml
from joblib import Parallel, delayed

import drawer_lib.synth.gl  # noqa: F401  (MuJoCo reads MUJOCO_GL once, at import)
from drawer_lib.bench.config import BenchConfig
from drawer_lib.bench.kitchens import kitchen_scene
from drawer_lib.config.compose import set_param
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.paths import ScenePaths
from drawer_lib.robot.pipeline import run_robot, scene_ground_truth
from drawer_lib.robot.plan import RobotConfig
from drawer_lib.runner import stage_run
from drawer_lib.sim.config import SimConfig

ROOT = Path(__file__).resolve().parent.parent


def one(p: dict, split: str, k: int, twins: ScenePaths, out: ScenePaths) -> dict:
    rc = to_typed(RobotConfig, p["robot"], "robot")
    sim = to_typed(SimConfig, p["sim"], "sim")
    bc = to_typed(BenchConfig, p["bench"], "bench")
    base = yaml.safe_load((ROOT / "conf" / "scene" / f"{bc.base_scene}.yaml").read_text())
    gt = scene_ground_truth(kitchen_scene(base, split, k, bc.camera), sim)
    with stage_run("robot", out.stage_dir("robot"), seed=0) as run:
        m = run_robot(rc, twins.stage_dir("twin"), twins.parts, run, None, gt)
        run.metrics.update(m)
    attempts = json.loads(out.file("robot", "attempts").read_text())
    return {"kitchen": twins.scene, "metrics": m, "attempts": attempts["parts"],
            "pick_place": attempts.get("pick_place", [])}


def _pick_summary(xs: list[dict]) -> dict:
    """Pick-and-place demonstrations pooled: how many, placed in the twin and after transfer, why not."""
    tr = [x.get("transfer", {"placed": False, "reason": "failed in the twin"}) for x in xs]
    return {"n": len(xs), "twin": sum(x["twin"]["placed"] for x in xs), "transfer": sum(t["placed"] for t in tr),
            "twin_fail_reasons": dict(Counter(x["twin"]["reason"] for x in xs if x["twin"]["reason"])),
            "transfer_fail_reasons": dict(Counter(t["reason"] for t in tr if t["reason"]))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--twins", type=Path, required=True, help="bench_twin.py's --out")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--split", default="test", choices=("train", "test"))
    ap.add_argument("-S", dest="set", action="append", default=[], help="params override key=value (repeatable)")
    ap.add_argument("--camera", action="store_true", help="record the camera stream (off: faster)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--kitchens", type=int, nargs="*", default=None)
    a = ap.parse_args()
    p = yaml.safe_load((ROOT / "params.yaml").read_text())
    if not a.camera:
        p["robot"]["camera"] = [0, 0]
    for s in a.set:
        try:
            set_param(p, s)
        except ConfigError as e:
            raise SystemExit(str(e)) from None
    bc = to_typed(BenchConfig, p["bench"], "bench")
    kitchens = bc.kitchens if a.kitchens is None else a.kitchens
    todo = []
    for k in kitchens:
        tw = ScenePaths(a.twins / a.split, f"kitchen_{k}")
        if not tw.file("twin", "mjcf").is_file():
            raise InputError(f"{tw.stage_dir('twin')}: no twin (run scripts/bench_twin.py --out {a.twins} first)")
        todo.append((k, tw))
    t0 = time.perf_counter()
    rows = Parallel(n_jobs=a.jobs)(delayed(one)(p, a.split, k, tw, ScenePaths(a.out / a.split, tw.scene))
                                   for k, tw in todo)
    att = [x | {"kitchen": r["kitchen"]} for r in rows for x in r["attempts"]]
    by_kind: dict[str, Counter] = defaultdict(Counter)
    for x in att:
        kind = x.get("transfer", {}).get("gt_kind") or f"{x['kind']} (no GT match)"
        c = by_kind[kind]
        c["n"] += 1
        c["twin_open"] += x["twin"]["opened"]
        c["twin_close"] += x["twin"]["closed"]
        c["transfer_open"] += bool(x.get("transfer", {}).get("opened"))
    n = len(att)
    summary = {
        "split": a.split, "overrides": a.set, "n_kitchens": len(rows), "n_parts": n,
        "twin_open": sum(x["twin"]["opened"] for x in att), "twin_close": sum(x["twin"]["closed"] for x in att),
        "transfer_open": sum(bool(x.get("transfer", {}).get("opened")) for x in att),
        "twin_fail_reasons": dict(Counter(x["twin"]["reason"] for x in att if x["twin"]["reason"])),
        "transfer_fail_reasons": dict(Counter(x["transfer"]["reason"] for x in att
                                              if x.get("transfer", {}).get("reason"))),
        "by_gt_kind": {k: dict(v) for k, v in sorted(by_kind.items())},
        "dataset_episodes": sum(r["metrics"].get("dataset_episodes", 0) for r in rows),
        "dataset_frames": sum(r["metrics"].get("dataset_frames", 0) for r in rows),
        "pick_place": _pick_summary([x for r in rows for x in r["pick_place"]]),
        "robot_wall_s_per_kitchen": sorted(r["metrics"]["robot_plan_s"] + r["metrics"]["robot_sim_s"]
                                           + r["metrics"]["robot_transfer_s"] for r in rows),
        "wall_s": time.perf_counter() - t0, "kitchens": rows}
    print(f"\nrobot on the {a.split} split's twins ({len(rows)} kitchens, {n} parts)\n")
    print("| GT kind of the part | parts | opened in the twin | closed in the twin | opened after transfer |")
    print("|---|---|---|---|---|")
    for k, c in sorted(by_kind.items()):
        print(f"| {k} | {c['n']} | {c['twin_open']} | {c['twin_close']} | {c['transfer_open']} |")
    print(f"| all | {n} | {summary['twin_open']} | {summary['twin_close']} | {summary['transfer_open']} |")
    print(f"\nfailures in the twin: {summary['twin_fail_reasons']}")
    print(f"failures after transfer: {summary['transfer_fail_reasons']}")
    pk = summary["pick_place"]
    print(f"pick and place (a block from the counter into an opened drawer): {pk['n']} drawers, placed in the twin "
          f"{pk['twin']}, after transfer {pk['transfer']}; failures in the twin {pk['twin_fail_reasons']}, after "
          f"transfer {pk['transfer_fail_reasons']}")
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    print(f"{summary['wall_s']:.0f} s; {a.out / 'summary.json'}")


if __name__ == "__main__":
    main()
