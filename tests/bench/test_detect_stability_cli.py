"""scripts/detect_stability.py compares bench_detect runs whose detections were jittered against
the run without, from the outputs they left: identical kitchens, parts kept / retyped / lost /
added, detection pixels changed, and the reference's near decisions; a missing run is a clear
error."""

import json
from pathlib import Path

import numpy as np
from helpers import door_part, run_script

from drawer_lib.io.images import write_json, write_u16
from drawer_lib.io.parts import Part, PartsFile, write_parts


def _run(*args):
    return run_script("detect_stability.py", *args)


def _tagged(root: Path, tag: str, parts: list[Part], lab: np.ndarray, rows: list[dict], near: dict | None = None):
    d = root / "by_detector" / f"builtin-{tag}"
    (d / "articulate").mkdir(parents=True)
    write_parts(d / "articulate" / "parts.json", PartsFile(tuple(parts), ()))
    (d / "detect" / "detections").mkdir(parents=True)
    write_u16(d / "detect" / "detections" / "frame_0.png", lab)
    write_json(d / "detect" / "detections" / "frame_0.json", rows)
    write_json(d / "detect" / "metrics.json", {"n_frames": 1, **(near or {})})


def test_jittered_runs_against_the_reference(tmp_path):
    split = tmp_path / "hand_tune"
    lab = np.zeros((4, 5), np.uint16)
    lab[1:3, 1:4] = 1
    front = [{"id": 1, "label": "front", "score": 0.9}]
    near = {"near_decisions": {"merge": 1, "merge_band": 0, "score": 2}, "near_frames": 1}
    moved = lab.copy()
    moved[1, 1] = 0  # one pixel fewer of the front
    renumbered = np.where(lab > 0, 7, 0).astype(np.uint16)  # the same front under another id
    cut = lab.copy()
    cut[1:3, 3] = 2  # the front cut in two: no label changes, its instances do
    two = front + [{"id": 2, "label": "front", "score": 0.9}]
    same = [door_part("a", 0.0), door_part("b", 2.0)]
    for k, other, olab, orows in ((0, same, renumbered, [{**front[0], "id": 7}]),
                                  (1, [door_part("a", 0.0, "prismatic"), door_part("c", 4.0)], moved, front),
                                  (2, same, cut, two)):
        root = split / f"kitchen_{k}"
        _tagged(root, "j0", same, lab, front, near)
        _tagged(root, "j3", other, olab, orows)
    for tag, jit in (("j0", "0"), ("j3", "1e-3")):
        write_json(split / f"summary-{tag}.json", {"set": [f"detect.builtin.logit_jitter={jit}"],
                                                   "by_model": {"builtin": {"precision_pooled": 0.9, "recall_pooled": 0.8}}})
    r = _run(split, "--ref", "j0", "--tags", "j3", "--json", tmp_path / "s.json")
    assert r.returncode == 0, r.stderr
    assert "9 decoding decisions within 0.001" in r.stdout and "in 3 of 3 frames" in r.stdout
    # kitchens 0 and 2: identical parts; 0 its front renumbered (no change), 2 its front cut in
    # two (a frame changed, no label); 1: a retyped, b lost, c added, one pixel of its 20 moved
    assert "| j3 | 1e-3 | 2 / 3 | 4 / 6 | 1 | 1 | 1 | 0 / 2 | 2 / 3 | 1.67e-02 | 0.900 / 0.800 |" in r.stdout
    out = json.loads((tmp_path / "s.json").read_text())
    assert out["tags"]["j3"]["total"]["pixels_changed"] == 1 and out["near"]["decisions"]["score"] == 6
    assert [r["frames_changed"] for r in out["tags"]["j3"]["rows"]] == [0, 1, 1]
    # a reference that reran articulate alone reads its detections from the run it came from
    for k in range(3):
        art = split / f"kitchen_{k}" / "by_detector"
        (art / "builtin-a0" / "articulate").mkdir(parents=True)
        (art / "builtin-a0" / "articulate" / "parts.json").write_bytes((art / "builtin-j0" / "articulate" / "parts.json").read_bytes())
    r = _run(split, "--ref", "a0", "--ref-detect", "j0", "--tags", "j3")
    assert r.returncode == 0 and "| j3 | 1e-3 | 2 / 3 | 4 / 6 | 1 | 1 | 1 | 0 / 2 | 2 / 3 |" in r.stdout
    assert "not recorded" not in r.stdout
    write_json(split / "kitchen_0" / "by_detector" / "builtin-j0" / "detect" / "metrics.json", {"n_frames": 1})
    r = _run(split, "--ref", "j0", "--tags", "j3")  # detections from before the count: said so, not zero
    assert r.returncode == 0 and "6 decoding decisions" in r.stdout and "not recorded for 1 kitchens" in r.stdout
    r = _run(split, "--ref", "a0", "--tags", "j3")
    assert r.returncode != 0 and "builtin-a0/detect/metrics.json: missing" in r.stderr
    r = _run(split, "--ref", "j0", "--tags", "j9")
    assert r.returncode != 0 and "builtin-j9/articulate/parts.json: missing" in r.stderr
    r = _run(tmp_path / "nothing", "--ref", "j0", "--tags", "j3")
    assert r.returncode != 0 and "no kitchen_* folders" in r.stderr


def test_numerics_needs_the_weights_and_the_comparison_its_folders(tmp_path):
    r = _run("--numerics", tmp_path / "capture")
    assert r.returncode != 0 and "--numerics needs --weights" in r.stderr
    r = _run(tmp_path, "--tags", "j3")
    assert r.returncode != 0 and "--ref and --tags are needed" in r.stderr
