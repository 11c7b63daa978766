"""The capture stage as a program: the `dir` source round trip, and bad input -> a message
naming the file, exit code 2, no partial output, previous output kept."""

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import yaml
from helpers import ROOT, render_capture, sensor_cfg

from drawer_lib.capture.config import DirSource, SceneConfig
from drawer_lib.io.capture import load_capture
from drawer_lib.io.manifest import read_manifest


def run_stage(conf, out, scene, *extra):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "stages.capture", "-cd", str(conf), f"scene={scene}",
                           f"paths.out={out}", *extra], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


@pytest.fixture
def project(tmp_path, exact_capture):
    """A copy of conf/ with a `dir` scene pointing at a copy of the tiny exact capture."""
    conf = tmp_path / "conf"
    shutil.copytree(ROOT / "conf", conf)
    src = tmp_path / "input_capture"
    shutil.copytree(exact_capture[0], src)
    (conf / "scene" / "mine.yaml").write_text(yaml.safe_dump(
        {"source": "dir", "synth": None, "video": None,
         "dir": {"path": str(src), "metric_scale": True, "gravity": True}}))
    return conf, src, tmp_path / "out"


def test_dir_source_round_trip(tmp_path, exact_capture):
    src = exact_capture[0]
    manifest, metrics = render_capture(SceneConfig(source="dir", dir=DirSource(str(src), True, True)), sensor_cfg(), tmp_path / "c")
    a, b = load_capture(src), load_capture(tmp_path / "c")
    assert [f.file_path for f in a.frames] == [f.file_path for f in b.frames]
    assert a.train == b.train and a.test == b.test and a.intrinsics == b.intrinsics
    np.testing.assert_array_equal(a.depth(5), b.depth(5))
    assert b.detections(2)[1] == a.detections(2)[1]
    assert manifest.has == {"rgb": True, "depth": True, "mono_depth": True, "mono_normal": True, "detections": True,
                            "sparse_points": False, "gt": True}
    assert manifest.world_frame["metric_scale"] and manifest.gt_part_kinds == exact_capture[1].gt_part_kinds
    assert (tmp_path / "c" / "gt" / "parts.json").read_text() == (src / "gt" / "parts.json").read_text()


def test_stage_runs_and_bad_input_keeps_previous_output(project):
    conf, src, out = project
    r = run_stage(conf, out, "mine")
    assert r.returncode == 0, r.stderr
    cap_dir = out / "mine" / "capture"
    m = json.loads((cap_dir / "metrics.json").read_text())
    assert m["n_frames"] == 12 and m["wall_s"] > 0 and m["peak_rss_mb"] > 0
    assert read_manifest(cap_dir / "manifest.json").source == "dir"
    before = (cap_dir / "transforms.json").read_text()

    (src / "images" / "frame_00003.png").unlink()
    r = run_stage(conf, out, "mine")
    assert r.returncode == 2
    assert "error:" in r.stderr and "frame_00003.png: file is missing" in r.stderr
    assert (cap_dir / "transforms.json").read_text() == before  # nothing already computed is lost
    assert sorted(p.name for p in (out / "mine").iterdir()) == ["capture"]  # no temporary left


def test_bad_input_leaves_no_output(project):
    conf, src, out = project
    t = json.loads((src / "transforms.json").read_text())
    t["frames"][2]["transform_matrix"][1][1] = 7.0
    (src / "transforms.json").write_text(json.dumps(t))
    r = run_stage(conf, out, "mine")
    assert r.returncode == 2 and "frame images/frame_00002.png: transform_matrix" in r.stderr
    assert not (out / "mine").exists() or not any((out / "mine").iterdir())


def test_bad_config_is_named(project):
    conf, _, out = project
    r = run_stage(conf, out, "kitchen_tiny", "capture.depth.dropout=3.0")
    assert r.returncode == 2 and "dropout = 3.0" in r.stderr
    r = run_stage(conf, out, "nonexistent")
    assert r.returncode != 0 and "nonexistent" in r.stderr
    r = run_stage(conf, out, "mine", "+scene.extra_key=1")
    assert r.returncode == 2 and "unknown key(s) ['extra_key']" in r.stderr
