"""A phone's RGB-D capture as ``ns-process-data polycam --use-depth`` leaves it: a camera per
frame (drifting focal length), JPEG frames with gaps in their numbering, LiDAR depth at a
quarter of the RGB's size in millimetres, Polycam's 0 / 127 / 255 confidence maps beside it,
no train / test lists. It imports through a scene file that says ``source: dir``; the depth
comes out at the RGB's size, edge-aware, with the low-confidence pixels dropped."""

import dataclasses
import json
import shutil

import numpy as np
import pytest
from helpers import render_capture, sensor_cfg
from PIL import Image

from drawer_lib.capture.config import DirSource, SceneConfig
from drawer_lib.io.rgbd import confidence_levels, upsample_depth
from drawer_lib.errors import CaptureError, ConfigError
from drawer_lib.geometry.distortion import remap, undistortion_map
from drawer_lib.io.capture import load_capture
from drawer_lib.io.manifest import read_manifest
from drawer_lib.synth import phone

S = 4  # the LiDAR map is 1 / S of the RGB's size (256 x 192 beside 1024 x 768)
DRIFT = 0.996  # odd frames' focal length, relative to the even frames'


def lidar(depth: np.ndarray) -> np.ndarray:
    return phone.lidar(depth, S)


def write_polycam(src, out, confidence: bool = True) -> None:
    phone.write_polycam(src, out, S, DRIFT, confidence=confidence)


@pytest.fixture(scope="module")
def polycam(tmp_path_factory, exact_capture):
    d = tmp_path_factory.mktemp("polycam") / "capture"
    write_polycam(exact_capture[0], d)
    return d


def far_off(got: np.ndarray, want: np.ndarray, tol: float = 0.05) -> float:
    """Fraction of the pixels valid in both whose depths differ by more than ``tol`` m."""
    ok = (got > 0) & (want > 0)
    return float(np.mean(np.abs(got[ok] - want[ok]) > tol))


def test_a_polycam_capture_imports_with_its_depth_at_the_rgbs_size(polycam, exact_capture, tmp_path):
    src = load_capture(polycam, default_test_every=8)  # full validation: the small depth maps are accepted
    assert src.per_frame_cameras and src.intrinsics.fx == pytest.approx(load_capture(exact_capture[0]).intrinsics.fx)
    assert src.depth_raw(0).shape == (18, 24) and src.depth(0).shape == (72, 96)
    manifest, metrics = render_capture(SceneConfig(source="dir", dir=DirSource(str(polycam), True, True)),
                                       sensor_cfg(), tmp_path / "c")
    cap = load_capture(tmp_path / "c")
    assert not cap.per_frame_cameras and (cap.intrinsics.width, cap.intrinsics.height) == (96, 72)
    m = read_manifest(tmp_path / "c" / "manifest.json")
    assert m.has["depth"] and m.world_frame["metric_scale"] and m.world_frame["gravity"]
    # the ground truth under the phone's frame names, its instance maps resampled with the frames
    assert m.has["gt"] and sorted(p.stem for p in (tmp_path / "c" / "gt" / "instances").glob("*.png")) == sorted(
        f.stem for f in cap.frames)
    dep = m.details["depth"]
    assert dep["source_size"] == [24, 18] and dep["frames_upsampled"] == len(cap.frames)
    assert dep["upsample"] == "edge_aware" and dep["min_confidence"] == 1 and 0 < dep["low_confidence_fraction"] < 0.3
    assert m.details["intrinsics"]["per_frame"]["n_frames_own_camera"] == sum(1 for f in cap.frames
                                                                               if int(f.stem[-5:]) % 2 == 0)
    assert metrics["resampled"] and metrics["depth_frames_upsampled"] == len(cap.frames)
    # the even frames have the capture's camera: their depth is the exact depth's LiDAR samples, the
    # low-confidence ones dropped, edge-aware upsampled; closer to the truth than nerfstudio's nearest
    truth = load_capture(exact_capture[0])
    index = {f"frame_{k + 1:05d}": k for k in range(len(truth.frames))}  # write_polycam's names
    errs = []
    for i, fr in enumerate(cap.frames):
        k = index[fr.stem]
        if k % 2:
            continue
        got, want = cap.depth(i), truth.depth(k)
        kept = np.where(src.confidence(i) >= 1, lidar(want), 0.0)
        near = upsample_depth(kept, want.shape, method="nearest")
        np.testing.assert_array_equal(got > 0, near > 0)  # a dropped sample's pixels stay without depth
        ok = (got > 0) & (near > 0) & (want > 0)
        errs.append((np.abs(got - want)[ok].mean(), np.abs(near - want)[ok].mean()))
    e_edge, e_near = np.mean(errs, 0)
    assert e_edge < 0.85 * e_near, (e_edge, e_near)
    # the odd frames were seen through their own cameras and are resampled to the capture's: their
    # images and depths line up with the truth's again (inside the border the wider view covers)
    odd = [i for i, f in enumerate(cap.frames) if index[f.stem] % 2]
    inner = (slice(2, -2), slice(2, -2))
    for i in odd:
        k = index[cap.frames[i].stem]
        got, want = cap.depth(i)[inner], truth.depth(k)[inner]
        ok = (got > 0) & (want > 0)
        assert np.abs(got - want)[ok].mean() < 1.5 * e_edge
        diff = np.abs(cap.image(i)[inner].astype(float) - truth.image(k)[inner].astype(float)).mean()
        assert diff < 6.0, diff  # of 255: JPEG and two bilinear resamplings


