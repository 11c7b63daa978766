"""The capture format: round trip, and every kind of bad input gets an error naming the file."""

import json
import shutil

import numpy as np
import pytest
from PIL import Image

from drawer_lib.errors import CaptureError
from drawer_lib.io.capture import Capture, load_capture, split_every, write_transforms
from drawer_lib.io.images import read_depth, write_depth


@pytest.fixture
def cap_dir(tmp_path, exact_capture):
    src, _, _ = exact_capture
    dst = tmp_path / "cap"
    shutil.copytree(src, dst)
    return dst


def edit_transforms(d, fn):
    p = d / "transforms.json"
    t = json.loads(p.read_text())
    fn(t)
    p.write_text(json.dumps(t))


def test_round_trip(cap_dir, tmp_path):
    cap = load_capture(cap_dir)
    assert len(cap.frames) == 12 and cap.test == [4] and len(cap.train) == 11
    assert all(cap.has(k) for k in ("depth_file_path", "mono_depth_file_path", "mono_normal_file_path", "detections_path"))
    # write the same capture elsewhere (files copied) and read it back: identical
    other = tmp_path / "other"
    shutil.copytree(cap_dir, other)
    cap2 = Capture(other, cap.intrinsics, cap.frames, cap.train, cap.test, cap.depth_unit_scale_factor, cap.extra)
    write_transforms(cap2)
    back = load_capture(other)
    assert back.intrinsics == cap.intrinsics and back.train == cap.train and back.test == cap.test
    for a, b in zip(back.frames, cap.frames):
        np.testing.assert_array_equal(a.c2w_gl, b.c2w_gl)
        assert a.file_path == b.file_path and a.depth_file_path == b.depth_file_path
    np.testing.assert_array_equal(back.image(3), cap.image(3))
    # OpenCV world-to-camera puts the scene in front of the camera (z > 0)
    z = back.depth(0)
    assert (z > 0).mean() > 0.9
    assert back.w2c_all().shape == (12, 4, 4)


def test_depth_png_round_trip(tmp_path):
    d = np.array([[0.0, 1.2344, np.nan], [np.inf, -1.0, 70.0]])
    write_depth(tmp_path / "d.png", d, 0.001)
    back = read_depth(tmp_path / "d.png", 0.001)
    np.testing.assert_allclose(back, [[0, 1.234, 0], [0, 0, 0]], atol=1e-6)  # invalid and out-of-range -> 0


def test_split_every():
    tr, te = split_every(10, 8)
    assert te == [4] and len(tr) == 9
    with pytest.raises(ValueError):
        split_every(10, 1)


BAD_CASES = {
    "missing image": (lambda d: (d / "images" / "frame_00003.png").unlink(), "frame_00003.png: file is missing"),
    "truncated image": (lambda d: (d / "images" / "frame_00005.png").write_bytes(
        (d / "images" / "frame_00005.png").read_bytes()[:60]), "frame_00005.png: unreadable image"),
    "wrong image size": (lambda d: Image.new("RGB", (10, 10)).save(d / "images" / "frame_00002.png"), "frame_00002.png: size 10x10"),
    "non-finite transform": (lambda d: edit_transforms(d, lambda t: t["frames"][7]["transform_matrix"][0].__setitem__(3, float("nan"))),
                             "frame images/frame_00007.png: transform_matrix has non-finite"),
    "non-rigid transform": (lambda d: edit_transforms(d, lambda t: t["frames"][1]["transform_matrix"][0].__setitem__(0, 1.5)),
                            "frame images/frame_00001.png: transform_matrix rotation block is not orthonormal"),
    "empty test split": (lambda d: edit_transforms(d, lambda t: t.__setitem__("test_filenames", [])), "test_filenames is empty"),
    "unknown split frame": (lambda d: edit_transforms(d, lambda t: t["train_filenames"].append("images/nope.png")), "names 'images/nope.png'"),
    "duplicate frame": (lambda d: edit_transforms(d, lambda t: t["frames"].append(t["frames"][0])), "repeats file_path"),
    "no frames": (lambda d: edit_transforms(d, lambda t: t.__setitem__("frames", [])), "no frames"),
    "bad intrinsics": (lambda d: edit_transforms(d, lambda t: t.__setitem__("fl_x", -3)), "fl_x = -3 must be positive"),
    "bad camera model": (lambda d: edit_transforms(d, lambda t: t.__setitem__("camera_model", "FISHEYE")), "camera_model 'FISHEYE'"),
    "missing transforms": (lambda d: (d / "transforms.json").unlink(), "transforms.json: file is missing"),
    "broken json": (lambda d: (d / "transforms.json").write_text("{"), "not valid JSON"),
    "8-bit depth": (lambda d: Image.new("L", (96, 72)).save(d / "depth" / "frame_00004.png"), "frame_00004.png: expected a 16-bit"),
    "bad mono normal": (lambda d: np.save(d / "mono_normal" / "frame_00006.npy", np.zeros((72, 96, 3), np.float32)),
                        "frame_00006.npy: dtype float32"),
    "unlisted detection id": (lambda d: (d / "detections" / "frame_00008.json").write_text("[]"), "frame_00008.png: ids"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_input_is_named(cap_dir, case):
    mutate, message = BAD_CASES[case]
    mutate(cap_dir)
    with pytest.raises(CaptureError) as e:
        load_capture(cap_dir)
    assert message in str(e.value), str(e.value)


def test_missing_splits_can_be_derived(cap_dir):
    edit_transforms(cap_dir, lambda t: (t.pop("train_filenames"), t.pop("test_filenames")))
    with pytest.raises(CaptureError, match="no train_filenames"):
        load_capture(cap_dir)
    cap = load_capture(cap_dir, default_test_every=4)
    assert cap.test == [2, 6, 10]
