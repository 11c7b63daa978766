"""Repair of a twin whose parts sit a few millimetres into the static scene at q = 0."""

import math

import numpy as np
import pytest

import sim_fixtures as F
from drawer_lib.bodies import PartBody, TwinModel, box_shape
from drawer_lib.errors import ConfigError
from drawer_lib.sim.config import SimConfig
from drawer_lib.sim.repair import RepairConfig, repair_penetrations, static_part_penetrations

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
    out, log, kept = repair_penetrations(model, SIM, RepairConfig())
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
    out, log, kept = repair_penetrations(model, SIM, RepairConfig())
    actions = {r["static_piece"]: r["action"] for r in log}
    assert actions == {1: "removed", 2: "too deep"}
    assert [k for k, _ in kept] == [0, 2] and len(out.static_collision) == 2
    # off: nothing changes
    same, none, kept0 = repair_penetrations(model, SIM, RepairConfig(enabled=False))
    assert none == [] and same is model and [k for k, _ in kept0] == [0, 1, 2]
    with pytest.raises(ConfigError, match="twin.repair"):
        RepairConfig(min_depth=0.03, max_depth=0.02)
