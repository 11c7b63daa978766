"""Bad input to the stages not covered by their own test files: each ends with one line
``error: <message naming the file or key>``, exit code 2, and no output. (capture, sdf, mesh,
decompose, articulate and appearance: see tests/capture, tests/sdf, tests/perception,
tests/splat.)"""

import json
import os
import shutil
import subprocess
import sys

from helpers import run_stage


def _assert_named_error(r, *names):
    assert r.returncode == 2, (r.returncode, r.stderr[-3000:])
    last = [ln for ln in r.stderr.strip().splitlines() if ln.strip()][-1]
    assert last.startswith("error: "), last
    for n in names:
        assert n in last, (n, last)
    assert "Traceback" not in r.stderr


def test_evaluate_names_a_malformed_parts_file(tmp_path, exact_capture):
    scene = tmp_path / "out" / "kitchen_tiny"
    shutil.copytree(exact_capture[0], scene / "capture")
    (scene / "articulate").mkdir()
    parts = json.loads((scene / "capture" / "gt" / "parts.json").read_text())
    parts["parts"][0]["axis"]["direction"] = [0.0, 0.0, 0.0]
    (scene / "articulate" / "parts.json").write_text(json.dumps(parts))
    _assert_named_error(run_stage("evaluate", tmp_path), "parts.json", "axis.direction")
    assert not (scene / "evaluate").exists()


def test_report_stages_without_metrics_name_the_folder(tmp_path):
    (tmp_path / "out").mkdir()
    for stage in ("geometry_table", "ablation", "report"):
        _assert_named_error(run_stage(stage, tmp_path), str(tmp_path / "out"))
        assert not (tmp_path / "reports").exists()


def test_stability_and_simulate_name_what_is_missing(tmp_path):
    (tmp_path / "out" / "kitchen_tiny").mkdir(parents=True)
    _assert_named_error(run_stage("stability", tmp_path), "scene.xml", "twin")
    assert not (tmp_path / "out" / "kitchen_tiny" / "stability").exists()
    _assert_named_error(run_stage("simulate", tmp_path), "scene.xml")
    _assert_named_error(run_stage("stability", tmp_path, "stability.integrators=[verlet]"), "verlet")


def test_robot_names_what_is_missing_and_a_bad_key(tmp_path):
    (tmp_path / "out" / "kitchen_tiny").mkdir(parents=True)
    _assert_named_error(run_stage("robot", tmp_path), "scene.xml", "twin")
    assert not (tmp_path / "out" / "kitchen_tiny" / "robot").exists()
    _assert_named_error(run_stage("robot", tmp_path, "robot.open_fraction=1.5"), "open_fraction")


def test_misspelt_scene_key_is_named(tmp_path, exact_capture):
    import yaml

    from helpers import ROOT

    conf = tmp_path / "conf"  # -cd adds a config dir after conf/: the scene needs a new name
    (conf / "scene").mkdir(parents=True)
    scene = yaml.safe_load((ROOT / "conf" / "scene" / "kitchen_tiny.yaml").read_text())
    scene["synth"]["camera"]["n_frame"] = scene["synth"]["camera"].pop("n_frames")
    (conf / "scene" / "typo.yaml").write_text(yaml.safe_dump(scene))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-m", "stages.capture", "-cd", str(conf), "scene=typo",
                        f"paths.out={tmp_path / 'out'}"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    _assert_named_error(r, "n_frame", "typo.yaml")
    assert not (tmp_path / "out" / "typo").exists()


def _bad_parts(tmp_path, exact_capture, edit):
    scene = tmp_path / "out" / "kitchen_tiny"
    shutil.copytree(exact_capture[0], scene / "capture")
    (scene / "articulate").mkdir()
    parts = json.loads((scene / "capture" / "gt" / "parts.json").read_text())
    edit(parts["parts"])
    (scene / "articulate" / "parts.json").write_text(json.dumps(parts))
    return scene


def test_complete_and_twin_name_a_bad_part_and_write_nothing(tmp_path, exact_capture):
    """A zero axis, a NaN front centre, an empty or negative range in parts.json: each an error
    naming parts.json and the part's key, and no complete/ or twin/ folder."""
    cases = {"axis.direction": lambda ps: ps[0]["axis"].update(direction=[0.0, 0.0, 0.0]),
             "front.center": lambda ps: ps[1]["front"].update(center=[float("nan"), 0.0, 0.0]),
             "limits": lambda ps: ps[2].update(limits=[0.5, 0.5])}
    for k, (key, edit) in enumerate(cases.items()):
        root = tmp_path / f"case{k}"
        scene = _bad_parts(root, exact_capture, edit)
        for stage in ("complete", "twin"):
            _assert_named_error(run_stage(stage, root), "parts.json", key)
            assert not (scene / stage).exists()
