"""The sdf, mesh and geometry_table stages as programs on the tiny kitchen: outputs, curves,
the TSDF variant side by side, and bad input -> a message naming the file, exit 2, no output."""

import csv
import json
import shutil

import pytest
from helpers import add_overlays, run_stage, scene_paths

from drawer_lib.paths import LAYOUT, ScenePaths

FAST = ["sdf.neural.steps=16", "sdf.neural.eval_every=8", "sdf.neural.sampling.groups=4",
        "sdf.neural.sampling.rays_per_group=32", "sdf.neural.monocal.refine_steps=4",
        "sdf.neural.monocal.search_levels=6", "mesh.cell=0.03", "mesh.eval_points=20000"]


def run(module, tmp, *extra):
    return run_stage(module, tmp, *FAST, *extra)


@pytest.fixture(scope="module")
def project(tmp_path_factory, exact_capture):
    tmp = tmp_path_factory.mktemp("geom")
    shutil.copytree(exact_capture[0], tmp / "out" / "kitchen_tiny" / "capture")
    add_overlays(tmp, detect=False)
    return tmp


def read_curve(p):
    with open(p) as f:
        return list(csv.DictReader(f))


def test_neural_sdf_then_mesh(project):
    r = run("sdf", project)
    assert r.returncode == 0, r.stderr[-3000:]
    sp = scene_paths(project)
    m = json.loads(sp.metrics("sdf").read_text())
    assert m["method"] == "neural" and m["steps"] == 16 and m["wall_s"] > 0 and m["depth_source"] == "sensor"
    rows = read_curve(sp.stage_dir("sdf") / LAYOUT["curve"])
    assert [int(x["step"]) for x in rows] == [8, 16]
    assert all(float(x["wall_s"]) > 0 and x["chamfer_l1"] != "" and x["test_depth_l1"] != "" for x in rows)
    r = run("mesh", project)
    assert r.returncode == 0, r.stderr[-3000:]
    mm = json.loads(sp.metrics("mesh").read_text())
    assert mm["faces_out"] > 0 and 0 <= mm["fscore_2cm"] <= 1 and mm["chamfer_l1"] > 0 and mm["wall_s"] > 0
    assert sp.mesh.stat().st_size > 0


def test_tsdf_and_mono_variants_and_the_table(project):
    for v in ("tsdf", "neural_mono"):
        r = run("sdf", project, f"sdf={v}", f"+geometry_variant={v}")
        assert r.returncode == 0, r.stderr[-3000:]
        r = run("mesh", project, f"+geometry_variant={v}")
        assert r.returncode == 0, r.stderr[-3000:]
    tsdf, mono = (ScenePaths(project / "out", "kitchen_tiny", v) for v in ("tsdf", "neural_mono"))
    t = json.loads(tsdf.metrics("mesh").read_text())
    assert t["field"] == "tsdf" and t["chamfer_l1"] < 0.01 and t["fscore_2cm"] > 0.9  # exact depth
    s = json.loads(mono.metrics("sdf").read_text())
    assert s["depth_source"] == "calibrated_mono" and "monocal" in s
    assert s["skipped"]["sensor_depth"].startswith("priors.depth = mono")
    assert len(read_curve(tsdf.stage_dir("sdf") / LAYOUT["curve"])) == 1  # the TSDF is one point
    if not scene_paths(project).metrics("mesh").exists():
        pytest.skip("needs test_neural_sdf_then_mesh")
    r = run("geometry_table", project, "sdf=neural", "scenes=[kitchen_tiny]")
    assert r.returncode == 0, r.stderr[-3000:]
    rep = project / "reports" / "geometry"
    js = json.loads((rep / "table.json").read_text())
    assert set(js["kitchen_tiny"]) == {"neural (selected)", "tsdf", "neural_mono"}
    assert (rep / "curves.png").stat().st_size > 1000 and "| kitchen_tiny | tsdf | sensor |" in (rep / "table.md").read_text()


def test_bad_input_is_named_and_leaves_no_output(tmp_path, exact_capture):
    # no capture at all
    r = run("sdf", tmp_path)
    assert r.returncode == 2 and "transforms.json: file is missing" in r.stderr and "error:" in r.stderr
    assert not (tmp_path / "out" / "kitchen_tiny" / "sdf").exists()
    # a capture with a missing image
    cap = tmp_path / "out" / "kitchen_tiny" / "capture"
    shutil.copytree(exact_capture[0], cap)
    victim = sorted((cap / "images").iterdir())[3]
    victim.unlink()
    r = run("sdf", tmp_path)
    assert r.returncode == 2 and victim.name in r.stderr, r.stderr[-2000:]
    assert not (tmp_path / "out" / "kitchen_tiny" / "sdf").exists()
    # mesh without a field
    r = run("mesh", tmp_path)
    assert r.returncode == 2 and "field.pt" in r.stderr
    assert not (tmp_path / "out" / "kitchen_tiny" / "mesh").exists()


