#!/usr/bin/env python
"""Benchmark of the twin (``complete`` + ``twin``) on procedural kitchens with noisy detections.

Per kitchen of ``--split`` (default ``test``: never tuned on), on the capture and mesh that
``scripts/bench_articulation.py`` built for it (TSDF geometry from the sensor depth, the
``generic`` detections: missed, merged, ragged and false masks), copied to ``--out``:

1. decompose + articulate rerun with the current code (precision / recall / EA-score);
2. the appearance model (the default config: Gaussians on the mesh, ``movable_gs_ste``);
3. ``complete`` + ``twin`` twice: with the fitted interiors (the default; the twin's physical
   checks on) and with DRAWER's fixed rule (``complete.interiors.method=drawer_rule``; checks
   off, since the rule's boxes are not fitted to the carcass and may not open);

and reports closed vs opened PSNR / SSIM / LPIPS (whole image and the moving part's region),
the interior depth error against GT (fitted vs rule) and the opened region PSNR of each, the
static collision's fidelity (Chamfer-L1, F@2cm of the boxes to the visual mesh) and its size,
the penetration at q = 0, the simulation speed and the ``complete`` + ``twin`` wall time.
Writes ``<out>/results.json`` and ``<out>/summary.md``.

    python scripts/bench_articulation.py --split test --kitchens 0,2,3,4,6 --build-only --out /work/bench17/data
    python scripts/bench_twin.py --kitchens 0,2,3,4,6 --data /work/bench17/data --out /work/bench18
    python scripts/bench_twin.py --kitchens 0 --reuse ...     # complete + twin only, on the kitchens' appearance models
"""

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

import drawer_lib.synth.gl  # noqa: F401, E402, I001  (MuJoCo reads MUJOCO_GL once, at import)
from bench_articulation import MODE_FILE, compose, one  # noqa: E402
from drawer_lib.capture.config import CaptureConfig, SceneConfig  # noqa: E402
from drawer_lib.complete.config import CompleteConfig  # noqa: E402
from drawer_lib.complete.pipeline import CompleteInputs, run_complete  # noqa: E402
from drawer_lib.config.typed import to_typed  # noqa: E402
from drawer_lib.errors import TwinCheckError  # noqa: E402
from drawer_lib.io.capture import load_capture  # noqa: E402
from drawer_lib.paths import ScenePaths  # noqa: E402
from drawer_lib.runner import StageRun  # noqa: E402
from drawer_lib.splat.config import AppearanceConfig  # noqa: E402
from drawer_lib.splat.pipeline import run_appearance  # noqa: E402
from drawer_lib.synth.splits import SPLITS, split_synth  # noqa: E402
from drawer_lib.twin.config import TwinConfig  # noqa: E402
from drawer_lib.twin.pipeline import run_twin  # noqa: E402

MODE = "generic"
TWIN_KEYS = ("closed_psnr", "closed_ssim", "closed_lpips", "open_psnr", "open_ssim", "open_lpips", "open_region_psnr",
             "sim_penetration_parts_max_m",
             "n_parts_scored_open", "sim_penetration_max_m", "sim_path_penetration_max_m", "sim_rigid_drift_max_m",
             "sim_sim_steps_per_s", "sim_sim_realtime_factor", "sim_drive_time_to_open_s_max",
             "sim_pull_time_to_open_s_max", "n_static_collision", "n_part_collision", "n_gaussians", "wall_s")
COMPLETE_KEYS = ("interior_depth_error", "interior_depth_error_max", "interior_depth_error_drawer_rule",
                 "interior_depth_error_drawer_rule_max", "n_interiors_scored", "collision_chamfer_l1",
                 "collision_fscore_2cm", "n_static_boxes", "n_cavity_walls", "n_interior_gaussians_culled", "wall_s")


def scene_config(cfg, split: str, k: int) -> SceneConfig:
    """kitchen_small's scene config with the split's synth values (as bench_articulation builds it)."""
    d = OmegaConf.to_container(cfg.scene, resolve=True)
    for key, val in split_synth(split, k).items():
        if isinstance(val, dict):
            d["synth"][key].update(val)
        else:
            d["synth"][key] = val
    return to_typed(SceneConfig, d, f"{split} kitchen {k}", strict=False)


def _stage(name: str, d: Path, fn, seed: int = 0) -> dict:
    if d.exists():
        shutil.rmtree(d)
    d.mkdir(parents=True)
    return fn(StageRun(name, d, d, seed))


