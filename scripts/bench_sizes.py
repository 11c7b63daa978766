#!/usr/bin/env python
"""What each stage costs on captures of a phone's size: a procedural kitchen rendered at W x H
x N frames, written as a phone app writes it (``ns-process-data polycam --use-depth``: JPEG,
a camera per frame, LiDAR depth at about 256 x 192 with confidence maps; drawer_lib/synth/phone.py),
imported by a two-line scene file, then every stage up to the twin run as ``dvc repro`` runs
them (``python -m stages.<name>``), one after the other. Reports per stage the wall time and
the peak memory it records in its ``metrics.json``, and what the twin came out as.

    python scripts/bench_sizes.py --size 640x480x150
    python scripts/bench_sizes.py --size 1280x960x300 --stages capture detect priors sdf mesh
    python scripts/bench_sizes.py --size 1280x960x300 --tag full --stages sdf mesh decompose articulate \
        --set sdf.max_side=null decompose.max_side=null articulate.max_side=null   # at full resolution

The capture has no detections and no monocular priors: ``detect`` runs the built-in detector
(``--bench``: where the ``detector`` stage wrote its weights), ``priors`` records none.
Articulate uses the prior decision weights. ``--set`` overrides apply to every stage that has
the key's group; with ``--tag T`` the stages write to ``<out>/<size>/out-T/`` (the capture,
detect and priors outputs linked from ``out/`` when T has none of its own), so two settings
compare on one capture. Writes ``<out>/<size>/summary[-T].json``. Simulated
input: rendered RGB and depth, sampled as a time-of-flight sensor samples it.
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

import drawer_lib  # noqa: F401
from drawer_lib.bench.scenes import kitchen_scene
from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig
from drawer_lib.config.compose import compose_config
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.io.images import read_json
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.articulation import articulation_metrics
from drawer_lib.paths import ScenePaths, capture_name
from drawer_lib.synth.phone import write_polycam

ROOT = Path(__file__).resolve().parent.parent
STAGES = ["capture", "detect", "priors", "sdf", "mesh", "decompose", "articulate", "appearance", "complete", "twin"]
EXTRA = {"articulate": ["articulate.types.weights=prior"], "appearance": ["appearance_variant=movable_gs_ste"]}


def render_source(w: int, h: int, n: int, out: Path) -> float:
    """kitchen_small's layout (test split kitchen 0's camera path) at w x h x n, exact depth only."""
    cfg = compose_config(ROOT / "conf", ["scene=kitchen_small", "capture/depth=exact", "capture/mono=off",
                                         "capture/detections=off"])
    scene = kitchen_scene(OmegaConf.to_container(cfg.scene, resolve=True), "test", 0,
                          {"width": w, "height": h, "n_frames": n})
    out.mkdir(parents=True)
    t0 = time.perf_counter()
    build_capture("source", scene, to_typed(CaptureConfig, cfg.capture, "capture"), out, np.random.default_rng(0), ROOT)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="640x480x150", help="WxHxN")
    ap.add_argument("--stages", nargs="+", default=STAGES)
    ap.add_argument("--bench", type=Path, default=ROOT / "bench", help="paths.bench: the detector's weights")
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_sizes"))
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="Hydra overrides, each passed to the stages whose config group it names")
    ap.add_argument("--tag", default="", help="write the stage outputs to out-TAG/ (shared inputs linked from out/)")
    a = ap.parse_args()
    w, h, n = (int(x) for x in a.size.split("x"))
    root = a.out / a.size
    scene = f"phone_{a.size}"
    src, data = root / "source", root / "phone"
    if not (data / "transforms.json").is_file():
        t = render_source(w, h, n, src)
        write_polycam(src, data, factor=max(2, round(w / 256)))
        (root / "render_s.txt").write_text(f"{t:.1f}\n")
    conf = root / "conf" / "scene"
    conf.mkdir(parents=True, exist_ok=True)
    (conf / f"{scene}.yaml").write_text(f"source: dir\ndir: {{path: {data}, metric_scale: true, gravity: true}}\n")
    out = root / (f"out-{a.tag}" if a.tag else "out")
    if a.tag:
        for st in ("capture", "detect", "priors"):
            shared, own = root / "out" / scene / st, out / scene / st
            if shared.is_dir() and not own.exists() and st not in a.stages:
                own.parent.mkdir(parents=True, exist_ok=True)
                own.symlink_to(shared)
    common = [f"scene={scene}", f"paths.out={out}", f"paths.bench={a.bench.resolve()}",
              f"paths.reports={root / 'reports'}", f"hydra.searchpath=[file://{root / 'conf'}]"]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    sp = ScenePaths(out, scene)
    rows = []
    for st in a.stages:
        t0 = time.perf_counter()
        sets = [s for s in a.set if s.split(".")[0] == st]
        r = subprocess.run([sys.executable, "-m", f"stages.{st}", *common, *EXTRA.get(st, []), *sets], cwd=ROOT, env=env,
                           capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            print(r.stderr[-3000:], file=sys.stderr)
            raise SystemExit(f"error: stage {st} failed ({r.returncode})")
        mp = (sp.appearance_dir("movable_gs_ste") / "metrics.json") if st == "appearance" else sp.metrics(st)
        m = read_json(mp)
        rows.append({"stage": st, "wall_s": m["wall_s"], "process_s": round(wall, 1), "peak_rss_mb": m["peak_rss_mb"],
                     "threads": m.get("threads"), "working_size": m.get("working_size"), "skipped": m.get("skipped", {})})
        print(f"{a.size} {st:11s} {m['wall_s']:8.1f} s  (process {wall:7.1f} s)  peak {m['peak_rss_mb']:7.0f} MiB",
              flush=True)
    summ = {"size": a.size, "tag": a.tag, "set": a.set, "frames_written": len(read_json(data / "transforms.json")["frames"]),
            "render_s": float((root / "render_s.txt").read_text()), "stages": rows}
    if sp.parts.is_file():
        gt = read_parts(sp.capture / capture_name("gt_parts"))
        cap = load_capture(sp.capture, check_files=False)
        res, _ = articulation_metrics(read_parts(sp.parts), gt, cap.cameras(cap.test))
        summ["articulation"] = {k: res.get(k) for k in ("precision", "recall", "ea_score", "n_pred", "n_gt", "n_correct")}
        summ["detect"] = {k: v for k, v in read_json(sp.metrics("detect")).items() if k.startswith(("parts_2d", "model"))}
    if sp.metrics("twin").is_file():
        summ["twin"] = {k: v for k, v in read_json(sp.metrics("twin")).items() if isinstance(v, (int, float, str, bool))}
    (root / (f"summary-{a.tag}.json" if a.tag else "summary.json")).write_text(json.dumps(summ, indent=2))
    print(json.dumps({k: v for k, v in summ.items() if k != "stages"}, indent=1))


if __name__ == "__main__":
    main()