def test_tsdf_without_depth_and_unknown_estimator_are_config_errors(tmp_path, exact_capture):
    cap = tmp_path / "out" / "kitchen_tiny" / "capture"
    shutil.copytree(exact_capture[0], cap)
    add_overlays(tmp_path, detect=False)
    man = json.loads((cap / "manifest.json").read_text())
    man["has"]["depth"] = False
    man["lacks"]["depth"] = "test: depth removed"
    (cap / "manifest.json").write_text(json.dumps(man))
    r = run("sdf", tmp_path, "sdf=tsdf")
    assert r.returncode == 2 and "needs metric depth" in r.stderr and "test: depth removed" in r.stderr, r.stderr[-2000:]
    # as a comparison (geometry@<scene>-tsdf) the scene cannot run, it is skipped with its reason and the run goes on
    for stage in ("sdf", "mesh"):
        r = run(stage, tmp_path, *(["sdf=tsdf"] if stage == "sdf" else []), "+geometry_variant=tsdf")
        assert r.returncode == 0, r.stderr[-2000:]
    v = ScenePaths(tmp_path / "out", "kitchen_tiny", "tsdf")
    sdf, mesh = (json.loads(v.metrics(st).read_text()) for st in ("sdf", "mesh"))
    assert "needs metric depth" in sdf["skipped"]["sdf"] and "test: depth removed" in sdf["skipped"]["sdf"]
    assert mesh["skipped"]["mesh"].startswith("no field: the sdf was skipped (sdf.method = tsdf needs metric depth")
    assert sorted(p.name for p in v.stage_dir("sdf").iterdir()) == ["metrics.json"]
    assert sorted(p.name for p in v.stage_dir("mesh").iterdir()) == ["metrics.json"]
    r = run("geometry_table", tmp_path, "scenes=[kitchen_tiny]", "geometry_variants=[tsdf]")
    assert r.returncode == 0, r.stderr[-2000:]
    js = json.loads((tmp_path / "reports" / "geometry" / "table.json").read_text())
    assert js["kitchen_tiny"]["tsdf"]["skipped"].startswith("sdf.method = tsdf needs metric depth")
    md = (tmp_path / "reports" / "geometry" / "table.md").read_text()
    assert "| kitchen_tiny | tsdf | skipped: sdf.method = tsdf needs metric depth" in md
    r = run("sdf", tmp_path, "sdf.neural.priors.estimator=marigold", "sdf.neural.priors.depth=mono")
    assert r.returncode == 2 and "marigold" in r.stderr and "not available" in r.stderr
    assert not (tmp_path / "out" / "kitchen_tiny" / "sdf").exists()


def test_without_ground_truth_the_curve_has_time_and_loss_and_metrics_are_skipped(tmp_path, exact_capture):
    cap = tmp_path / "out" / "kitchen_tiny" / "capture"
    shutil.copytree(exact_capture[0], cap)
    add_overlays(tmp_path, detect=False)
    shutil.rmtree(cap / "gt")
    man = json.loads((cap / "manifest.json").read_text())
    man["has"]["gt"] = False
    man["lacks"]["gt"] = "test: a real capture has no ground truth"
    man["gt_part_kinds"] = None
    (cap / "manifest.json").write_text(json.dumps(man))
    r = run("sdf", tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    sp = scene_paths(tmp_path)
    rows = read_curve(sp.stage_dir("sdf") / LAYOUT["curve"])
    assert [int(x["step"]) for x in rows] == [8, 16]
    assert all(x["chamfer_l1"] == "" and float(x["loss"]) > 0 and float(x["wall_s"]) > 0 for x in rows)
    assert "capture has no gt" in json.dumps(json.loads(sp.metrics("sdf").read_text())["skipped"])
    r = run("mesh", tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    mm = json.loads(sp.metrics("mesh").read_text())
    assert "chamfer_l1" not in mm and "metrics_vs_gt" in mm["skipped"] and mm["faces_out"] > 0
