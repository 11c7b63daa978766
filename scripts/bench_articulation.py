#!/usr/bin/env python
"""Benchmark of scene decomposition + articulation over procedural kitchens of two splits.

``--split train`` (tune on it) or ``--split test`` (never tuned on: other seeds, sizes, styles,
counts; drawer_lib/synth/splits.py states both), kitchens 0..``--n``-1 of the split, each
with every detection mode in ``--modes``:

- ``generic``: the default detector simulation (missed, merged, ragged, false masks), every
  label generic (front / handle / object);
- ``noisy``: the same noise with typed labels (drawer / door / ..., with confusions);
- ``off``: no detections (decompose falls back to geometry);

it renders the capture, fuses the sensor depth (TSDF, 2 cm: the fast geometry of the pipeline;
``--sdf neural`` trains the pipeline's neural SDF instead, ``--depth exact`` renders exact depth),
meshes it, runs decompose + articulate with the default configs and scores the parts against the
GT (DESIGN §6). Prints per-run rows and, per mode, precision / recall / EA-score (mean and worst
scene) and pooled over all parts; writes ``<out>/<split>/results.json`` and ``summary.md``.

    python scripts/bench_articulation.py --split train [--n 20] [--modes generic] [--out /tmp/bench_articulation]
    python scripts/bench_articulation.py --split test --reuse   # after a perception change: same captures and meshes
    python scripts/bench_articulation.py --split train --reuse --kitchens 1,10   # a subset
    python scripts/bench_articulation.py --split test --kitchens 1,5,9,13,17 --sdf neural --depth exact \
        --out /tmp/bench_neural      # the geometry of the large kitchens with the default neural SDF
    python scripts/bench_articulation.py --split train --reuse --set articulate.types.use_labels=false
                                     # a config variant: results_<overrides>.json / summary_<overrides>.md
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

from drawer_lib.articulation.config import ArticulateConfig  # noqa: E402
from drawer_lib.articulation.pipeline import run_articulate  # noqa: E402
from drawer_lib.capture.build import build_capture  # noqa: E402
from drawer_lib.capture.config import CaptureConfig, SceneConfig  # noqa: E402
from drawer_lib.config.typed import to_typed  # noqa: E402
from drawer_lib.io.capture import load_capture  # noqa: E402
from drawer_lib.io.parts import read_parts  # noqa: E402
from drawer_lib.mesh.config import MeshConfig  # noqa: E402
from drawer_lib.mesh.pipeline import run_mesh  # noqa: E402
from drawer_lib.metrics.articulation import articulation_metrics  # noqa: E402
from drawer_lib.paths import ScenePaths, capture_name  # noqa: E402
from drawer_lib.perception.config import DecomposeConfig  # noqa: E402
from drawer_lib.perception.pipeline import run_decompose  # noqa: E402
from drawer_lib.runner import StageRun  # noqa: E402
from drawer_lib.sdf.config import SdfConfig  # noqa: E402
from drawer_lib.sdf.io import load_field  # noqa: E402
from drawer_lib.sdf.pipeline import run_sdf  # noqa: E402
from drawer_lib.synth.splits import SPLITS, split_synth  # noqa: E402

MODE_FILE = {"generic": "noisy_generic", "noisy": "noisy", "off": "off"}  # also the order of the summary


def compose(overrides: list[str]):
    from hydra import compose as hcompose
    from hydra import initialize_config_dir

    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return hcompose(config_name="config", overrides=overrides)


def one(split: str, k: int, mode: str, out: Path, reuse: bool = False, extra: tuple[str, ...] = (),
        build_only: bool = False, articulate_only: bool = False, sdf: str = "tsdf", depth: str = "sensor") -> dict:
    cfg = compose(["scene=kitchen_small", f"capture/detections={MODE_FILE[mode]}", f"capture/depth={depth}",
                   f"sdf={sdf}", *extra])
    scene_d = OmegaConf.to_container(cfg.scene, resolve=True)
    for key, val in split_synth(split, k).items():  # the split's values replace kitchen_small's
        if isinstance(val, dict):
            scene_d["synth"][key].update(val)
        else:
            scene_d["synth"][key] = val
    scene = to_typed(SceneConfig, scene_d, f"{split} kitchen {k}", strict=False)
    capcfg = to_typed(CaptureConfig, cfg.capture, "capture")
    d = out / f"k{k:02d}_{mode}"
    cap_dir = d / "capture"
    kept = reuse and (d / "mesh" / "mesh.ply").is_file()
    redo = ("articulate",) if articulate_only and (d / "decompose" / "segments.json").is_file() else (
        "decompose", "articulate")
    if kept:  # perception only, on the capture and mesh of an earlier run
        for stage in redo:
            shutil.rmtree(d / stage, ignore_errors=True)
        prev = json.loads((d / "row.json").read_text()) if (d / "row.json").is_file() else {}
        times = {f"{t}_s": prev.get(f"{t}_s", float("nan")) for t in ("capture", "sdf", "mesh", "decompose")
                 if t not in redo}
    else:
        if d.exists():
            shutil.rmtree(d)
        cap_dir.mkdir(parents=True)
        t0 = time.perf_counter()
        build_capture(f"bench_{k}", scene, capcfg, cap_dir, np.random.default_rng(k), ROOT)
        times = {"capture_s": time.perf_counter() - t0}
    cap = load_capture(cap_dir)
    sp = ScenePaths(out, d.name)
    stages = (("sdf", lambda r: run_sdf(to_typed(SdfConfig, cfg.sdf, "sdf"), cap, r)),
              ("mesh", lambda r: run_mesh(to_typed(MeshConfig, cfg.mesh, "mesh"), load_field(sp.field), cap, r)),
              ("decompose", lambda r: run_decompose(to_typed(DecomposeConfig, cfg.decompose, "decompose"), cap, sp.mesh,
                                                    r)),
              ("articulate", lambda r: run_articulate(to_typed(ArticulateConfig, cfg.articulate, "articulate"), cap,
                                                      sp.decompose, r)))
    geo, sdf_m = {}, {}
    for stage, fn in stages[4 - len(redo):] if kept else stages:
        if build_only and stage == "decompose":
            break
        t = time.perf_counter()
        o = sp.stage_dir(stage)
        o.mkdir()
        m = fn(StageRun(stage, o, o, 0))
        times[f"{stage}_s"] = time.perf_counter() - t
        if stage == "sdf":
            sdf_m = {f"sdf_{k}": m[k] for k in ("train_s", "steps") if k in m}
        if stage == "mesh":
            geo = {k: m[k] for k in ("chamfer_l1", "fscore_1cm", "fscore_2cm") if k in m} | sdf_m
            (d / "geometry.json").write_text(json.dumps(geo))
    if build_only:
        return {"kitchen": k, "mode": mode, **{t: round(v, 2) for t, v in times.items()}, **geo}
    if kept and (d / "geometry.json").is_file():
        geo = json.loads((d / "geometry.json").read_text())
    res, details = articulation_metrics(read_parts(sp.parts), read_parts(cap_dir / capture_name("gt_parts")),
                                        cap.cameras(cap.test))
    (d / "matches.json").write_text(json.dumps(details, indent=1))
    row = {"kitchen": k, "mode": mode, **res, **{t: round(v, 2) for t, v in times.items()}, **geo,
           "eas": [r["ea_score"] for r in details if r.get("ea_score") is not None]}
    (d / "row.json").write_text(json.dumps(row))
    return row


def geometry_summary(rows: list[dict], sdf: str) -> str:
    """Chamfer / F-scores / training time of the meshes, mean and worst kitchen."""
    rs = [r for r in rows if "chamfer_l1" in r]
    if not rs:
        return ""
    ch, f1, f2 = (np.array([r.get(k, np.nan) for r in rs]) for k in ("chamfer_l1", "fscore_1cm", "fscore_2cm"))
    t = np.array([r.get("sdf_train_s", r.get("sdf_s", np.nan)) for r in rs])
    return ("| geometry | kitchens | Chamfer-L1 mean / worst | F@1cm mean / worst | F@2cm mean / worst | "
            "training s mean / max |\n|---|---|---|---|---|---|\n"
            f"| {sdf} | {len(rs)} ({', '.join(str(r['kitchen']) for r in rs)}) | {1000 * ch.mean():.2f} / "
            f"{1000 * ch.max():.2f} mm | {f1.mean():.3f} / {f1.min():.3f} | {f2.mean():.3f} / {f2.min():.3f} | "
            f"{np.nanmean(t):.0f} / {np.nanmax(t):.0f} |\n")


def summary(rows: list[dict]) -> str:
    lines = ["| detections | kitchens | precision mean / worst | recall mean / worst | EA mean / worst scene | "
             "pooled P / R (parts) | EA pooled (revolute parts) | s per kitchen (perception) | "
             "mesh: Chamfer mean / worst, F@2cm mean / worst |",
             "|---|---|---|---|---|---|---|---|---|"]
    for mode in dict.fromkeys(r["mode"] for r in rows):
        rs = [r for r in rows if r["mode"] == mode]
        P = [r["precision"] for r in rs if "precision" in r]
        R = [r["recall"] for r in rs]
        E = [r["ea_score"] for r in rs if "ea_score" in r]
        n_pred = sum(r["n_pred"] - r["n_ignored"] for r in rs)
        n_cor = sum(r["n_correct"] for r in rs)
        n_gt = sum(r["n_gt"] for r in rs)
        eas = [e for r in rs for e in r["eas"]]
        per = np.mean([r["decompose_s"] + r["articulate_s"] for r in rs])
        ch = [r["chamfer_l1"] for r in rs if "chamfer_l1" in r]
        fs = [r["fscore_2cm"] for r in rs if "fscore_2cm" in r]
        geo = f"{1000 * np.mean(ch):.1f} / {1000 * np.max(ch):.1f} mm, {np.mean(fs):.3f} / {np.min(fs):.3f}" if ch else "–"
        f = lambda v: f"{np.mean(v):.3f} / {np.min(v):.3f}" if v else "–"  # noqa: E731
        lines.append(f"| {mode} | {len(rs)} | {f(P)} | {f(R)} | {f(E)} | {n_cor / max(n_pred, 1):.3f} / "
                     f"{n_cor / max(n_gt, 1):.3f} ({n_cor}/{n_pred}, {n_cor}/{n_gt}) | "
                     f"{(np.mean(eas) if eas else float('nan')):.4f} (n = {len(eas)}) | {per:.1f} | {geo} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--split", choices=SPLITS, required=True, help="drawer_lib/synth/splits.py")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--kitchens", default="", help="comma-separated kitchen indices (instead of --start/--n)")
    ap.add_argument("--modes", default="generic")
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_articulation"))
    ap.add_argument("--reuse", action="store_true",
                    help="rerun only decompose + articulate on the captures and meshes already under --out")
    ap.add_argument("--build-only", action="store_true", help="captures and meshes only (no perception, no rows)")
    ap.add_argument("--articulate-only", action="store_true",
                    help="with --reuse: rerun articulate only, on the decompose outputs already there")
    ap.add_argument("--sdf", choices=("tsdf", "neural"), default="tsdf", help="the geometry (conf/sdf)")
    ap.add_argument("--depth", choices=("sensor", "exact"), default="sensor", help="the capture's depth (conf/capture/depth)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a Hydra override of the perception configs (repeatable); with --reuse on the same captures")
    a = ap.parse_args()
    bad = [o for o in a.set if not o.startswith(("decompose.", "articulate."))]
    if bad:
        sys.exit(f"--set {bad[0]}: only decompose.* / articulate.* overrides (the captures and meshes are shared)")
    a.out = a.out / a.split
    a.out.mkdir(parents=True, exist_ok=True)
    tag = "".join("_" + "".join(c if c.isalnum() or c in ".=-" else "-" for c in o) for o in a.set)
    res_path = a.out / f"results{tag}.json"
    rows = json.loads(res_path.read_text()) if res_path.exists() else []
    ks = [int(k) for k in a.kitchens.split(",")] if a.kitchens else list(range(a.start, a.start + a.n))
    todo = [(k, mode) for mode in a.modes.split(",") for k in ks]
    if a.reuse:  # recompute these rows
        rows = [r for r in rows if (r["kitchen"], r["mode"]) not in set(todo)]
    done = {(r["kitchen"], r["mode"]) for r in rows}
    geo_path = a.out / "geometry.json"  # build-only rows: the geometry alone
    geo_rows = json.loads(geo_path.read_text()) if geo_path.exists() else []
    for k, mode in todo:
        if (k, mode) in done:
            continue
        if a.set and not (a.out / f"k{k:02d}_{mode}" / "mesh" / "mesh.ply").is_file():
            sys.exit(f"--set needs the captures and meshes of a plain run under {a.out}: k{k:02d}_{mode} is missing")
        if a.build_only:
            if not (a.out / f"k{k:02d}_{mode}" / "mesh" / "mesh.ply").is_file():
                r = one(a.split, k, mode, a.out, build_only=True, sdf=a.sdf, depth=a.depth)
                geo_rows = [g for g in geo_rows if (g["kitchen"], g["mode"]) != (k, mode)] + [r]
                geo_path.write_text(json.dumps(geo_rows, indent=1))
                print(f"kitchen {k:2d} {mode}: built; {json.dumps(r)}", flush=True)
            continue
        r = one(a.split, k, mode, a.out, a.reuse or bool(a.set), tuple(a.set), articulate_only=a.articulate_only,
                sdf=a.sdf, depth=a.depth)
        rows.append(r)
        res_path.write_text(json.dumps(rows, indent=1))
        print(f"kitchen {k:2d} {mode:8s} P {r.get('precision', float('nan')):.3f} R {r['recall']:.3f} "
              f"EA {r.get('ea_score', float('nan')):.4f} ({r['n_correct']}/{r['n_pred'] - r['n_ignored']} pred, "
              f"{r['n_gt']} GT) perception {r['decompose_s'] + r['articulate_s']:.1f} s", flush=True)
    rows.sort(key=lambda r: (list(MODE_FILE).index(r["mode"]), r["kitchen"]))
    md = geometry_summary(geo_rows if a.build_only else rows, f"{a.sdf}, {a.depth} depth")
    if not a.build_only:
        md = summary(rows) + "\n" + md
    (a.out / f"summary{tag}{'_geometry' if a.build_only else ''}.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