def twin_pair(cfg, cap, sp: ScenePaths, scene: SceneConfig, d: Path) -> dict:
    """complete + twin with the fitted interiors (checks on) and with DRAWER's rule (checks off)."""
    row: dict = {}
    render = to_typed(CaptureConfig, cfg.capture, "capture").render
    density = float(cfg.twin.sim.densities.part)
    app_model = sp.appearance_dir(cfg.complete.gaussians.variant) / "model"
    for method in ("fitted", "drawer_rule"):
        ccfg = OmegaConf.merge(cfg.complete, {"interiors": {"method": method}})
        cc = to_typed(CompleteConfig, ccfg, "complete")
        tc = to_typed(TwinConfig, OmegaConf.merge(cfg.twin, {"check": method == "fitted"}), "twin")
        cdir, tdir = d / f"complete_{method}", d / f"twin_{method}"
        t0 = time.perf_counter()
        cm = _stage("complete", cdir, lambda r: run_complete(cc, cap, CompleteInputs(sp.parts, sp.mesh, sp.decompose,
                                                                                      sp.field, app_model), r, density))
        try:
            tm = _stage("twin", tdir, lambda r: run_twin(tc, cap, sp.parts, cdir, r, scene, render))
        except TwinCheckError as e:  # a failing check is a finding: record it, then build the twin unchecked
            row[f"{method}_check_error"] = str(e)
            tc = to_typed(TwinConfig, OmegaConf.merge(cfg.twin, {"check": False}), "twin")
            tm = _stage("twin", tdir, lambda r: run_twin(tc, cap, sp.parts, cdir, r, scene, render))
        row[f"{method}_complete_twin_s"] = round(time.perf_counter() - t0, 2)
        row |= {f"{method}_{k}": cm[k] for k in COMPLETE_KEYS if k in cm}
        row |= {f"{method}_twin_{k}": tm[k] for k in TWIN_KEYS if k in tm}
    return row


def one_kitchen(split: str, k: int, data: Path, out: Path, reuse: bool) -> dict:
    src = data / split / f"k{k:02d}_{MODE}"
    dst = out / split / f"k{k:02d}_{MODE}"
    if not (src / "mesh" / "mesh.ply").is_file() and not (reuse and (dst / "mesh" / "mesh.ply").is_file()):
        sys.exit(f"{src}: no capture + mesh (build them: python scripts/bench_articulation.py --split {split} "
                 f"--kitchens {k} --build-only --out {data})")
    cfg = compose(["scene=kitchen_small", f"capture/detections={MODE_FILE[MODE]}"])
    sp = ScenePaths(out / split, dst.name)
    times: dict = {}
    if not reuse:
        if dst.exists():
            shutil.rmtree(dst)
        dst.mkdir(parents=True)
        for sub in ("capture", "sdf", "mesh"):
            shutil.copytree(src / sub, dst / sub)
        shutil.copy(src / "geometry.json", dst / "geometry.json") if (src / "geometry.json").is_file() else None
    perception = one(split, k, MODE, out / split, reuse=True)  # decompose + articulate on the copied capture + mesh
    cap = load_capture(sp.capture)
    app_dir = sp.appearance_dir(cfg.appearance.variant)
    if not reuse or not (app_dir / "model" / "gaussians.ply").is_file():
        app = to_typed(AppearanceConfig, cfg.appearance, "appearance")
        t0 = time.perf_counter()
        am = _stage("appearance", app_dir, lambda r: run_appearance(app, cap, sp.mesh, r, sp.field))
        times["appearance_s"] = round(time.perf_counter() - t0, 1)
        (dst / "appearance.json").write_text(json.dumps({k: am[k] for k in ("psnr", "ssim", "lpips") if k in am}))
    app_m = json.loads((dst / "appearance.json").read_text())
    row = {"kitchen": k, "split": split, **{f"perception_{x}": perception[x] for x in
                                           ("precision", "recall", "ea_score", "n_pred", "n_gt", "n_correct")},
           **{f"appearance_{x}": v for x, v in app_m.items()}, **times,
           **twin_pair(cfg, cap, sp, scene_config(cfg, split, k), dst)}
    return row


def _f(rows, key, scale=1.0, fmt="{:.2f}"):
    v = np.array([r.get(key, np.nan) for r in rows], float) * scale
    v = v[np.isfinite(v)]
    return (fmt.format(v.mean()) + " (" + fmt.format(v.min()) + "–" + fmt.format(v.max()) + ")") if len(v) else "–"


