"""The decision-stability check's parts: the mesh jitter and the comparison of two part sets."""

import dataclasses

import numpy as np
import pytest
import trimesh

from drawer_lib.articulation.joints import hinge_axis
from drawer_lib.articulation.robustness import compare_parts, stability_counts
from drawer_lib.io.parts import Axis, Front, Part, PartsFile
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
