#!/usr/bin/env python
"""Benchmark of the video source: `synth` renders a kitchen, the frames are encoded as H.264,
and the video goes through frame selection + pycolmap SfM; the recovered cameras are scored
against the true ones after a similarity alignment.

    python scripts/bench_video_sfm.py                       # kitchen_small, best quality
    python scripts/bench_video_sfm.py --quality 10 8 6 --scene kitchen_medium
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig, SceneConfig, VideoSource
from drawer_lib.config.compose import compose_config
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.report.markdown import md_row, md_table
from drawer_lib.sfm.video import write_video

ROOT = Path(__file__).resolve().parent.parent

COLS = ["video_frames_read", "video_frames_kept", "video_frames_registered", "registered_fraction",
        "pose_rot_err_median_deg", "pose_center_err_median_m", "pose_center_err_rel", "gravity_err_deg",
        "scale_to_reference", "sfm_points", "sfm_s"]


def capture(scene: SceneConfig, overrides: list[str], out: Path) -> dict:
    """The capture of ``scene`` with the capture config composed with ``overrides``; its metrics."""
    cap = to_typed(CaptureConfig, compose_config(ROOT / "conf", overrides).capture, "capture")
    out.mkdir(parents=True)
    return build_capture("bench_video", scene, cap, out, np.random.default_rng(0), ROOT)[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--quality", type=float, nargs="+", default=[10.0], help="imageio-ffmpeg quality (0-10)")
    ap.add_argument("--matcher", default="sequential", choices=["sequential", "exhaustive"])
    a = ap.parse_args()
    scene = to_typed(SceneConfig, compose_config(ROOT / "conf", [f"scene={a.scene}"]).scene, f"conf/scene/{a.scene}.yaml:")
    with tempfile.TemporaryDirectory(prefix="bench_video_") as tmp:
        d = Path(tmp)
        t = time.perf_counter()
        capture(scene, ["capture/depth=exact", "capture/mono=off", "capture/detections=off"], d / "truth")
        print(f"rendered {a.scene} in {time.perf_counter() - t:.1f} s")
        cap = load_capture(d / "truth")
        frames = [cap.image(i) for i in range(len(cap.frames))]
        print(md_table(["quality", "MB", *COLS], []), end="")  # the rows follow as they are measured
        for q in a.quality:
            vid = d / f"q{q:g}.mp4"
            write_video(vid, frames, fps=10, quality=q)
            vs = SceneConfig(source="video", video=VideoSource(str(vid), str(d / "truth")))
            m = capture(vs, [f"capture.video.matcher={a.matcher}"], d / f"cap_q{q:g}")
            mb = vid.stat().st_size / 1e6
            print(md_row([f"{q:g}", f"{mb:.2f}", *(f"{m.get(c, np.nan):.4g}" for c in COLS)]))


if __name__ == "__main__":
    main()
