"""Handle boxes and grasp frames on analytic fronts: a 0.6 x 0.7 m front at y = -0.6 facing -y
(u = +x, v = +z), its centre at (0.3, -0.6, 0.45)."""

import math

import mujoco
import numpy as np
import pytest

from drawer_lib.bodies import PartBody, TwinModel, box_shape
from drawer_lib.complete.grasp import HandleConfig, grasp_frame, handle_box
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.parts import Axis, Front, Part
from drawer_lib.sim.mjcf import build_spec, compile_spec, part_index

C = HandleConfig()
FRONT = Front((0.3, -0.6, 0.45), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.6, 0.7))


def door(hinge: str = "left", handle: dict | None = None) -> Part:
    x = 0.0 if hinge == "left" else 0.6
    d = (0.0, 0.0, 1.0) if hinge == "left" else (0.0, 0.0, -1.0)
    extra = {"family": "door", "hinge": hinge} | ({"handle": handle} if handle else {})
    return Part("door_0", "revolute", Axis((x, -0.6, 0.45), d), (0.0, math.pi / 2), FRONT, extra=extra)


def drawer(handle: dict | None = None) -> Part:
    extra = {"family": "drawer"} | ({"handle": handle} if handle else {})
    return Part("drawer_0", "prismatic", Axis(FRONT.center, (0.0, -1.0, 0.0)), (0.0, 0.4), FRONT, extra=extra)


def test_a_vertical_bar_by_the_free_edge_is_a_box_proud_of_the_front_and_the_grasp_closes_across_it():
    p = door("left", {"a_u": 0.9, "a_v": 0.5, "orientation": "vertical", "size": [0.02, 0.16], "source": "images"})
    b = handle_box(p, C).box
    np.testing.assert_allclose(b.center, [0.3 + 0.4 * 0.6, -0.6 - (C.proud - C.thickness / 2), 0.45], atol=1e-12)
    np.testing.assert_allclose(sorted(b.half), sorted([C.thickness / 2, 0.08, C.thickness / 2]), atol=1e-12)
    # its outer face is `proud` in front of the front, its back face `proud - thickness`
    corners_y = b.center[1] + np.array([-1, 1]) * (np.abs(b.rotation[1]) @ b.half)
    np.testing.assert_allclose(corners_y, [-0.6 - C.proud, -0.6 - C.proud + C.thickness], atol=1e-12)
    g = grasp_frame(p, C)
    assert g["kind"] == "handle" and g["width"] == pytest.approx(C.thickness)
    np.testing.assert_allclose(g["position"], b.center, atol=1e-12)
    np.testing.assert_allclose(g["approach"], [0, 1, 0], atol=1e-12)  # into the front
    np.testing.assert_allclose(np.abs(g["closing_axis"]), [1, 0, 0], atol=1e-12)  # across a vertical bar
    assert abs(np.dot(g["approach"], g["closing_axis"])) < 1e-12


def test_a_horizontal_bar_a_knob_and_a_bar_past_the_edge():
    bar = handle_box(drawer({"a_u": 0.5, "a_v": 0.9, "orientation": "horizontal", "size": [0.3, 0.03]}), C).box
    assert bar.half[0] == pytest.approx(0.15) and bar.half[1] == pytest.approx(C.thickness / 2)
    g = grasp_frame(drawer({"a_u": 0.5, "a_v": 0.9, "orientation": "horizontal", "size": [0.3, 0.03]}), C)
    np.testing.assert_allclose(np.abs(g["closing_axis"]), [0, 0, 1], atol=1e-12)  # fingers close vertically
    knob = handle_box(door("right", {"a_u": 0.1, "a_v": 0.5, "orientation": "round", "size": [0.02, 0.02]}), C).box
    np.testing.assert_allclose(knob.half[:2], [C.knob / 2, C.knob / 2])
    # evidence at the very edge and longer than the front: clipped, moved inside the rectangle
    edge = handle_box(door("left", {"a_u": 1.0, "a_v": 0.02, "orientation": "vertical", "size": [0.01, 2.0]}), C).box
    rel = edge.center - np.asarray(FRONT.center)
    assert rel[0] + edge.half[0] <= 0.3 + 1e-12 and rel[2] - edge.half[1] >= -0.35 - 1e-12
    assert 2 * edge.half[1] == pytest.approx(C.max_length)


