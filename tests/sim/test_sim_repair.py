"""Repair of a twin whose parts sit a few millimetres into the static scene at q = 0."""

import math

import numpy as np
import pytest

import sim_fixtures as F
from drawer_lib.bodies import PartBody, TwinModel, box_shape
from drawer_lib.errors import ConfigError
from drawer_lib.sim.config import SimConfig
from drawer_lib.sim.repair import (RepairConfig, part_part_overlaps, path_grazes, repair_penetrations,
                                   static_part_penetrations)

SIM = SimConfig()


def panel_part(yaw: float = 0.0) -> PartBody:
    """A 0.5 x 0.02 x 0.6 m door panel at the origin, hinged at its left edge, turned by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    panel = box_shape([0.0, 0.0, 0.5], [0.25, 0.01, 0.3], R)
    return PartBody("door_0", "revolute", R @ np.array([-0.25, 0.0, 0.5]), np.array([0.0, 0.0, 1.0]),
                    (0.0, math.pi / 2), [], [panel], 600.0)


def test_a_rotated_box_pressing_into_a_part_is_carved_on_the_face_it_presses_with():
    """A 4 cm carcass side, turned 30 deg with the panel, reaching 6 mm into its back: carved
    back by 6 mm + 1 mm on that face only, and afterwards nothing overlaps."""
    yaw = math.radians(30)
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    side = box_shape(R @ np.array([0.0, 0.01 + 0.02 - 0.006, 0.5]), [0.2, 0.02, 0.2], R)
    model = TwinModel([], [F.floor(), side], [panel_part(yaw)], [])
    (hit,) = [h for h in static_part_penetrations(model, SIM) if h[0] == 1]
    assert hit[2] == pytest.approx(0.006, abs=1e-6)
    np.testing.assert_allclose(hit[3], -R[:, 1], atol=1e-6)  # from the side into the panel: -v of the box
    out, log, kept, _ = repair_penetrations(model, SIM, RepairConfig(path_samples=0))
    assert [(r["static_piece"], r["action"]) for r in log] == [(1, "carved")]
    new = out.static_collision[1].box
    np.testing.assert_allclose(new.half, [0.2, 0.02 - 0.0035, 0.2], atol=1e-9)
    np.testing.assert_allclose(new.center, side.box.center + R[:, 1] * 0.0035, atol=1e-9)
    assert [k for k, _ in kept] == [0, 1] and kept[0][1] is None and kept[1][1] is not None
    assert all(h[2] <= 1e-9 for h in static_part_penetrations(out, SIM))


def test_a_thin_skin_is_removed_a_deep_overlap_and_a_mesh_are_left_to_the_checks():
    skin = box_shape([0.0, 0.0095, 0.5], [0.2, 0.001, 0.2])  # 2 mm thick, 1.5 mm into the panel
    deep = box_shape([0.0, 0.03 - 0.04 + 0.01, 0.9], [0.1, 0.03, 0.2])  # 4 cm into it, at its top
    model = TwinModel([], [F.floor(), skin, deep], [panel_part()], [])
    out, log, kept, _ = repair_penetrations(model, SIM, RepairConfig(path_samples=0))
    actions = {r["static_piece"]: r["action"] for r in log}
    assert actions == {1: "removed", 2: "too deep"}
    assert [k for k, _ in kept] == [0, 2] and len(out.static_collision) == 2
    # off: nothing changes
    same, none, kept0, _ = repair_penetrations(model, SIM, RepairConfig(enabled=False))
    assert none == [] and same is model and [k for k, _ in kept0] == [0, 1, 2]
    with pytest.raises(ConfigError, match="twin.repair"):
        RepairConfig(min_depth=0.03, max_depth=0.02)


def _front(pid: str, x0: float, x1: float, z0: float = 0.1, z1: float = 0.5, y: float = 0.0) -> PartBody:
    """A 20 mm front over x [x0, x1], z [z0, z1] with its back face at y (m), opening to -y."""
    panel = box_shape([(x0 + x1) / 2, y - 0.01, (z0 + z1) / 2], [(x1 - x0) / 2, 0.01, (z1 - z0) / 2])
    return PartBody(pid, "prismatic", np.array([(x0 + x1) / 2, y, (z0 + z1) / 2]), np.array([0.0, -1.0, 0.0]),
                    (0.0, 0.3), [], [panel], 600.0)


def test_two_fronts_overlapping_in_their_plane_are_trimmed_apart_along_it():
    """Neighbouring fronts whose rectangles overlap by 6 mm: 6 mm is less than their 20 mm
    thickness, yet the trim runs along x (in their plane), each losing 3.5 mm; afterwards nothing
    overlaps, and the thickness is untouched."""
    a, b = _front("drawer_0", 0.0, 0.5), _front("drawer_1", 0.494, 0.9)
    model = TwinModel([], [F.floor()], [a, b], [])
    ((pa, ka, pb, kb, ov, axis),) = part_part_overlaps(model)
    assert (pa, ka, pb, kb) == ("drawer_0", 0, "drawer_1", 0) and ov == pytest.approx(0.006)
    np.testing.assert_allclose(axis, [1.0, 0.0, 0.0], atol=1e-12)
    out, log, _, changed = repair_penetrations(model, SIM, RepairConfig())
    assert [(r["part"], r["other"], r["action"]) for r in log] == [("drawer_0", "drawer_1", "carved")]
    na, nb = out.parts[0].collision[0].box, out.parts[1].collision[0].box
    np.testing.assert_allclose(na.half, [0.25 - 0.00175, 0.01, 0.2], atol=1e-12)
    np.testing.assert_allclose(nb.half, [0.203 - 0.00175, 0.01, 0.2], atol=1e-12)
    assert na.center[0] + na.half[0] == pytest.approx(0.497 - 0.0005)  # 0.5 mm of the 1 mm clearance each
    assert nb.center[0] - nb.half[0] == pytest.approx(0.497 + 0.0005)
    assert set(changed) == {"drawer_0", "drawer_1"} and part_part_overlaps(out) == []
    assert all(h[2] <= 1e-9 for h in static_part_penetrations(out, SIM))  # the floor stays clear


def test_a_front_detected_twice_is_left_and_reported():
    """One front inside another (a part detected twice): 30 cm of overlap, too deep to trim;
    reported, nothing changed."""
    a, b = _front("drawer_0", 0.0, 0.5), _front("drawer_1", 0.1, 0.3, 0.2, 0.4)
    out, log, _, changed = repair_penetrations(TwinModel([], [F.floor()], [a, b], []), SIM, RepairConfig())
    assert [(r["part"], r["other"], r["action"]) for r in log] == [("drawer_0", "drawer_1", "too deep")]
    assert log[0]["depth_m"] == pytest.approx(0.3)  # b must move 30 cm along x or z to clear a
    assert changed == {} and out.parts[0].collision[0].box.half.tolist() == [0.25, 0.01, 0.2]


def _door_beside(edge_x: float) -> TwinModel:
    """The door cabinet of tests/sim (door hinged at x = 0.95 on its back face, opening to -y by
    90 deg) and a neighbouring front to its left, in the same plane, ending at ``edge_x``: as
    the door swings, its outer hinge-side corner sweeps to x = 0.95 - 0.018 = 0.932 at 90 deg."""
    walls, door = F.door_cabinet()
    front = F.slab((0.5, -F.GAP - F.T, 0.1), (edge_x, -F.GAP, 0.6))
    drawer = PartBody("drawer_5", "prismatic", np.array([0.7, -F.GAP, 0.35]), np.array([0.0, -1.0, 0.0]), (0.0, 0.3),
                      [], [front], 600.0)
    return TwinModel([], [F.floor(), *walls], [door, drawer], [])


def test_a_neighbour_the_door_brushes_as_it_opens_is_carved_back_and_a_real_stop_is_not():
    """Neighbour edge at 0.934: the door's corner brushes 2 mm into it at the end of its swing;
    that edge is carved back by 2 + 1 mm and the door opens freely (its stop is its limit). At
    0.945 the corner would go 13 mm in: too deep to be a graze, nothing carved, and the door
    stops where it meets the neighbour."""
    from drawer_lib.sim.checks import check_twin
    from drawer_lib.sim.mjcf import build_spec, compile_spec

    model = _door_beside(0.934)
    ((pid, _, other, k, dep, _),) = path_grazes(model, SIM, 32)
    assert (pid, other, k) == ("door_0", "drawer_5", 0) and dep == pytest.approx(0.002, abs=2e-4)
    out, log, _, changed = repair_penetrations(model, SIM, RepairConfig())
    (r,) = log
    assert r["along_path"] and r["action"] == "carved" and list(changed) == ["drawer_5"]
    assert out.parts[1].collision[0].box.center[0] + out.parts[1].collision[0].box.half[0] == pytest.approx(
        0.934 - r["depth_m"] - 0.001, abs=1e-4)
    assert path_grazes(out, SIM, 32) == []
    rep = check_twin(compile_spec(build_spec(out, SIM)), out, SIM)
    assert rep["parts"]["door_0"]["stopped_by"] is None
    deep = _door_beside(0.945)
    out2, log2, _, changed2 = repair_penetrations(deep, SIM, RepairConfig())
    assert [(r["other"], r["action"]) for r in log2] == [("drawer_5", "too deep")] and changed2 == {}
    assert log2[0]["depth_m"] == pytest.approx(0.013, abs=5e-4)
