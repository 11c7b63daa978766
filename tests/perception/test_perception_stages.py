"""decompose -> articulate -> evaluate as programs on the tiny kitchen (GT mesh as the scene mesh):
outputs and metrics; geometry-only path; no-GT scenes skip with the reason; bad input is named,
exits 2 and leaves no output. Articulate runs with the prior weights (the fitted ones are an
output of the benchmark's fit_decisions stage, tests/bench)."""

import json
import shutil

import pytest
from helpers import add_overlays, gt_mesh_project, run_stage, scene_paths

from drawer_lib.io.parts import read_parts


@pytest.fixture()
def project(tmp_path, exact_capture):
    gt_mesh_project(tmp_path, exact_capture[0])
    add_overlays(tmp_path, priors=False)
    return tmp_path


PRIOR = "articulate.types.weights=prior"


def test_stages_write_parts_and_articulation_metrics(project):
    for st in ("decompose", "articulate", "evaluate"):
        r = run_stage(st, project, *([PRIOR] if st == "articulate" else []))
        assert r.returncode == 0, r.stderr[-3000:]
    sp = scene_paths(project)
    dm = json.loads(sp.metrics("decompose").read_text())
    assert dm["source"] == "detections" and dm["n_segments"] > 0 and dm["wall_s"] > 0
    parts = read_parts(sp.parts)  # the drawer.parts/1 format, validated
    assert any(p.articulated for p in parts.parts)
    ev = json.loads(sp.metrics("evaluate").read_text())
    assert ev["precision"] == 1.0 and ev["recall"] == 1.0
    dec = json.loads(sp.file("articulate", "decisions").read_text())
    assert {s["segment"] for s in dec["segments"]} == set(range(dm["n_segments"]))


def test_geometry_only_path_runs_and_scene_without_gt_skips_evaluation(project):
    cap = project / "out" / "kitchen_tiny" / "capture"
    shutil.rmtree(cap / "gt")
    man = json.loads((cap / "manifest.json").read_text())
    man["has"]["gt"] = False
    man["lacks"]["gt"] = "test: a real capture has no ground truth"
    man["gt_part_kinds"] = None
    (cap / "manifest.json").write_text(json.dumps(man))
    for st, extra in (("decompose", ["decompose.source=geometric"]), ("articulate", [PRIOR]), ("evaluate", [])):
        r = run_stage(st, project, *extra)
        assert r.returncode == 0, r.stderr[-3000:]
    sp = scene_paths(project)
    assert json.loads(sp.metrics("decompose").read_text())["source"] == "geometric"
    ev = json.loads(sp.metrics("evaluate").read_text())
    assert "precision" not in ev and "ground truth" in ev["skipped"]["articulation"]


def test_bad_input_is_named_and_leaves_no_output(project):
    scene_paths(project).mesh.unlink()
    r = run_stage("decompose", project)
    assert r.returncode == 2 and "mesh.ply" in r.stderr and "missing" in r.stderr
    assert not (project / "out" / "kitchen_tiny" / "decompose").exists()
    r = run_stage("articulate", project)  # the fitted weights: the benchmark has not run here
    assert r.returncode == 2 and r.stderr.strip().splitlines()[-1] == (
        f"error: {project / 'bench' / 'fit' / 'weights.json'}: no decision weights (the fit_decisions stage writes "
        "them: `dvc repro fit_decisions`; or set articulate.types.weights=prior)")
    r = run_stage("articulate", project, PRIOR)
    assert r.returncode == 2 and "segments.json" in r.stderr
    assert not (project / "out" / "kitchen_tiny" / "articulate").exists()
    r = run_stage("articulate", project, PRIOR, "articulate.estimator=3doi")
    assert r.returncode == 2 and "3doi" in r.stderr.strip().splitlines()[-1]
