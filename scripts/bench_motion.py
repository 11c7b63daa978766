#!/usr/bin/env python
"""Benchmark of the simulated twin's motion (motion EMD, DESIGN §6) and its interaction probes
on procedural kitchens with noisy detections.

Per kitchen of ``--split`` (default ``test``: never tuned on), on the capture and TSDF mesh that
``scripts/bench_articulation.py`` built for it (the ``generic`` detections), copied to
``--out``: decompose + articulate with the current code, ``complete`` (no appearance model: the
EMD needs no Gaussians), ``twin`` (its physical checks on; a failing check is recorded and the
twin built unchecked), ``stability`` on the twin's parts (the extreme cases do not depend on
the kitchen), ``simulate`` (drives + probes, with the stability choice) and ``evaluate`` (precision, recall,
EA-score, motion EMD). Reports the EMD per kitchen and pooled over every correct part (the
paper: 1.41e-5), the simulation's deviation from the joints, the probes and the wall times;
writes ``<out>/<split>/results.json`` and ``summary.md``.

    python scripts/bench_articulation.py --split test --n 20 --build-only --out /work/bench17/data
    python scripts/bench_motion.py --n 20 --data /work/bench17/data --out /work/bench19
"""

import argparse
import json
import shutil
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

import drawer_lib.synth.gl  # noqa: F401, E402, I001  (MuJoCo reads MUJOCO_GL once, at import)
from bench_articulation import MODE_FILE, compose, one  # noqa: E402
from bench_twin import _stage, scene_config  # noqa: E402
from drawer_lib.capture.config import CaptureConfig  # noqa: E402
from drawer_lib.complete.config import CompleteConfig  # noqa: E402
from drawer_lib.complete.pipeline import CompleteInputs, run_complete  # noqa: E402
from drawer_lib.config.typed import to_typed  # noqa: E402
from drawer_lib.errors import TwinCheckError  # noqa: E402
from drawer_lib.io.capture import load_capture  # noqa: E402
from drawer_lib.metrics.evaluate import run_evaluate  # noqa: E402
from drawer_lib.paths import ScenePaths  # noqa: E402
from drawer_lib.sim.pipeline import SimulateConfig, run_simulate  # noqa: E402
from drawer_lib.sim.stability_stage import StabilityConfig, run_stability  # noqa: E402
from drawer_lib.synth.splits import SPLITS  # noqa: E402
from drawer_lib.twin.config import TwinConfig  # noqa: E402
from drawer_lib.twin.pipeline import run_twin  # noqa: E402

MODE = "generic"