def test_nearest_keeps_nerfstudios_choice_and_all_confidence_keeps_every_sample(polycam, exact_capture, tmp_path):
    render_capture(SceneConfig(source="dir", dir=DirSource(str(polycam), True, True, depth_upsample="nearest",
                                                            min_confidence=0)), sensor_cfg(), tmp_path / "c")
    cap, src = load_capture(tmp_path / "c"), load_capture(polycam, default_test_every=8)
    i = next(i for i, f in enumerate(src.frames) if f.intrinsics is None)  # an even frame: no resampling
    np.testing.assert_array_equal(cap.depth(i), upsample_depth(src.depth_raw(i), (72, 96), method="nearest"))
    assert read_manifest(tmp_path / "c" / "manifest.json").details["depth"]["low_confidence_fraction"] == 0.0


def test_bad_phone_files_are_named(polycam, tmp_path):
    d = tmp_path / "c"
    shutil.copytree(polycam, d)
    tf = json.loads((d / "transforms.json").read_text())
    name = tf["frames"][2]["depth_file_path"]
    Image.fromarray(np.zeros((18, 30), np.uint16)).save(d / name)  # not the image's aspect
    with pytest.raises(CaptureError, match=r"frame_00003.png: size 30x18; a depth map must have the image's size 96x72"):
        load_capture(d, default_test_every=8)
    Image.fromarray(np.zeros((18, 24), np.uint16)).save(d / name)
    conf = tf["frames"][2]["confidence_file_path"]
    Image.fromarray(np.full((18, 24), 50, np.uint8)).save(d / conf)
    with pytest.raises(CaptureError, match=r"frame_00003.png: values \[50\] are neither levels"):
        load_capture(d, default_test_every=8)
    Image.fromarray(np.zeros((9, 12), np.uint8)).save(d / conf)
    with pytest.raises(CaptureError, match="size 12x9, expected the depth's 24x18"):
        load_capture(d, default_test_every=8)
    del tf["frames"][0]["fl_x"]
    (d / "transforms.json").write_text(json.dumps(tf))
    with pytest.raises(CaptureError, match="missing 'fl_x' .neither at the top level nor in frame ./images/frame_00001.jpg"):
        load_capture(d, default_test_every=8)
    with pytest.raises(ConfigError, match="depth_upsample"):
        DirSource("x", depth_upsample="bicubic")
    with pytest.raises(ConfigError, match="min_confidence"):
        DirSource("x", min_confidence=3)


