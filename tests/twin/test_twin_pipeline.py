"""The twin stage's library on the tiny analytic kitchen of tests/sim (a drawer in a carcass, a
door, a flap, two cups): complete/ -> twin/ with MJCF (checked), URDF, USD, per-body Gaussians,
opened-state renders and twin.json; bad bodies end in an error naming the part."""

import dataclasses
import json

import mujoco
import numpy as np
import pytest
import trimesh
from sim_fixtures import kitchen, parts_of

from drawer_lib.bodies import PartBody, TwinModel, box_shape
from drawer_lib.complete.io import write_complete
from drawer_lib.errors import InputError, TwinCheckError
from drawer_lib.io.capture import load_capture
from drawer_lib.io.parts import write_parts
from drawer_lib.runner import StageRun
from drawer_lib.sim.config import SimConfig
from drawer_lib.splat.gaussians import box_surface_gaussians, concat
from drawer_lib.splat.ply import read_gaussian_ply
from drawer_lib.twin.config import RendersConfig, TwinConfig
from drawer_lib.viewer.config import RecordConfig
from drawer_lib.twin.pipeline import run_twin
from drawer_lib.viewer.scene import load_twin_scene


def gaussians_of(model: TwinModel) -> dict:
    g = {"static": concat([box_surface_gaussians(s.box, np.array([0.6, 0.6, 0.6]), 0.05)
                           for s in model.static_collision if s.kind == "box"])}
    for k, b in enumerate(model.parts):
        col = np.array([[0.9, 0.2, 0.2], [0.2, 0.9, 0.2], [0.2, 0.2, 0.9]])[k % 3]
        g[b.id] = concat([box_surface_gaussians(s.box, col, 0.02) for s in b.collision])
    return g


@pytest.fixture(scope="module")
def built(tmp_path_factory, exact_capture):
    d = tmp_path_factory.mktemp("twin")
    model = kitchen()
    (d / "complete").mkdir()
    gs = gaussians_of(model)
    write_complete(d / "complete", model, gs, {}, {})
    write_parts(d / "parts.json", parts_of(model))
    cap = load_capture(exact_capture[0], check_files=False)
    (d / "twin").mkdir()
    cfg = TwinConfig(renders=RendersConfig(max_views=1, lpips=False))
    m = run_twin(cfg, SimConfig(), cap, d / "parts.json", d / "complete", StageRun("twin", d / "twin", d / "twin", 0))
    return d, model, gs, m, cap


def test_the_twin_folder_holds_every_export(built):
    d, model, gs, m, _ = built
    t = d / "twin"
    mj = mujoco.MjModel.from_xml_path(str(t / "scene.xml"))
    for b in model.parts:
        j = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, b.id)
        assert j >= 0 and mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_ACTUATOR, b.id) >= 0
        np.testing.assert_allclose(mj.jnt_range[j], b.limits)
    tj = json.loads((t / "twin.json").read_text())
    assert tj["schema"] == "drawer.twin/1"
    assert {p["id"] for p in tj["parts"]} == {b.id for b in model.bodies()}
    for p in tj["parts"]:
        assert p["joint"] == p["id"] and (p["actuator"] == p["id"]) == (p["kind"] != "rigid")
    assert (t / "urdf" / "scene.urdf").is_file() and (t / "scene.usda").is_file() and (t / "visual.glb").is_file()
    checks = json.loads((t / "checks.json").read_text())
    assert checks and m["check_s"] > 0
    # the per-body PLYs are the complete/ Gaussians, together as many as went in
    n = sum(len(read_gaussian_ply(t / "gaussians" / f"{k}.ply").means) for k in gs)
    assert n == m["n_gaussians"] == sum(len(g.means) for g in gs.values())
    # a third-party PLY parser (trimesh's) reads the INRIA layout: positions and every 3DGS field
    pc = trimesh.load(t / "gaussians" / "static.ply")
    names = pc.metadata["_ply_raw"]["vertex"]["data"].dtype.names
    assert {"f_dc_0", "opacity", "scale_0", "rot_0", "f_rest_44"} <= set(names)
    np.testing.assert_allclose(pc.vertices, read_gaussian_ply(t / "gaussians" / "static.ply").means.numpy(), atol=1e-6)


