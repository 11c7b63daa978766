"""Slow checks on the larger presets (`pytest -m slow`): they render into valid captures with
every kind of part, and the video source meets its pose targets on kitchen_medium too."""

import pytest
from helpers import load_scene, render_capture, sensor_cfg

from drawer_lib.capture.config import SceneConfig, VideoSource
from drawer_lib.io.capture import load_capture
from drawer_lib.io.parts import read_parts
from drawer_lib.sfm.video import write_video

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("scene", ["kitchen_small", "kitchen_medium", "kitchen_large"])
def test_preset_renders_a_valid_capture(scene, tmp_path):
    manifest, metrics = render_capture(load_scene(scene), sensor_cfg(), tmp_path / "c")
    cap = load_capture(tmp_path / "c")  # full validation of every file
    parts = read_parts(tmp_path / "c" / "gt" / "parts.json")
    fams = {p.extra["family"] for p in parts.parts}
    assert {"drawer", "door", "flap", "sliding"} <= fams
    assert len(parts.ignore_boxes) >= 1
    assert manifest.n_frames == len(cap.frames) and 0.85 < metrics["depth_valid_fraction"] < 0.99


def test_video_source_targets_on_kitchen_medium(tmp_path):
    render_capture(load_scene("kitchen_medium"), sensor_cfg(depth="exact", mono="off", detections="off"), tmp_path / "truth")
    cap = load_capture(tmp_path / "truth")
    write_video(tmp_path / "v.mp4", [cap.image(i) for i in range(len(cap.frames))], quality=10)
    _, m = render_capture(SceneConfig(source="video", video=VideoSource(str(tmp_path / "v.mp4"), str(tmp_path / "truth"))),
                          sensor_cfg(), tmp_path / "v")
    assert m["registered_fraction"] >= 0.95
    assert m["pose_rot_err_median_deg"] <= 0.5 and m["pose_center_err_rel"] <= 0.01
