"""Interaction probes on the tiny analytic kitchen's MJCF (drawer_lib.simulate.interact): a cup in the
opened drawer rides along when it closes, a hand pulling each handle opens the part with a
plausible force, a block dropped on the counter rests on it; and their failures are seen."""

import dataclasses

import pytest
import sim_fixtures as F

from drawer_lib.simulate.interact import cup_rides_along, drop_on_counter, pull_handle
from drawer_lib.sim.mjcf import build_spec, write_mjcf


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    model = F.kitchen()
    xml = write_mjcf(build_spec(model), tmp_path_factory.mktemp("twin"))
    return xml, {p.id: p for p in F.parts_of(model).parts}


def test_a_cup_rides_along_in_a_closing_drawer(scene):
    xml, parts = scene
    r = cup_rides_along(xml, parts["drawer_0"])
    assert r.passed and r.values["drawer_travel_m"] < -0.3  # closed from 80 % of 0.4 m
    assert r.values["error_m"] < 0.005 and r.values["problem"] is None


def test_a_cup_in_a_drawer_whose_bottom_is_missing_falls_out(tmp_path):
    """The drawer box without its bottom: no bottom under the front, the probe says so."""
    model = F.kitchen()
    drawer = model.parts[0]
    no_bottom = dataclasses.replace(drawer, collision=drawer.collision[:4], visual=drawer.visual[:4])
    model = dataclasses.replace(model, parts=[no_bottom, *model.parts[1:]])
    xml = write_mjcf(build_spec(model), tmp_path)
    r = cup_rides_along(xml, {p.id: p for p in F.parts_of(model).parts}["drawer_0"])
    assert r.passed is None and "no drawer bottom" in r.reason


@pytest.mark.parametrize("pid", ["drawer_0", "door_0", "flap_0"])
def test_pulling_the_handle_opens_the_part(scene, pid):
    xml, parts = scene
    r = pull_handle(xml, parts[pid])
    assert r.passed and abs(r.values["reached_q"] - r.values["goal_q"]) < 0.01
    # the joint's damping and friction at 0.2-0.75 m/s at the handle, and the part's inertia:
    # a few newtons (DRAWER's drive damping of 1e10 would need millions)
    assert 0.5 < r.values["peak_force_n"] < 10.0


def test_a_stiff_hinge_needs_more_force(scene, tmp_path):
    model = F.kitchen()
    from drawer_lib.sim.config import JointConfig, SimConfig

    cfg = SimConfig(revolute=JointConfig(damping=50.0, armature=0.005, frictionloss=0.05, speed=0.8726646,
                                         drive_tau=0.02, effort=20.0))
    xml = write_mjcf(build_spec(model, cfg), tmp_path)
    parts = {p.id: p for p in F.parts_of(model).parts}
    soft = pull_handle(scene[0], parts["door_0"]).values["peak_force_n"]
    stiff = pull_handle(xml, parts["door_0"]).values["peak_force_n"]
    assert stiff > 10 * soft


def test_a_block_dropped_on_the_counter_rests_on_it(scene):
    xml, parts = scene
    r = drop_on_counter(xml, list(parts.values()))
    assert r.passed and abs(r.values["rest_gap_m"]) < 0.003 and r.values["rest_speed_m_s"] < 1e-3
    assert r.values["counter_z_m"] == pytest.approx(0.3, abs=0.002)  # the drawer cabinet's top


def test_no_counter_no_drop(scene):
    xml, parts = scene
    high = [dataclasses.replace(p, front=dataclasses.replace(p.front, center=(p.front.center[0], p.front.center[1], 5.0)))
            for p in parts.values() if p.articulated]
    r = drop_on_counter(xml, high)
    assert r.passed is None and "no counter" in r.reason