def summary(rows: list[dict]) -> str:
    ks = ", ".join(str(r["kitchen"]) for r in rows)
    L = [f"Kitchens {ks} ({rows[0]['split']} split), {MODE} detections, TSDF geometry; mean (min–max).", "",
         "| | fitted interiors (default) | DRAWER's rule |", "|---|---|---|"]
    for label, key, scale, fmt in (
            ("closed PSNR dB (capture test views)", "twin_closed_psnr", 1, "{:.2f}"),
            ("closed SSIM", "twin_closed_ssim", 1, "{:.3f}"),
            ("closed LPIPS", "twin_closed_lpips", 1, "{:.3f}"),
            ("opened PSNR dB (GT at the same q)", "twin_open_psnr", 1, "{:.2f}"),
            ("opened SSIM", "twin_open_ssim", 1, "{:.3f}"),
            ("opened LPIPS", "twin_open_lpips", 1, "{:.3f}"),
            ("opened region PSNR dB", "twin_open_region_psnr", 1, "{:.2f}"),
            ("parts scored opened", "twin_n_parts_scored_open", 1, "{:.1f}"),
            ("interior depth error mean cm", "interior_depth_error", 100, "{:.1f}"),
            ("interior depth error max cm", "interior_depth_error_max", 100, "{:.1f}"),
            ("complete + twin s", "complete_twin_s", 1, "{:.1f}")):
        if key.startswith("interior_depth"):  # both measured in the fitted run, against the same GT
            a, b = _f(rows, f"fitted_{key}", scale, fmt), _f(rows, "fitted_" + key.replace("error", "error_drawer_rule"),
                                                             scale, fmt)
        else:
            a, b = _f(rows, f"fitted_{key}", scale, fmt), _f(rows, f"drawer_rule_{key}", scale, fmt)
        L.append(f"| {label} | {a} | {b} |")
    L += ["", "| fitted twin | value |", "|---|---|"]
    for label, key, scale, fmt in (
            ("appearance model PSNR dB (test views)", "appearance_psnr", 1, "{:.2f}"),
            ("perception precision / recall", None, 1, "{:.3f}"),
            ("static collision: boxes", "fitted_n_static_boxes", 1, "{:.0f}"),
            ("static collision: all geoms (boxes + cavity walls + pads)", "fitted_twin_n_static_collision", 1, "{:.0f}"),
            ("part collision geoms", "fitted_twin_n_part_collision", 1, "{:.0f}"),
            ("collision Chamfer-L1 cm (boxes to the static mesh)", "fitted_collision_chamfer_l1", 100, "{:.1f}"),
            ("collision F@2cm", "fitted_collision_fscore_2cm", 1, "{:.3f}"),
            ("penetration at q = 0 mm", "fitted_twin_sim_penetration_max_m", 1000, "{:.2f}"),
            ("penetration along the opening paths mm", "fitted_twin_sim_path_penetration_max_m", 1000, "{:.2f}"),
            ("rigid objects' drift in 2 s mm", "fitted_twin_sim_rigid_drift_max_m", 1000, "{:.2f}"),
            ("sim steps / s", "fitted_twin_sim_sim_steps_per_s", 1, "{:.0f}"),
            ("real-time factor", "fitted_twin_sim_sim_realtime_factor", 1, "{:.1f}"),
            ("interior Gaussians culled (seen when closed)", "fitted_n_interior_gaussians_culled", 1, "{:.0f}")):
        if key is None:
            L.append(f"| {label} | {_f(rows, 'perception_precision', 1, fmt)} / {_f(rows, 'perception_recall', 1, fmt)} |")
        else:
            L.append(f"| {label} | {_f(rows, key, scale, fmt)} |")
    fails = [(r["kitchen"], r[k]) for r in rows for k in r if k.endswith("_check_error")]
    L += ["", f"Twins failing a physical check: {len(fails)}" + "".join(f"\n- kitchen {k}: {e}" for k, e in fails)]
    return "\n".join(L) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--split", choices=SPLITS, default="test")
    ap.add_argument("--kitchens", default="0,2,3,4,6", help="comma-separated kitchen indices")
    ap.add_argument("--data", type=Path, default=Path("/work/bench17/data"), help="bench_articulation's --out")
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_twin"))
    ap.add_argument("--reuse", action="store_true", help="keep the copied captures and the appearance models")
    a = ap.parse_args()
    (a.out / a.split).mkdir(parents=True, exist_ok=True)
    res = a.out / a.split / "results.json"
    rows = json.loads(res.read_text()) if res.is_file() else []
    for k in (int(x) for x in a.kitchens.split(",")):
        t0 = time.perf_counter()
        r = one_kitchen(a.split, k, a.data, a.out, a.reuse)
        rows = [x for x in rows if x["kitchen"] != k] + [r]
        res.write_text(json.dumps(rows, indent=1))
        print(f"kitchen {k}: closed {r.get('fitted_twin_closed_psnr', float('nan')):.2f} dB, opened "
              f"{r.get('fitted_twin_open_psnr', float('nan')):.2f} / region "
              f"{r.get('fitted_twin_open_region_psnr', float('nan')):.2f} dB (rule "
              f"{r.get('drawer_rule_twin_open_region_psnr', float('nan')):.2f}), interior depth error "
              f"{r.get('fitted_interior_depth_error', float('nan')):.3f} m (rule "
              f"{r.get('fitted_interior_depth_error_drawer_rule', float('nan')):.3f}); {time.perf_counter() - t0:.0f} s",
              flush=True)
    rows.sort(key=lambda r: r["kitchen"])
    md = summary(rows)
    (a.out / a.split / "summary.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
