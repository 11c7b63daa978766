"""The detect and priors stages' outputs read in place of the capture's own files: present,
removed, a frame missing, the manifest that says so; `capture` and `none` as stages."""

import json
import shutil

import numpy as np
import pytest
from helpers import run_stage, scene_paths

from drawer_lib.errors import CaptureError
from drawer_lib.io.capture import load_capture
from drawer_lib.io.overlay import apply_overlay, capture_manifest, write_overlay


def test_an_overlay_replaces_and_removes_files(tmp_path, exact_capture):
    cap = load_capture(exact_capture[0])
    f0 = cap.frames[0]
    ov = tmp_path / "detect"
    (ov / "detections").mkdir(parents=True)
    frames = {}
    for f in cap.frames:
        np.save(ov / "detections" / f"{f.stem}.npy", np.zeros(1))
        frames[f.file_path] = {"detections_path": f"detections/{f.stem}.png"}
    write_overlay(ov / "detect.json", "detect", "test", {"detections": {"has": True, "details": {"k": 1}}}, frames)
    c2 = apply_overlay(cap, ov / "detect.json")
    assert (c2.root / c2.frames[0].detections_path).resolve() == (ov / "detections" / f"{f0.stem}.png").resolve()
    assert c2.frames[0].mono_depth_file_path == f0.mono_depth_file_path  # other modalities untouched
    assert capture_manifest(c2).details["detections"] == {"k": 1, "stage": "detect", "model": "test"}
    # a modality the model did not give is removed, with its reason in the manifest
    write_overlay(ov / "priors.json", "priors", "none", {"mono_depth": {"has": False, "lacks": "priors.model = none"}}, {})
    c3 = apply_overlay(cap, ov / "priors.json")
    assert not c3.has("mono_depth_file_path") and c3.has("mono_normal_file_path")
    man = capture_manifest(c3)
    assert man.missing("mono_depth") == "capture has no mono_depth: priors: priors.model = none"
    # an index of another capture: the frame is named
    del frames[f0.file_path]
    write_overlay(ov / "detect.json", "detect", "test", {"detections": {"has": True}}, frames)
    with pytest.raises(CaptureError, match=f0.file_path):
        apply_overlay(cap, ov / "detect.json")
    with pytest.raises(CaptureError, match="run the detect stage first"):
        apply_overlay(cap, tmp_path / "nowhere" / "detect.json")
    with pytest.raises(ValueError, match="no reason"):
        write_overlay(ov / "x.json", "detect", "test", {"detections": {"has": False}}, {})


def test_capture_and_none_as_stages(tmp_path, exact_capture):
    sp = scene_paths(tmp_path)
    shutil.copytree(exact_capture[0], sp.capture)
    for st in ("detect", "priors"):
        r = run_stage(st, tmp_path)
        assert r.returncode == 0, r.stderr[-3000:]
    cap = load_capture(sp.capture)
    c2 = apply_overlay(apply_overlay(cap, sp.file("detect", "index")), sp.file("priors", "index"))
    for i in (0, len(cap.frames) - 1):
        assert np.array_equal(c2.detections(i)[0], cap.detections(i)[0])
        assert c2.detections(i)[1] == cap.detections(i)[1]
        assert np.array_equal(c2.mono_depth(i), cap.mono_depth(i))
    m = json.loads(sp.metrics("detect").read_text())
    # perfect detections find every part; their masks of fixed fronts count against precision
    assert m["parts_2d_recall"] > 0.95 and 0.5 < m["parts_2d_precision"] < 1.0  # (a sliver at an image border: IoU < 0.5)
    r = run_stage("detect", tmp_path, "detect.model=none")
    assert r.returncode == 0, r.stderr[-3000:]
    assert not apply_overlay(cap, sp.file("detect", "index")).has("detections_path")
    assert sorted(p.name for p in sp.file("detect", "detections").iterdir()) == []  # an empty output, never a missing one
    r = run_stage("detect", tmp_path, "detect.model=yolo")
    assert r.returncode == 2 and "detect.model" in r.stderr.strip().splitlines()[-1]


def test_auto_takes_the_captures_own_or_else_the_builtin_detector(tmp_path, exact_capture):
    sp = scene_paths(tmp_path)
    shutil.copytree(exact_capture[0], sp.capture)
    r = run_stage("detect", tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads(sp.metrics("detect").read_text())
    assert m["model"] == "capture" and m["chosen"] == "auto: the capture has detections"
    man = json.loads((sp.capture / "manifest.json").read_text())
    man["has"]["detections"], man["lacks"]["detections"] = False, "test: an RGB-only capture"
    (sp.capture / "manifest.json").write_text(json.dumps(man))
    r = run_stage("detect", tmp_path)  # the built-in detector, whose weights the detector stage has not written here
    last = r.stderr.strip().splitlines()[-1]
    assert r.returncode == 2 and "weights.pt" in last and "dvc repro detector" in last, r.stderr[-2000:]
    shutil.rmtree(sp.capture / "mono_depth")
    for k in ("mono_depth", "mono_normal"):
        man["has"][k], man["lacks"][k] = False, "test: no priors"
    (sp.capture / "manifest.json").write_text(json.dumps(man))
    t = json.loads((sp.capture / "transforms.json").read_text())
    for f in t["frames"]:
        f.pop("mono_depth_file_path", None)
        f.pop("mono_normal_file_path", None)
    (sp.capture / "transforms.json").write_text(json.dumps(t))
    r = run_stage("priors", tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    cap = apply_overlay(load_capture(sp.capture), sp.file("priors", "index"))
    assert "priors.model=depth_anything" in capture_manifest(cap).missing("mono_depth")


def test_an_overlay_on_a_linked_capture_reads_the_overlays_files(tmp_path, exact_capture):
    """A capture folder that is a symlink (a user's data linked into out/<scene>/capture): the
    overlay's files are the ones beside the overlay, not those at the same relative place next
    to the link's target."""
    target = tmp_path / "data" / "scene" / "capture"
    shutil.copytree(exact_capture[0], target)
    scene = tmp_path / "out" / "scene"
    scene.mkdir(parents=True)
    (scene / "capture").symlink_to(target, target_is_directory=True)
    for where in (scene, target.parent):  # the same layout beside the link and beside its target
        (where / "detect" / "detections").mkdir(parents=True)
    cap = load_capture(scene / "capture")
    frames = {f.file_path: {"detections_path": f"detections/{f.stem}.png"} for f in cap.frames}
    write_overlay(scene / "detect" / "detect.json", "detect", "test", {"detections": {"has": True}}, frames)
    c2 = apply_overlay(cap, scene / "detect" / "detect.json")
    got = (c2.root / c2.frames[0].detections_path).resolve()
    assert got == (scene / "detect" / "detections" / f"{cap.frames[0].stem}.png").resolve()