def test_confidence_levels_read_both_encodings():
    np.testing.assert_array_equal(confidence_levels(np.array([[0, 1, 2]], np.uint8)), [[0, 1, 2]])
    np.testing.assert_array_equal(confidence_levels(np.array([[0, 127, 255]], np.uint8)), [[0, 1, 2]])
    with pytest.raises(CaptureError, match="neither"):
        confidence_levels(np.array([[0, 3]], np.uint8))


def test_edge_aware_upsampling_follows_the_colour_edge_and_invents_no_depth():
    """A near box (1 m) against a far wall (3 m), its edge at column 37 of 96 (inside a LiDAR
    cell); the colour edge coincides with the depth edge."""
    H, W = 72, 96
    truth = np.full((H, W), 3.0, np.float32)
    truth[:, :37] = 1.0
    rgb = np.zeros((H, W, 3), np.uint8)
    rgb[:, :37] = (200, 40, 40)
    rgb[:, 37:] = (40, 40, 200)
    lo = lidar(truth)
    edge = upsample_depth(lo, (H, W), rgb, "edge_aware")
    near = upsample_depth(lo, (H, W), method="nearest")
    np.testing.assert_allclose(edge, truth, atol=1e-6)  # exact where the colour says which side: no depth in between
    assert (near != truth).sum() == H  # nearest puts column 36 (in the 36-39 cell, sampled at 37-38) on the wall
    # deterministic, and equal sizes come back unchanged
    np.testing.assert_array_equal(edge, upsample_depth(lo, (H, W), rgb, "edge_aware"))
    np.testing.assert_array_equal(upsample_depth(truth, (H, W), rgb), truth)


def test_a_slope_is_interpolated_not_stepped():
    """A wall receding from 1.5 to 1.8 m across the image (1.9 cm, 1.2 % from one sample to the
    next): nearest gives stairs a cell wide, the edge-aware upsampling (one colour: one
    surface) the plane."""
    H, W = 48, 64
    truth = np.tile(np.linspace(1.5, 1.8, W, dtype=np.float32), (H, 1))
    lo = lidar(truth)
    edge = upsample_depth(lo, (H, W), np.full((H, W, 3), 128, np.uint8))
    near = upsample_depth(lo, (H, W), method="nearest")
    inner = slice(S, W - S)  # away from the border, where there is nothing to interpolate towards
    assert np.abs(edge - truth)[:, inner].max() < 1e-5 < np.abs(near - truth)[:, inner].max()
    # same_surface 0: the picked sample alone, as nearest does away from edges
    np.testing.assert_array_equal(upsample_depth(lo, (H, W), np.full((H, W, 3), 128, np.uint8), same_surface=0.0)
                                  [:, inner], near[:, inner])


def test_upsampling_extremes_invalid_samples_and_nans():
    lo = np.array([[0.0, np.nan], [np.inf, -1.0]], np.float32)  # nothing valid
    assert not upsample_depth(lo, (8, 8), np.zeros((8, 8, 3), np.uint8)).any()
    lo[0, 0] = 2.0  # one valid sample: its cell has its depth, the others none
    out = upsample_depth(lo, (8, 8), np.zeros((8, 8, 3), np.uint8))
    assert np.isfinite(out).all() and np.allclose(out[:4, :4], 2.0) and not out[4:].any() and not out[:, 4:].any()
    # colours as far apart as they get: no weight underflows to "no sample"
    rgb = np.zeros((8, 8, 3), np.uint8)
    rgb[:, 4:] = 255
    lo = np.array([[1.0, 3.0], [1.0, 3.0]], np.float32)
    out = upsample_depth(lo, (8, 8), rgb)
    assert np.allclose(out[:, :4], 1.0) and np.allclose(out[:, 4:], 3.0)
    with pytest.raises(ValueError, match="guide"):
        upsample_depth(lo, (8, 8), None, "edge_aware")