def test_every_file_twin_json_names_is_in_the_twin_folder_and_the_viewer_opens_it(built):
    d, model, gs, m, _ = built
    t = d / "twin"
    tj = json.loads((t / "twin.json").read_text())
    named = [g for g in [tj["static"]["gaussians"], *[p["gaussians"] for p in tj["parts"]]] if g]
    named += [c["file"] for b in [tj["static"], *tj["parts"]] for c in b["collision"] if c["kind"] == "mesh"]
    assert any(c["kind"] == "mesh" for p in tj["parts"] for c in p["collision"])  # the cups' hulls
    for f in named:
        assert (t / f).is_file(), f
    # a collision mesh is world frame at rest, as the boxes: the cup's hull lies around the cup
    cup = next(p for p in tj["parts"] if p["id"] == "cup_0")
    v = trimesh.load(t / cup["collision"][0]["file"]).vertices
    np.testing.assert_allclose(v.mean(0)[:2], [2.3, 0.3], atol=0.01)
    # the recording: a self-contained page, and the viewer reads the folder
    assert b"__VISER_EMBED_DATA__" in (t / "open_parts.html").read_bytes() and (t / "open_parts.viser").is_file()
    assert m["recording_mb"] > 0.5
    sc = load_twin_scene(t)
    assert [b.id for b in sc.bodies] == [p["id"] for p in tj["parts"]] and sc.n_gaussians == m["n_gaussians"]


def test_opened_renders_are_indexed_per_part_at_half_its_range(built):
    d, model, gs, m, cap = built
    idx = json.loads((d / "twin" / "renders" / "index.json").read_text())["renders"]
    assert {r["id"] for r in idx} == {b.id for b in model.parts} and len(idx) == len(model.parts)
    for r in idx:
        assert (d / "twin" / "renders" / r["image"]).is_file()
        part = next(b for b in model.parts if b.id == r["id"])
        assert r["q"] == pytest.approx(0.5 * part.limits[1])
    assert "closed_psnr" in m and "open_psnr" not in m  # no synthetic reference given: skipped


def test_a_bad_part_is_an_error_naming_it(tmp_path, exact_capture):
    model = kitchen()
    bad = model.parts[1]
    broken = PartBody(bad.id, bad.kind, bad.axis_origin, np.array([0.0, 0.0, 0.0]), bad.limits, bad.visual,
                      bad.collision, bad.density)
    model2 = TwinModel(model.static_visual, model.static_collision, [model.parts[0], broken, model.parts[2]], model.rigid)
    (tmp_path / "complete").mkdir()
    write_complete(tmp_path / "complete", model2, {}, {}, {})
    write_parts(tmp_path / "parts.json", parts_of(model))
    (tmp_path / "twin").mkdir()
    cap = load_capture(exact_capture[0], check_files=False)
    with pytest.raises(InputError, match=bad.id):
        run_twin(TwinConfig(), SimConfig(), cap, tmp_path / "parts.json", tmp_path / "complete",
                 StageRun("twin", tmp_path / "twin", tmp_path / "twin", 0))


def _intruded(tmp_path, depth: float):
    """The kitchen fixture plus a static box reaching ``depth`` m into its door's panel from
    behind; (model, door, the box's index in the static collision), complete/ and parts.json
    written under ``tmp_path``."""
    model = kitchen()
    door = next(p for p in model.parts if p.kind == "revolute")
    b = door.collision[0].box
    lo, hi = b.center - b.half, b.center + b.half
    intruder = box_shape((lo + hi) / 2 + np.array([0.0, (hi - lo)[1] / 2 + 0.02 - depth, 0.0]),
                         [(hi - lo)[0] / 4, 0.02, (hi - lo)[2] / 4])
    model2 = TwinModel(model.static_visual, [*model.static_collision, intruder], model.parts, model.rigid)
    (tmp_path / "complete").mkdir()
    write_complete(tmp_path / "complete", model2, {}, {}, {})
    write_parts(tmp_path / "parts.json", parts_of(model))
    return model, door, len(model2.static_collision) - 1


def _run(tmp_path, exact_capture, name: str, cfg=None):
    cap = load_capture(exact_capture[0], check_files=False)
    cfg = cfg or TwinConfig(renders=RendersConfig(max_views=1, lpips=False), recording=RecordConfig(enabled=False))
    (tmp_path / name).mkdir()
    return run_twin(cfg, SimConfig(), cap, tmp_path / "parts.json", tmp_path / "complete",
                    StageRun("twin", tmp_path / name, tmp_path / name, 0))


