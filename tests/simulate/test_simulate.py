"""The simulate stage's physics (drawer_lib.simulate.drive / pipeline) on the tiny analytic kitchen
(a drawer, a door, a flap): every part driven open reaches its upper limit along its own
kinematics, and the EMD of the simulated tracks against the part itself is ~0."""

import json

import numpy as np
import pytest
import sim_fixtures as F

from drawer_lib.errors import InputError
from drawer_lib.io.parts import write_parts
from drawer_lib.metrics.motion import front_grid, motion_emd
from drawer_lib.runner import StageRun
from drawer_lib.sim.mjcf import build_spec, compile_spec, set_drives, write_mjcf
from drawer_lib.simulate.pipeline import SimulateConfig, run_simulate
from drawer_lib.simulate.drive import drive_open
from drawer_lib.geometry.camera import Camera, Intrinsics


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim")
    model = F.kitchen()
    write_mjcf(build_spec(model), d / "twin")
    parts = F.parts_of(model)
    write_parts(d / "parts.json", parts)
    (d / "simulate").mkdir()
    m = run_simulate(SimulateConfig(samples=50, use_stability=False), d / "parts.json", d / "twin", StageRun("simulate", d / "simulate",
                                                                                          d / "simulate", 0))
    return d, parts, m


def test_every_part_opens_along_its_own_joint(simulated):
    d, parts, m = simulated
    assert m["n_parts"] == 3 and m["n_parts_not_opened"] == 0 and m["n_sim_warnings"] == 0
    assert m["kinematic_dev_max_m"] < 1e-3  # the physics follows the joint (a rigid body on a joint)
    assert m["realtime_factor"] > 1 and m["integrator"] == "implicitfast"
    per = json.loads((d / "simulate" / "motion.json").read_text())["parts"]
    for p in parts.parts:
        if p.articulated:
            # the drive commands 50 deg/s or 0.5 m/s; the joint's damping and friction hold a
            # velocity servo back by (b v + f) / kv (kv = inertia / 20 ms): up to ~20 % slower
            ideal = p.limits[1] / (0.8726646 if p.kind == "revolute" else 0.5)
            assert ideal <= per[p.id]["time_to_upper_s"] <= 1.25 * ideal + 0.05
    with np.load(d / "simulate" / "tracks.npz") as t:
        assert t["drawer_0/points"].shape == (50, 64, 3) and t["drawer_0/reached"].all()
    # the interaction probes ran, each a metric (tests/simulate/test_interact.py checks them one by one)
    assert (m["cup_rides_along_passed"], m["cup_rides_along_n"]) == (1, 1) and m["cup_rides_along_error_max_m"] < 0.005
    assert (m["pull_handle_passed"], m["pull_handle_n"]) == (3, 3) and m["pull_handle_peak_force_max_n"] < 10
    assert m["drop_on_counter_passed"] == 1 and abs(m["drop_on_counter_rest_gap_max_m"]) < 0.003
    probes = json.loads((d / "simulate" / "motion.json").read_text())["probes"]
    # every file simulate writes is a DVC output (the runner adds metrics.json)
    assert sorted(p.name for p in (d / "simulate").iterdir()) == ["motion.json", "tracks.npz"]
    assert [p["name"] for p in probes].count("pull_handle") == 3


def test_simulated_tracks_against_the_part_itself_give_zero_emd(simulated):
    d, parts, _ = simulated
    arts = [p for p in parts.parts if p.articulated]
    cam = Camera(Intrinsics(160.0, 160.0, 100.0, 75.0, 200, 150),
                 np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 1.2], [0, 1.0, 0, 3.0], [0, 0, 0, 1]]))  # at y = -3, looking +y
    with np.load(d / "simulate" / "tracks.npz") as t:
        s, rows = motion_emd(arts, arts, [(i, i) for i in range(len(arts))], t, cam)
    assert s["n_emd"] == 3 and s["emd"] < 1e-7, rows  # the paper: 1.41e-5


def test_drive_open_errors_name_the_part():
    m = compile_spec(build_spec(F.kitchen()))
    pts = front_grid(F.parts_of(F.kitchen()).parts[0].front)
    with pytest.raises(InputError, match="drives are off"):  # the twin loads passive
        drive_open(m, "drawer_0", pts, np.array([0.1]))
    set_drives(m, True)
    with pytest.raises(InputError, match="'nope'"):
        drive_open(m, "nope", pts, np.array([0.1]))
    with pytest.raises(InputError, match="increasing"):
        drive_open(m, "drawer_0", pts, np.array([0.2, 0.1]))
    # a target beyond the part's limit is never reached, within the time given
    tr = drive_open(m, "drawer_0", pts, np.array([0.1, 5.0]), max_time=1.5)
    assert tr.reached.tolist() == [True, False]
