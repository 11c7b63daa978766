#!/usr/bin/env python
"""The metric scale of a plain video (:mod:`drawer_lib.sfm.scale`) on benchmark kitchens: each
kitchen of a split is rendered by ``synth``, encoded as H.264, and goes through the video source
(frame selection, pycolmap SfM, the gravity frame, the scale estimate); the estimate is scored
against the true cameras after a similarity alignment (``scale_to_reference``: 1.0 is exact).
Reports per kitchen the error of the estimate and of the median-depth guess alone, the cues
used and the uncertainty the estimate states, and per split the median and worst error and
how many kitchens are within 10 %. Tune on ``train``, report ``test``.

    python scripts/bench_video_scale.py --split train --kitchens 0 1 2 3 4 5 6 7
    python scripts/bench_video_scale.py --split test

Writes ``<out>/<split>/summary.json`` (and keeps each kitchen's captures under ``<out>`` so a
rerun only scores). Simulated input: rendered frames, encoded; the cameras' heights are the
generator's (about 1.4 m, close to the camera-height prior), which favours that cue.
"""

import argparse
import json
import math
import shutil
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from drawer_lib.bench.kitchens import kitchen_scene
from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig, SceneConfig, VideoSource
from drawer_lib.config.compose import compose_config
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.io.manifest import read_manifest
from drawer_lib.sfm.video import write_video

ROOT = Path(__file__).resolve().parent.parent


def capture(scene: SceneConfig, overrides: list[str], out: Path) -> dict:
    cap = to_typed(CaptureConfig, compose_config(ROOT / "conf", overrides).capture, "capture")
    out.mkdir(parents=True)
    manifest, metrics = build_capture(out.parent.name, scene, cap, out, np.random.default_rng(0), ROOT)
    (out / "bench_metrics.json").write_text(json.dumps(metrics))
    return metrics


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--split", default="test", choices=["train", "test"])
    ap.add_argument("--kitchens", type=int, nargs="+", default=list(range(20)))
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_video_scale"))
    a = ap.parse_args()
    base = OmegaConf.to_container(compose_config(ROOT / "conf", ["scene=kitchen_small"]).scene, resolve=True)
    rows = []
    for k in a.kitchens:
        d = a.out / f"{a.split}_{k}"
        if not (d / "video" / "bench_metrics.json").is_file():
            shutil.rmtree(d, ignore_errors=True)
            capture(kitchen_scene(base, a.split, k), ["capture/depth=off", "capture/mono=off",
                                                      "capture/detections=off"], d / "truth")
            cap = load_capture(d / "truth")
            write_video(d / "video.mp4", [cap.image(i) for i in range(len(cap.frames))], fps=10, quality=10)
            capture(SceneConfig(source="video", video=VideoSource(str(d / "video.mp4"), str(d / "truth"))), [],
                    d / "video")
        m = json.loads((d / "video" / "bench_metrics.json").read_text())
        sc = read_manifest(d / "video" / "manifest.json").world_frame["scale"]
        true = m["scale_to_reference"]  # true = this x the estimate: 1.0 is exact
        guess = sc["cues"]["median_depth"]["factor"] / sc["factor"]  # the median-depth guess, relative
        row = {"kitchen": k, "error": 1.0 / true - 1.0,
               "guess_error": guess / true - 1.0, "sigma_log": sc["sigma_log"],
               "cues": "+".join(c for c, v in sc["cues"].items() if v.get("used")),
               "metric": bool(read_manifest(d / "video" / "manifest.json").world_frame["metric_scale"])}
        rows.append(row)
        print(f"{a.split} {k:2d}: estimate {100 * row['error']:+6.1f} %  (stated 1 sigma {100 * (math.exp(row['sigma_log']) - 1):.0f} %, "
              f"{row['cues']})   median-depth guess {100 * row['guess_error']:+6.1f} %", flush=True)
    err = np.abs([r["error"] for r in rows])
    gerr = np.abs([r["guess_error"] for r in rows])
    summ = {"split": a.split, "n": len(rows), "median_abs_error": float(np.median(err)), "max_abs_error": float(err.max()),
            "within_10pct": int((err <= 0.10).sum()), "guess_median_abs_error": float(np.median(gerr)),
            "guess_max_abs_error": float(gerr.max()), "guess_within_10pct": int((gerr <= 0.10).sum()),
            "n_metric": int(sum(r["metric"] for r in rows)),
            "within_stated_sigma": int(sum(abs(math.log(1 + r["error"])) <= r["sigma_log"] for r in rows)), "rows": rows}
    (a.out / a.split).mkdir(parents=True, exist_ok=True)
    (a.out / a.split / "summary.json").write_text(json.dumps(summ, indent=2))
    print(f"\n| {a.split} ({len(rows)} kitchens) | median error | worst | within 10 % | within the stated 1 sigma |\n"
          f"|---|---|---|---|---|\n"
          f"| estimate | {100 * summ['median_abs_error']:.1f} % | {100 * summ['max_abs_error']:.1f} % | "
          f"{summ['within_10pct']}/{len(rows)} | {summ['within_stated_sigma']}/{len(rows)} |\n"
          f"| median-depth guess (before) | {100 * summ['guess_median_abs_error']:.1f} % | "
          f"{100 * summ['guess_max_abs_error']:.1f} % | {summ['guess_within_10pct']}/{len(rows)} | – |")


if __name__ == "__main__":
    main()
