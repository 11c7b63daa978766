"""A capture as nerfstudio's ns-process-data writes it from COLMAP (OPENCV distortion, JPEG
frames, applied_transform, no splits) imports through a scene file that only says
``source: dir`` and its path: undistorted to a pinhole camera, recorded in the manifest."""

import json

import numpy as np
import pytest
from helpers import NS_DIST, render_capture, sensor_cfg, write_ns_capture

from drawer_lib.capture.config import DirSource, SceneConfig
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import CaptureError, ConfigError
from drawer_lib.geometry.camera import pixel_dirs
from drawer_lib.geometry.distortion import remap
from drawer_lib.io.capture import load_capture
from drawer_lib.io.manifest import read_manifest


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(255.0**2 / np.mean((a.astype(float) - b.astype(float)) ** 2)))


@pytest.fixture(scope="module")
def ns_capture(tmp_path_factory, exact_capture):
    d = tmp_path_factory.mktemp("ns") / "capture"
    write_ns_capture(exact_capture[0], d)
    return d


def test_minimal_scene_file_and_misspelt_keys():
    sc = to_typed(SceneConfig, {"source": "dir", "dir": {"path": "data/x"}}, "conf/scene/x.yaml:", strict=False)
    assert sc.dir == DirSource("data/x", False, False) and sc.synth is None and sc.video is None
    assert to_typed(SceneConfig, {"source": "synth"}, "s:", strict=False).synth.camera.n_frames == 48  # defaults
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['pth'\]"):
        to_typed(SceneConfig, {"source": "dir", "dir": {"pth": "data/x"}}, "conf/scene/x.yaml:", strict=False)
    with pytest.raises(ConfigError, match="no 'dir' block"):
        to_typed(SceneConfig, {"source": "dir"}, "conf/scene/x.yaml:", strict=False)


def test_distorted_capture_is_undistorted_at_import(ns_capture, exact_capture, tmp_path):
    src = load_capture(ns_capture, check_files=False, default_test_every=8)
    assert src.intrinsics.dist == NS_DIST and src.frames[0].file_path.endswith(".jpg")
    manifest, metrics = render_capture(SceneConfig(source="dir", dir=DirSource(str(ns_capture))), sensor_cfg(),
                                       tmp_path / "c")
    cap = load_capture(tmp_path / "c")  # full validation
    it = cap.intrinsics
    assert metrics["undistorted"] and not it.has_distortion and (it.width, it.height) == (96, 72)
    assert all(f.file_path.startswith("images/") and f.file_path.endswith(".png") for f in cap.frames)
    assert len(cap.test) == len(cap.frames) // 8 and cap.train and cap.test  # no split in the input: every 8th
    tf = json.loads((tmp_path / "c" / "transforms.json").read_text())
    assert tf["camera_model"] == "PINHOLE" and "k1" not in tf and tf["applied_transform"][1] == [0.0, 0.0, 1.0, 0.0]
    m = read_manifest(tmp_path / "c" / "manifest.json")
    cam = m.details["intrinsics"]
    assert cam["undistorted"] and cam["camera_model"] == "OPENCV" and tuple(cam["distortion"]) == NS_DIST
    assert not m.has["depth"] and "has no depth" in m.lacks["depth"]
    # the undistorted images are the original pinhole renders seen by the new pinhole camera
    ref = load_capture(exact_capture[0])
    ri = ref.intrinsics
    d = pixel_dirs(it)
    rows, cols = d[..., 1] * ri.fy + ri.cy - 0.5, d[..., 0] * ri.fx + ri.cx - 0.5
    for k in (0, 5, 11):
        want = remap(ref.image(k), rows, cols)
        got, raw = cap.image(k), src.image(k)
        assert psnr(got, want) > 27.0, psnr(got, want)
        assert psnr(got, want) > psnr(raw, want) + 5.0  # far closer than the distorted frame


def test_per_frame_cameras_and_other_models_are_named(ns_capture, tmp_path):
    import shutil

    d = tmp_path / "c"
    shutil.copytree(ns_capture, d)
    tf = json.loads((d / "transforms.json").read_text())
    tf["frames"][3]["fl_x"] = 99.0  # zoomed in: it sees too little of the capture's view to be resampled to it
    (d / "transforms.json").write_text(json.dumps(tf))
    with pytest.raises(CaptureError, match=r"frame images/frame_00004.jpg's camera \(fl_x 99.*leaves 62.6 x 0.0 px"):
        load_capture(d, check_files=False, default_test_every=8)
    tf["frames"][3]["fl_x"] = tf["fl_x"] * 0.995  # a phone's focal length drifts: resampled on import
    (d / "transforms.json").write_text(json.dumps(tf))
    cap = load_capture(d, check_files=False, default_test_every=8)
    assert cap.per_frame_cameras and cap.frame_intrinsics(3).fx == tf["fl_x"] * 0.995 and cap.intrinsics.fx == tf["fl_x"]
    tf["frames"][3]["k1"] = 0.2
    (d / "transforms.json").write_text(json.dumps(tf))
    with pytest.raises(CaptureError, match="frame images/frame_00004.jpg has its own lens model"):
        load_capture(d, check_files=False, default_test_every=8)
    del tf["frames"][3]["fl_x"], tf["frames"][3]["k1"]
    tf["k3"] = 0.01
    (d / "transforms.json").write_text(json.dumps(tf))
    with pytest.raises(CaptureError, match="k3"):
        load_capture(d, check_files=False, default_test_every=8)