def test_without_a_handle_the_grasp_is_at_the_free_edge():
    g = grasp_frame(door("left"), C)
    assert g["kind"] == "free_edge" and g["width"] == 0 and handle_box(door("left"), C) is None
    np.testing.assert_allclose(g["position"], [0.6 - C.edge_inset, -0.6, 0.45], atol=1e-12)  # right edge
    np.testing.assert_allclose(np.abs(g["closing_axis"]), [0, 0, 1], atol=1e-12)  # along the edge
    np.testing.assert_allclose(grasp_frame(door("right"), C)["position"], [C.edge_inset, -0.6, 0.45], atol=1e-12)
    np.testing.assert_allclose(grasp_frame(drawer(), C)["position"], [0.3, -0.6, 0.8 - C.edge_inset], atol=1e-12)
    flap = Part("flap_0", "revolute", Axis((0.6, -0.6, 0.8), (-1.0, 0.0, 0.0)), (0.0, 1.5), FRONT,
                extra={"family": "flap", "hinge": "top"})
    np.testing.assert_allclose(grasp_frame(flap, C)["position"], [0.3, -0.6, 0.1 + C.edge_inset], atol=1e-12)
    slide = Part("sliding_0", "prismatic", Axis(FRONT.center, (1.0, 0.0, 0.0)), (0.0, 0.3), FRONT,
                 extra={"family": "sliding"})
    np.testing.assert_allclose(grasp_frame(slide, C)["position"], [C.edge_inset, -0.6, 0.45], atol=1e-12)


def test_bad_handles_and_configs_are_named():
    with pytest.raises(InputError, match="door_0"):
        handle_box(door("left", {"a_u": 1.5, "a_v": 0.5, "orientation": "vertical"}), C)
    with pytest.raises(InputError, match="door_0"):
        handle_box(door("left", {"a_u": 0.5, "orientation": "vertical"}), C)
    with pytest.raises(ConfigError, match="thickness"):
        HandleConfig(thickness=0.05, proud=0.03)
    with pytest.raises(ConfigError, match="knob"):
        HandleConfig(knob=float("nan"))
    assert handle_box(door("left", {"a_u": 0.9, "a_v": 0.5, "orientation": "vertical"}),
                      HandleConfig(enabled=False)) is None


def test_the_handle_box_is_a_collision_geom_a_gripper_can_close_on():
    """In the compiled twin the handle is a box geom of the part (collision group), standing
    free of the front panel: a ray along the approach from 10 cm out hits the handle first,
    at `proud` from the front."""
    p = door("left", {"a_u": 0.9, "a_v": 0.5, "orientation": "vertical", "size": [0.02, 0.16]})
    panel = box_shape([0.3, -0.59, 0.45], [0.295, 0.345, 0.01])
    grip = handle_box(p, C)
    body = PartBody("door_0", "revolute", np.asarray(p.axis.origin), np.asarray(p.axis.direction), p.limits,
                    [], [panel, grip], 600.0)
    m = compile_spec(build_spec(TwinModel([], [box_shape([0.3, 0.0, -0.05], [1, 1, 0.05])], [body], [])))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    g = grasp_frame(p, C)
    start = np.asarray(g["position"]) - 0.1 * np.asarray(g["approach"])
    geomid = np.zeros(1, np.int32)
    dist = mujoco.mj_ray(m, d, start, np.asarray(g["approach"], np.float64), None, 1, -1, geomid)
    assert m.geom_bodyid[geomid[0]] == part_index(m, "door_0")["body"]
    assert mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, geomid[0]) == "door_0/col1"  # the handle, not the panel
    assert dist == pytest.approx(0.1 - C.thickness / 2, abs=1e-9)
