"""The decision-stability check's parts: the mesh jitter and the comparison of two part sets."""

import dataclasses

import numpy as np
import pytest
import trimesh

from drawer_lib.articulation.joints import hinge_axis
from drawer_lib.articulation.robustness import stability_counts
from drawer_lib.io.parts import Axis, Front, Part, PartsFile
from drawer_lib.metrics.articulation import compare_parts
from drawer_lib.perturb import jitter_mesh

A = Front((1.0, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.6, 0.7))
B = Front((2.0, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.6, 0.2))


def _door(front, hinge, pid="door_0", margin=3.0):
    return Part(pid, "revolute", hinge_axis(front, hinge), (0.0, 1.5), front,
                extra={"family": "door", "margin": margin})


def _drawer(front, pid="drawer_0"):
    return Part(pid, "prismatic", Axis(front.center, (0.0, -1.0, 0.0)), (0.0, 0.4), front, extra={"family": "drawer"})


def test_jitter_moves_vertices_by_sigma_and_keeps_faces():
    m = trimesh.creation.icosphere(3)
    j = jitter_mesh(m, 1e-3, seed=0)
    d = np.asarray(j.vertices) - np.asarray(m.vertices)
    assert np.array_equal(j.faces, m.faces) and d.std() == pytest.approx(1e-3, rel=0.1)
    assert np.array_equal(jitter_mesh(m, 1e-3, seed=0).vertices, j.vertices)  # same seed, same mesh
    assert np.array_equal(jitter_mesh(m, 0.0, seed=3).vertices, m.vertices)
    with pytest.raises(ValueError, match="sigma"):
        jitter_mesh(m, float("nan"), 0)


def test_compare_parts_names_flips_and_misses():
    ref = PartsFile((_door(A, "left"), _drawer(B)))
    assert [r["kept"] for r in compare_parts(ref, ref)] == [True, True]
    flipped = PartsFile((_door(A, "right"),))
    rows = {r["part"]: r for r in compare_parts(ref, flipped)}
    assert rows["door_0"]["now"] == "door_right" and not rows["door_0"]["kept"] and rows["door_0"]["margin"] == 3.0
    assert rows["drawer_0"]["now"] == "missed"


def test_stability_counts_add_up_kept_retyped_lost_and_added():
    C = Front((3.0, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.5, 0.5))
    flagged = dataclasses.replace(_drawer(B), extra={"family": "drawer", "low_margin": True})
    ref = PartsFile((_door(A, "left"), flagged))
    assert stability_counts(ref, ref) == {"n_ref": 2, "n_other": 2, "kept": 2, "retyped": 0, "lost": 0, "added": 0,
                                          "n_flagged": 1, "moved_flagged": 0}
    other = PartsFile((_door(A, "right"), _drawer(C, "drawer_9")))  # A's hinge flipped, B gone, C new
    assert stability_counts(ref, other) == {"n_ref": 2, "n_other": 2, "kept": 0, "retyped": 1, "lost": 1, "added": 1,
                                            "n_flagged": 1, "moved_flagged": 1}
    assert stability_counts(PartsFile(()), other)["added"] == 2


def test_mark_near_mesh_flags_the_moved_parts_and_changes_nothing_else():
    from drawer_lib.articulation.pipeline import mark_near_mesh

    parts = [_door(A, "left"), _drawer(B)]
    report = [{"segment": 0, "part": "door_0", "low_margin": False}, {"segment": 1, "part": "drawer_0", "low_margin": False},
              {"segment": 2, "family": "rigid"}]
    moved = {"drawer_0": [{"run": 1, "now": "missed"}]}
    out, rows = mark_near_mesh(parts, report, moved)
    assert out[0] is parts[0] and out[1].extra["low_margin"] is True and out[1].kind == "prismatic"
    assert out[1].front == parts[1].front and "low_margin" not in parts[1].extra  # the input is not modified
    assert rows[0] == report[0] and rows[2] == report[2]
    assert rows[1] == {"segment": 1, "part": "drawer_0", "low_margin": True, "near_mesh": moved["drawer_0"]}
    assert mark_near_mesh(parts, report, {}) == (parts, report)


@pytest.mark.parametrize("kw", [{"runs": -1}, {"sigma": 0.0}, {"sigma": float("nan")}, {"sigma": float("inf")}])
def test_check_config_rejects_bad_values(kw):
    from drawer_lib.articulation.config import CheckConfig
    from drawer_lib.errors import ConfigError

    with pytest.raises(ConfigError, match="articulate.check"):
        CheckConfig(**kw)


def test_mesh_check_reruns_decompose_and_flags_what_a_moved_mesh_changes(exact_capture, tmp_path):
    """kitchen_tiny with perfect detections on its true mesh: moved by 1e-6 m no part changes and
    nothing is flagged; moved by 4 cm (a mesh that is no longer the same kitchen) parts change,
    and exactly those are listed near_mesh and flagged, their kinds left as they were."""
    import json

    from drawer_lib.articulation.config import ArticulateConfig, CheckConfig
    from drawer_lib.articulation.pipeline import run_articulate
    from drawer_lib.errors import ConfigError
    from drawer_lib.io.capture import load_capture
    from drawer_lib.io.parts import read_parts
    from drawer_lib.perception.config import DecomposeConfig
    from drawer_lib.perception.pipeline import run_decompose
    from drawer_lib.runner import StageRun

    cap_dir, _, _ = exact_capture
    cap, mesh_p, dc = load_capture(cap_dir), cap_dir / "gt" / "mesh.ply", DecomposeConfig()
    d = tmp_path / "decompose"
    d.mkdir()
    run_decompose(dc, cap, mesh_p, StageRun("decompose", d, d, 0))

    def articulate(name, check, recheck=(dc, mesh_p)):
        a = tmp_path / name
        a.mkdir()
        m = run_articulate(ArticulateConfig(check=check), cap, d, StageRun("articulate", a, a, 0), recheck=recheck)
        return m, read_parts(a / "parts.json"), json.loads((a / "decisions.json").read_text())["segments"]

    _, ref, ref_rows = articulate("ref", CheckConfig())
    assert not any("near_mesh" in r for r in ref_rows)
    m, same, rows = articulate("fine", CheckConfig(runs=1, sigma=1e-6))
    assert m["n_near_mesh"] == 0 and m["check_s"] > 0 and same == ref and rows == ref_rows
    m, coarse, rows = articulate("coarse", CheckConfig(runs=1, sigma=0.04))
    listed = {r["part"] for r in rows if "near_mesh" in r}
    assert m["n_near_mesh"] == len(listed) > 0
    assert [(p.id, p.kind, p.front) for p in coarse.parts] == [(p.id, p.kind, p.front) for p in ref.parts]
    for p in coarse.parts:
        assert bool(p.extra.get("low_margin")) is (p.id in listed or bool(ref.by_id(p.id).extra.get("low_margin")))
    with pytest.raises(ConfigError, match="articulate.check.runs"):
        articulate("none", CheckConfig(runs=1), recheck=None)
