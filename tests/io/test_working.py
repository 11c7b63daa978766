"""Working resolutions (drawer_lib/io/working.py): the reductions against slow per-block
references, the camera's exactness, a capture read through it, and the stages that use it."""

import json

import numpy as np
import pytest
from helpers import add_overlays, gt_mesh_project, run_stage, scene_paths

from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Intrinsics, pixel_dirs
from drawer_lib.io.capture import load_capture
from drawer_lib.io.working import (WorkingCapture, at_working_size, block_centre, block_median, box_mean,
                                   scale_intrinsics, working_factor)


def _ref_blocks(a, f):
    h, w = a.shape[0] // f, a.shape[1] // f
    return [[a[i * f:(i + 1) * f, j * f:(j + 1) * f].reshape(f * f, *a.shape[2:]) for j in range(w)] for i in range(h)]


def test_working_factor():
    assert working_factor(1920, 1440, 640) == 3 and working_factor(1280, 960, 640) == 2
    assert working_factor(640, 480, 640) == 1 and working_factor(641, 480, 640) == 2
    assert working_factor(96, 72, None) == 1 and working_factor(10_000, 10, 8) == 1250
    with pytest.raises(ConfigError, match="max_side = 4"):
        working_factor(100, 100, 4)


@pytest.mark.parametrize("f", [1, 2, 3])
def test_box_mean_and_centre_match_per_block_references(f, rng):
    a = rng.integers(0, 256, (13, 17, 3)).astype(np.uint8)  # remainders on both sides
    ref = np.array([[b.astype(np.float64).mean(0) for b in row] for row in _ref_blocks(a, f)])
    assert box_mean(a, f).shape == (13 // f, 17 // f, 3)
    np.testing.assert_allclose(box_mean(a, f), ref, rtol=0, atol=1e-4)
    lab = rng.integers(0, 5, (13, 17)).astype(np.uint16)
    ref_c = np.array([[b.reshape(f, f)[f // 2, f // 2] for b in row] for row in _ref_blocks(lab, f)])
    np.testing.assert_array_equal(block_centre(lab, f), ref_c)


@pytest.mark.parametrize("f", [2, 3, 4])
def test_block_median_matches_reference_with_invalid_values(f, rng):
    d = rng.uniform(0.3, 4.0, (17, 21)).astype(np.float32)
    holes = rng.random(d.shape)
    d[holes < 0.3] = 0.0
    d[holes > 0.95] = np.nan
    d[: f, : f] = 0.0  # a block without depth
    out = block_median(d, f)
    for i, row in enumerate(_ref_blocks(d, f)):
        for j, b in enumerate(row):
            v = np.sort(b[np.isfinite(b) & (b > 0)])
            want = v[(len(v) - 1) // 2] if len(v) >= max(1, int(np.ceil(0.25 * f * f))) else 0.0
            assert out[i, j] == pytest.approx(want), (i, j, b)
    assert out[0, 0] == 0 and np.isfinite(out).all()


def test_block_median_keeps_one_side_of_a_depth_edge():
    """A block across a step from 1 m to 3 m gets a depth of the samples, not a flying 2 m."""
    d = np.array([[1.0, 3.0], [1.0, 3.0]], np.float32)
    assert block_median(d, 2)[0, 0] == 1.0 and box_mean(d, 2)[0, 0] == 2.0
    assert block_median(np.full((4, 4), 1e-6, np.float32), 2).min() == pytest.approx(1e-6)  # tiny scales survive
    assert block_median(np.full((4, 4), 1e6, np.float32), 4)[0, 0] == pytest.approx(1e6)


@pytest.mark.parametrize("f", [2, 3])
def test_scaled_camera_sees_each_block_centre(f):
    """The working pixel (k + 0.5) looks along the ray through the centre of full block k,
    at f k + f / 2 in the full image (the pixel convention of Intrinsics)."""
    full = Intrinsics(510.3, 498.7, 321.9, 237.2, 641, 481)
    w = scale_intrinsics(full, f)
    assert (w.width, w.height) == (641 // f, 481 // f)
    ii, jj = np.meshgrid(np.arange(w.height), np.arange(w.width), indexing="ij")
    d = pixel_dirs(w, ii.ravel(), jj.ravel())
    u = full.fx * d[:, 0] / d[:, 2] + full.cx
    v = full.fy * d[:, 1] / d[:, 2] + full.cy
    np.testing.assert_allclose(u, f * jj.ravel() + f / 2, atol=1e-9)
    np.testing.assert_allclose(v, f * ii.ravel() + f / 2, atol=1e-9)


def test_capture_at_working_size(exact_capture):
    cap = load_capture(exact_capture[0])
    assert at_working_size(cap, None) is cap and at_working_size(cap, 96) is cap
    w = at_working_size(cap, 48)
    assert isinstance(w, WorkingCapture) and w.factor == 2 and at_working_size(w, 48).factor == 2
    assert (w.intrinsics.width, w.intrinsics.height) == (48, 36) and w.camera(0).intrinsics == w.intrinsics
    assert w.train == cap.train and w.test == cap.test and w.root == cap.root
    img, dep = w.image(0), w.depth(0)
    assert img.shape == (36, 48, 3) and img.dtype == np.uint8 and dep.shape == (36, 48)
    np.testing.assert_allclose(img, box_mean(cap.image(0), 2), atol=0.5)
    n = w.mono_normal(0)
    assert n.shape == (36, 48, 3) and np.allclose(np.linalg.norm(n, axis=-1), 1, atol=1e-5)
    assert w.mono_depth(0).shape == (36, 48)
    for i in range(len(cap.frames)):
        labels, rows = w.detections(i)
        assert labels.shape == (36, 48)
        assert {r["id"] for r in rows} == set(np.unique(labels).tolist()) - {0}


def test_stages_record_and_use_the_working_size(tmp_path, exact_capture):
    """decompose and articulate at half the capture's size: views, masks and the recorded size."""
    gt_mesh_project(tmp_path, exact_capture[0])
    add_overlays(tmp_path, priors=False)
    for st, extra in (("decompose", ["decompose.max_side=48"]),
                      ("articulate", ["articulate.max_side=48", "articulate.types.weights=prior"])):
        r = run_stage(st, tmp_path, *extra)
        assert r.returncode == 0, r.stderr[-3000:]
        m = json.loads(scene_paths(tmp_path).metrics(st).read_text())
        assert m["working_size"] == [48, 36] and m["working_factor"] == 2
    seg = json.loads(scene_paths(tmp_path).file("decompose", "segments").read_text())
    assert seg["segments"], "no segment found at the working size"
    r = run_stage("decompose", tmp_path, "decompose.max_side=4")
    assert r.returncode == 2 and "decompose.max_side = 4" in r.stderr
