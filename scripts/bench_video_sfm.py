#!/usr/bin/env python
"""Benchmark of the video source: `synth` renders a kitchen, the frames are encoded as H.264,
and the video goes through frame selection + pycolmap SfM; the recovered cameras are scored
against the true ones after a similarity alignment.

    python scripts/bench_video_sfm.py                       # kitchen_small, best quality
    python scripts/bench_video_sfm.py --quality 10 8 6 --scene kitchen_medium
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from helpers import load_scene, render_capture, sensor_cfg  # noqa: E402

from drawer_lib.capture.config import SceneConfig, VideoSource  # noqa: E402
from drawer_lib.io.capture import load_capture  # noqa: E402
from drawer_lib.report.markdown import md_row, md_table  # noqa: E402
from drawer_lib.sfm.video import write_video  # noqa: E402

COLS = ["video_frames_read", "video_frames_kept", "video_frames_registered", "registered_fraction",
        "pose_rot_err_median_deg", "pose_center_err_median_m", "pose_center_err_rel", "gravity_err_deg",
        "scale_to_reference", "sfm_points", "sfm_s"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--quality", type=float, nargs="+", default=[10.0], help="imageio-ffmpeg quality (0-10)")
    ap.add_argument("--matcher", default="sequential", choices=["sequential", "exhaustive"])
    a = ap.parse_args()
    scene = load_scene(a.scene)
    with tempfile.TemporaryDirectory(prefix="bench_video_") as tmp:
        d = Path(tmp)
        t = time.perf_counter()
        render_capture(scene, sensor_cfg(depth="exact", mono="off", detections="off"), d / "truth")
        print(f"rendered {a.scene} in {time.perf_counter() - t:.1f} s")
        cap = load_capture(d / "truth")
        frames = [cap.image(i) for i in range(len(cap.frames))]
        print(md_table(["quality", "MB", *COLS], []), end="")  # the rows follow as they are measured
        for q in a.quality:
            vid = d / f"q{q:g}.mp4"
            write_video(vid, frames, fps=10, quality=q)
            vs = SceneConfig(source="video", video=VideoSource(str(vid), str(d / "truth")))
            _, m = render_capture(vs, sensor_cfg(matcher=a.matcher), d / f"cap_q{q:g}")
            mb = vid.stat().st_size / 1e6
            print(md_row([f"{q:g}", f"{mb:.2f}", *(f"{m.get(c, np.nan):.4g}" for c in COLS)]))


if __name__ == "__main__":
    main()