def one_kitchen(split: str, k: int, data: Path, out: Path) -> tuple[dict, list[dict]]:
    src = data / split / f"k{k:02d}_{MODE}"
    if not (src / "mesh" / "mesh.ply").is_file():
        sys.exit(f"{src}: no capture + mesh (build them: python scripts/bench_articulation.py --split {split} "
                 f"--kitchens {k} --build-only --out {data})")
    dst = out / split / src.name
    if dst.exists():
        shutil.rmtree(dst)
    dst.mkdir(parents=True)
    for sub in ("capture", "sdf", "mesh"):
        shutil.copytree(src / sub, dst / sub)
    cfg = compose(["scene=kitchen_small", f"capture/detections={MODE_FILE[MODE]}", "twin.renders.max_views=1",
                   "twin.renders.lpips=false"])
    one(split, k, MODE, out / split, reuse=True)  # decompose + articulate with the current code
    sp = ScenePaths(out / split, dst.name)
    cap = load_capture(sp.capture)
    times, row = {}, {"kitchen": k}
    t0 = time.perf_counter()
    cc = to_typed(CompleteConfig, cfg.complete, "complete")
    _stage("complete", sp.stage_dir("complete"), lambda r: run_complete(
        cc, cap, CompleteInputs(sp.parts, sp.mesh, sp.decompose, sp.field, None), r, float(cfg.twin.sim.densities.part)))
    times["complete_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    render = to_typed(CaptureConfig, cfg.capture, "capture").render
    tc = to_typed(TwinConfig, cfg.twin, "twin")
    try:
        _stage("twin", sp.stage_dir("twin"), lambda r: run_twin(tc, cap, sp.parts, sp.stage_dir("complete"), r,
                                                                scene_config(cfg, split, k), render))
    except TwinCheckError as e:
        row["check_error"] = str(e)
        tc = to_typed(TwinConfig, OmegaConf.merge(cfg.twin, {"check": False}), "twin")
        _stage("twin", sp.stage_dir("twin"), lambda r: run_twin(tc, cap, sp.parts, sp.stage_dir("complete"), r,
                                                                scene_config(cfg, split, k), render))
    times["twin_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()  # the stability study on this twin's parts (the extremes do not depend on the scene)
    stc = to_typed(StabilityConfig, OmegaConf.merge(cfg.stability, {"extremes": False}), "stability")
    st = _stage("stability", sp.stage_dir("stability"), lambda r: run_stability(
        stc, sp.parts, sp.stage_dir("twin"), (tc.sim.integrator, tc.sim.timestep), r))
    times["stability_s"] = time.perf_counter() - t0
    row |= {f"stab_{x}": st.get(x) for x in ("integrator", "timestep", "nominal_error_m", "realtime_factor")}
    t0 = time.perf_counter()
    sm = _stage("simulate", sp.stage_dir("simulate"), lambda r: run_simulate(
        to_typed(SimulateConfig, cfg.simulate, "simulate"), sp.parts, sp.stage_dir("twin"), r,
        sp.file("stability", "choice")))
    times["simulate_s"] = time.perf_counter() - t0
    em = _stage("evaluate", sp.stage_dir("evaluate"), lambda r: run_evaluate(cap, sp.parts, r,
                                                                             sp.file("simulate", "tracks")))
    motion = json.loads(sp.file("evaluate", "matches").read_text())["motion"]
    row |= {x: em[x] for x in ("precision", "recall", "ea_score", "emd", "emd_max", "n_emd") if x in em}
    row |= {f"sim_{x}": v for x, v in sm.items() if not isinstance(v, str)}
    row |= {x: round(v, 2) for x, v in times.items()}
    return row, [dict(r, kitchen=k) for r in motion]


def summary(rows: list[dict], parts: list[dict], split: str) -> str:
    e = np.array([p["emd"] for p in parts if p.get("emd") is not None])
    per = np.array([r["emd"] for r in rows if "emd" in r])
    f = lambda key, fmt="{:.3g}": (fmt.format(np.nanmean([r.get(key, np.nan) for r in rows])) + " (max "  # noqa: E731
                                   + fmt.format(np.nanmax([r.get(key, np.nan) for r in rows])) + ")")
    L = [f"Kitchens {', '.join(str(r['kitchen']) for r in rows)} ({split} split), {MODE} detections, TSDF geometry.", "",
         "| figure | value |", "|---|---|",
         f"| motion EMD pooled over correct parts (the paper: 1.41e-5) | {e.mean():.3g} (n = {len(e)}; median "
         f"{np.median(e):.3g}, max {e.max():.3g}) |" if len(e) else "| motion EMD | no correct part |",
         f"| motion EMD, mean of kitchens | {per.mean():.3g} (worst kitchen {per.max():.3g}) |" if len(per) else "",
         f"| revolute / prismatic parts, mean EMD | "
         f"{np.mean([p['emd'] for p in parts if p.get('emd') is not None and p['kind'] == 'revolute'] or [np.nan]):.3g} / "
         f"{np.mean([p['emd'] for p in parts if p.get('emd') is not None and p['kind'] == 'prismatic'] or [np.nan]):.3g} |",
         f"| precision / recall | {f('precision', '{:.3f}')} / {f('recall', '{:.3f}')} |",
         f"| simulation vs the joints' kinematics (max point distance, m) | {f('sim_kinematic_dev_max_m')} |",
         f"| parts that did not reach their upper limit | {sum(r.get('sim_n_parts_not_opened', 0) for r in rows)} |",
         f"| cups riding along in closing drawers | {sum(r.get('sim_cup_rides_along_passed', 0) for r in rows)} / "
         f"{sum(r.get('sim_cup_rides_along_n', 0) for r in rows)} (worst error {f('sim_cup_rides_along_error_max_m')} m) |",
         f"| hands pulling handles open | {sum(r.get('sim_pull_handle_passed', 0) for r in rows)} / "
         f"{sum(r.get('sim_pull_handle_n', 0) for r in rows)} (peak force {f('sim_pull_handle_peak_force_max_n')} N) |",
         f"| blocks dropped on the counter resting on it | {sum(r.get('sim_drop_on_counter_passed', 0) for r in rows)} / "
         f"{sum(r.get('sim_drop_on_counter_n', 0) for r in rows)} |",
         f"| twins failing a physical check | {sum('check_error' in r for r in rows)} |",
         "| stability choice (integrator, timestep: kitchens) | " + ", ".join(
             f"{i} {t:g} s: {n}" for (i, t), n in sorted(Counter((r.get('stab_integrator'), r.get('stab_timestep'))
                                                                for r in rows).items(), key=str)) + " |",
         f"| worst part error at the choice (m) / full twin real-time factor | {f('stab_nominal_error_m')} / "
         f"{f('stab_realtime_factor', '{:.1f}')} |",
         f"| complete / twin / stability / simulate s | {f('complete_s', '{:.1f}')} / {f('twin_s', '{:.1f}')} / "
         f"{f('stability_s', '{:.1f}')} / {f('simulate_s', '{:.1f}')} |"]
    return "\n".join(x for x in L if x) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--split", choices=SPLITS, default="test")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--kitchens", default="", help="comma-separated kitchen indices (instead of --n)")
    ap.add_argument("--data", type=Path, default=Path("/work/bench17/data"), help="bench_articulation's --out")
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_motion"))
    a = ap.parse_args()
    ks = [int(x) for x in a.kitchens.split(",")] if a.kitchens else list(range(a.n))
    (a.out / a.split).mkdir(parents=True, exist_ok=True)
    res = a.out / a.split / "results.json"
    prev = json.loads(res.read_text()) if res.is_file() else {"rows": [], "parts": []}
    rows = [r for r in prev["rows"] if r["kitchen"] not in ks]
    parts = [p for p in prev["parts"] if p["kitchen"] not in ks]
    for k in ks:
        t0 = time.perf_counter()
        r, ps = one_kitchen(a.split, k, a.data, a.out)
        rows.append(r)
        parts += ps
        res.write_text(json.dumps({"rows": rows, "parts": parts}, indent=1))
        print(f"kitchen {k}: EMD {r.get('emd', float('nan')):.3g} over {r.get('n_emd', 0)} parts, P/R "
              f"{r.get('precision', float('nan')):.3f}/{r.get('recall', float('nan')):.3f}, "
              f"{'CHECK FAILED' if 'check_error' in r else 'checks pass'}; {time.perf_counter() - t0:.0f} s", flush=True)
    rows.sort(key=lambda r: r["kitchen"])
    md = summary(rows, parts, a.split)
    (a.out / a.split / "summary.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