def test_a_part_a_few_millimetres_into_the_static_scene_is_freed_by_carving(tmp_path, exact_capture):
    """A static box 5 mm into the door's panel at q = 0 is carved back (5 mm + the clearance):
    every check passes, checks.json says what was carved, and twin.json lists the carved box."""
    model, door, k = _intruded(tmp_path, 0.005)
    m = _run(tmp_path, exact_capture, "twin")
    checks = json.loads((tmp_path / "twin" / "checks.json").read_text())
    assert checks["failures"] == [] and m["n_repairs"] == 1 and m["n_check_failures"] == 0
    (r,) = checks["repairs"]
    assert (r["part"], r["static_piece"], r["action"]) == (door.id, k, "carved") and r["depth_m"] == pytest.approx(0.005, abs=2e-4)
    static = json.loads((tmp_path / "twin" / "twin.json").read_text())["static"]["collision"]
    assert len(static) == k + 1
    carved = static[k]
    assert carved["half"][1] == pytest.approx(0.02 - (r["depth_m"] + 0.001) / 2, abs=1e-9)
    assert checks["penetration_max_m"] <= 1e-4


def test_a_failing_check_is_reported_per_part_and_the_twin_is_still_written(tmp_path, exact_capture):
    """A static box 3 cm into the door (deeper than a repair may carve: a wrong rectangle, not a
    small defect) fails the penetration check: by default the twin is written and checks.json,
    twin.json and the metrics name the part and the check; with ``on_check_failure: error`` the
    stage stops with the error (the runner then keeps nothing)."""
    model, door, _ = _intruded(tmp_path, 0.03)
    m = _run(tmp_path, exact_capture, "twin")
    checks = json.loads((tmp_path / "twin" / "checks.json").read_text())
    assert {(f["id"], f["check"]) for f in checks["failures"]} >= {(door.id, "penetration")}
    assert [r["action"] for r in checks["repairs"]] == ["too deep"] and m["n_unrepaired"] == 1
    assert m["n_check_failures"] == len(checks["failures"]) and m["n_parts_failing_checks"] >= 1
    tj = {p["id"]: p for p in json.loads((tmp_path / "twin" / "twin.json").read_text())["parts"]}
    assert "penetration" in tj[door.id]["checks"]
    assert all(tj[p.id]["checks"] == [] for p in model.parts if p.id not in {f["id"] for f in checks["failures"]})
    assert (tmp_path / "twin" / "scene.xml").is_file()
    cfg = TwinConfig(renders=RendersConfig(max_views=1, lpips=False), recording=RecordConfig(enabled=False),
                     on_check_failure="error")
    with pytest.raises(TwinCheckError, match=door.id):
        _run(tmp_path, exact_capture, "twin2", cfg)


def test_double_doors_whose_fronts_overlap_are_trimmed_apart_and_each_part_has_its_stop(tmp_path, exact_capture):
    """A second door beside the fixture's, its front overlapping the first's by 6 mm in their
    plane (a double door whose reconstructed rectangles overlap): both panels are trimmed by
    3.5 mm at the faces that meet, every check passes with the parts' contacts on, twin.json
    lists the trimmed boxes, and each part's stop is its upper limit (nothing stops it)."""
    model = kitchen()
    door = next(p for p in model.parts if p.kind == "revolute" and p.unit_axis[2] < -0.5)
    b = door.collision[0].box
    x1 = b.center[0] + b.half[0]
    panel = box_shape([(x1 - 0.006 + 1.9) / 2, b.center[1], b.center[2]], [(1.9 - x1 + 0.006) / 2, *b.half[1:]])
    twin_door = PartBody("door_9", "revolute", np.array([1.9, door.axis_origin[1], door.axis_origin[2]]),
                         np.array([0.0, 0.0, 1.0]), (0.0, np.pi / 2), [], [panel], door.density)
    model = dataclasses.replace(model, parts=[*model.parts, twin_door])
    (tmp_path / "complete").mkdir()
    write_complete(tmp_path / "complete", model, {}, {}, {})
    write_parts(tmp_path / "parts.json", parts_of(model))
    m = _run(tmp_path, exact_capture, "twin")
    checks = json.loads((tmp_path / "twin" / "checks.json").read_text())
    assert checks["failures"] == [] and m["n_repairs"] == 1 and SimConfig().contact.part_part
    (r,) = checks["repairs"]
    assert {r["part"], r["other"]} == {door.id, "door_9"} and r["action"] == "carved"
    assert r["depth_m"] == pytest.approx(0.006, abs=1e-9)
    tj = {p["id"]: p for p in json.loads((tmp_path / "twin" / "twin.json").read_text())["parts"]}
    trimmed = tj[door.id]["collision"][0]
    assert trimmed["half"][0] == pytest.approx(b.half[0] - 0.0035 / 2, abs=1e-9)
    assert trimmed["center"][0] + trimmed["half"][0] == pytest.approx(x1 - 0.0035, abs=1e-9)
    for p in model.parts:
        assert tj[p.id]["stop"] == {"q": pytest.approx(p.limits[1]), "by": None}
    assert checks["penetration_parts_max_m"] == 0.0 and m["sim_n_parts_stopped"] == 0
