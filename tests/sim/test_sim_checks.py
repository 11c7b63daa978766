"""Physical checks of the twin: every fixture passes; broken twins fail and name the part."""

import dataclasses
import math

import mujoco
import numpy as np
import pytest

import sim_fixtures as F
from drawer_lib.errors import InputError, NonFiniteError, TwinCheckError
from drawer_lib.sim.checks import check_twin
from drawer_lib.sim.mjcf import DRIVE_GROUP, build_spec, compile_spec, drives_on, part_index, set_drives, write_mjcf
from drawer_lib.bodies import TwinModel
from drawer_lib.sim.config import ContactConfig, JointConfig, SimConfig


@pytest.fixture(scope="module")
def kitchen_report(tmp_path_factory):
    twin = F.kitchen()
    path = write_mjcf(build_spec(twin), tmp_path_factory.mktemp("twin") / "twin")
    return twin, check_twin(path, twin)


def test_kitchen_passes_every_check(kitchen_report):
    twin, r = kitchen_report
    c = SimConfig().checks
    assert r["n_parts"] == 3 and r["n_rigid"] == 2
    for p in twin.parts:
        rec = r["parts"][p.id]
        hi = p.limits[1]
        rev = p.kind == "revolute"
        tol = c.drive_overshoot_rad if rev else c.drive_overshoot_m
        assert rec["drive_time_to_open_s"] <= 3.0 and rec["drive_overshoot"] <= tol
        assert abs(rec["drive_final_q"] - hi) <= tol
        assert rec["pull_time_to_open_s"] <= 3.0
        assert rec["pull_overshoot"] <= (c.pull_overshoot_rad if rev else c.pull_overshoot_m)
        assert rec["penetration_m"] <= 0.002 and rec["path_penetration_m"] <= 0.002
        assert rec["mass_kg"] == pytest.approx(p.mass_properties().mass)
    # the drive speed sets the opening time to 95 % of the range (the damping fed forward, only friction
    # and the servo's lag drive_tau slow it): door 0.95 x 90 deg at 50 deg/s = 1.71 s, drawer 0.95 x 0.4 m
    # at 0.5 m/s = 0.76 s
    assert 1.71 < r["parts"]["door_0"]["drive_time_to_open_s"] < 1.71 * 1.05 + 0.05
    assert 0.76 < r["parts"]["drawer_0"]["drive_time_to_open_s"] < 0.76 * 1.05 + 0.05
    for rid in ("cup_0", "cup_1"):
        assert r["rigid"][rid]["drift_m"] < 1e-3
    assert r["sim_steps_per_s"] > 0 and r["sim_realtime_factor"] == pytest.approx(r["sim_steps_per_s"] * 0.002)
    assert r["penetration_max_m"] <= 0.002 and r["rigid_drift_max_m"] < 0.01


def test_checks_also_pass_with_part_static_contacts():
    """With part-vs-static contacts on, the carcass clearances keep every part free."""
    cfg = SimConfig(contact=ContactConfig(part_static=True))
    twin = F.kitchen()
    r = check_twin(compile_spec(build_spec(twin, cfg)), twin, cfg)
    assert r["drive_time_to_open_s_max"] < 3.0


def _pulled(m: mujoco.MjModel, pid: str, force: float, seconds: float = 3.0) -> float:
    """The joint value of part ``pid`` after a constant generalised ``force`` for ``seconds``."""
    ix = part_index(m, pid)
    d = mujoco.MjData(m)
    d.qfrc_applied[ix["dof"]] = force
    mujoco.mj_step(m, d, nstep=round(seconds / m.opt.timestep))
    return float(d.qpos[ix["qpos"]])


def test_the_file_as_it_loads_is_a_passive_kitchen(tmp_path):
    """Loaded from scene.xml, the drives are off (actuator group disabled by the file's option),
    and a person's pull opens the drawer and the door; with the drives on, the servo at its
    default control 0 is a damper that holds both nearly shut. The checks pull the file as
    loaded: a twin written with its drives on fails them, naming the parts."""
    twin = F.kitchen()
    xml = write_mjcf(build_spec(twin), tmp_path / "twin")
    assert f'actuatorgroupdisable="{DRIVE_GROUP}"' in xml.read_text()  # a list of groups in the XML
    m = mujoco.MjModel.from_xml_path(str(xml))
    assert not drives_on(m) and (m.actuator_group == DRIVE_GROUP).all()
    c = SimConfig().checks
    drawer, door = (next(p for p in twin.parts if p.id == k) for k in ("drawer_0", "door_0"))
    assert _pulled(m, "drawer_0", c.pull_force) > 0.9 * drawer.limits[1]
    assert _pulled(m, "door_0", c.pull_torque) > 0.9 * door.limits[1]
    braked = set_drives(mujoco.MjModel.from_xml_path(str(xml)), True)
    assert drives_on(braked)
    # the 4.9 kg drawer's servo (kv 247 N·s/m: 20 N / kv = 8 cm/s) holds it to about half its
    # travel in 3 s; this fixture's light door (kv 16 N·m·s/rad) still swings open
    assert _pulled(braked, "drawer_0", c.pull_force) < c.pull_fraction * drawer.limits[1]
    assert check_twin(xml, twin)["drives_on_load"] is False
    on = SimConfig(drives_on_load=True)
    with pytest.raises(TwinCheckError, match="pulled with") as e:
        check_twin(compile_spec(build_spec(twin, on)), twin, on)
    assert {f["check"] for f in e.value.failures} == {"pull"}
    assert "drawer_0" in {f["id"] for f in e.value.failures}


def test_door_stops_at_its_limit_under_a_constant_drive():
    twin = F.single(F.door_cabinet)
    m = set_drives(compile_spec(build_spec(twin)), True)
    ix = part_index(m, "door_0")
    d = mujoco.MjData(m)
    d.ctrl[ix["actuator"]] = m.actuator_ctrlrange[ix["actuator"], 1]
    q = np.empty(2500)
    for i in range(len(q)):  # 5 s
        mujoco.mj_step(m, d)
        q[i] = d.qpos[ix["qpos"]]
    assert np.all(np.diff(q[q < 1.5]) >= -1e-9)  # opens monotonically
    assert q.max() <= math.pi / 2 + math.radians(1) and abs(q[-1] - math.pi / 2) < math.radians(0.2)
    assert abs(d.qvel[ix["dof"]]) < 1e-3  # at rest against the limit
    # the door's free edge has swung out to the front (-y), about the hinge line
    free_edge = d.xpos[ix["body"]] + d.xmat[ix["body"]].reshape(3, 3) @ np.array([0.5, 0, 0])
    assert free_edge[1] == pytest.approx(-0.002 - 0.5, abs=2e-3) and free_edge[0] == pytest.approx(0.95, abs=2e-3)


def test_a_cup_in_an_open_drawer_rides_along_when_it_closes():
    """The cup stands on the bottom of the opened drawer; the drawer is driven closed (at half
    the drive speed: at full speed the abrupt stop at q = 0 lets a cup slide ~2 cm, as a real
    one would) and the cup moves with it to within 1 cm, on the drawer's bottom."""
    walls, drawer = F.drawer_cabinet()
    hi = drawer.limits[1]
    cup = F.cup(0.0, 0.225 - hi, F.T + 0.003 + F.TD, "cup_0")  # centred on the open drawer's bottom
    twin = TwinModel(static_collision=[F.floor(), *walls], parts=[drawer], rigid=[cup])
    m = set_drives(compile_spec(build_spec(twin)), True)
    ix = part_index(m, "drawer_0")
    cb = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "cup_0")
    d = mujoco.MjData(m)
    d.qpos[ix["qpos"]] = hi
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d, nstep=100)  # settle
    c0, q0 = d.xpos[cb].copy(), float(d.qpos[ix["qpos"]])
    d.ctrl[ix["actuator"]] = -0.5 * SimConfig().prismatic.speed
    mujoco.mj_step(m, d, nstep=1500)
    travel = (q0 - d.qpos[ix["qpos"]]) * np.array([0.0, 1.0, 0.0])  # closing moves it along +y
    assert np.linalg.norm(travel) == pytest.approx(hi, abs=1e-3)
    moved = d.xpos[cb] - c0
    assert np.linalg.norm(moved - travel) < 0.01
    assert abs(moved[2]) < 1e-3  # still standing on the drawer's bottom
    assert (np.asarray(d.warning.number) == 0).all()


def _failures(excinfo) -> set[tuple[str, str]]:
    return {(f["id"], f["check"]) for f in excinfo.value.failures}


def test_drawer_opening_into_the_back_wall_fails_and_is_named():
    """Its axis points into the carcass: with part-vs-static contacts off the path check names
    it and the drive and pull go through the wall; on (the default), it is also blocked: it
    stops where it meets the wall, almost at once."""
    twin = F.single(F.drawer_cabinet, reverse=True)
    off = SimConfig(contact=ContactConfig(part_static=False, part_part=False))
    with pytest.raises(TwinCheckError, match="part 'drawer_0': opening it, it penetrates the static scene") as e:
        check_twin(compile_spec(build_spec(twin, off)), twin, off)
    assert _failures(e) == {("drawer_0", "path")}
    assert e.value.report["parts"]["drawer_0"]["path_penetration_m"] > 0.01
    with pytest.raises(TwinCheckError, match="part 'drawer_0': with every other part closed it runs into the "
                       "static scene at q = ") as e:
        check_twin(compile_spec(build_spec(twin)), twin)
    assert _failures(e) == {("drawer_0", "blocked"), ("drawer_0", "path")}
    rec = e.value.report["parts"]["drawer_0"]
    # the drawer box ends 32 mm before the carcass's back wall: it stops there + the 0.5 mm stop depth
    assert rec["stopped_by"] == "static" and rec["stop_q"] == pytest.approx(0.482 - 0.45 + 0.0005, abs=1e-5)


def test_part_placed_inside_the_static_scene_fails_the_penetration_check():
    """The drawer sunk 1 cm into the carcass bottom (3 mm clearance + 13 mm)."""
    twin = F.single(F.drawer_cabinet, sink=0.013)
    with pytest.raises(TwinCheckError) as e:
        check_twin(compile_spec(build_spec(twin)), twin)
    assert ("drawer_0", "penetration") in _failures(e)
    assert "part 'drawer_0': at q = 0 it penetrates the static scene by 10.0 mm" in str(e.value)


def test_overlapping_parts_fail_the_penetration_check_when_parts_collide():
    """Two drawers in one place: with part-part contacts on, a failure naming both; off (the
    conf/twin default: neighbours' reconstructed fronts abut), the overlap is reported only."""
    walls, a = F.drawer_cabinet()
    b = dataclasses.replace(a, id="drawer_1", collision=[c.shifted(np.array([0.0, 0.0, 0.005])) for c in a.collision])
    twin = TwinModel(static_collision=walls, parts=[a, b])
    cfg = SimConfig(contact=ContactConfig(part_part=True))
    with pytest.raises(TwinCheckError, match="penetrates 'drawer_1'") as e:
        check_twin(compile_spec(build_spec(twin, cfg)), twin, cfg)
    assert {("drawer_0", "penetration_parts"), ("drawer_1", "penetration_parts")} <= _failures(e)
    cfg = SimConfig(contact=ContactConfig(part_part=False))
    r = check_twin(compile_spec(build_spec(twin, cfg)), twin, cfg)
    assert r["penetration_parts_max_m"] > 0.01 and r["parts"]["drawer_0"]["penetration_parts_with"] == "drawer_1"
    assert r["penetration_max_m"] <= 0.002


def test_a_floating_cup_fails_the_rest_check():
    twin = TwinModel(static_collision=[F.floor()], rigid=[F.cup(0.0, 0.0, 0.05, "cup_7")])
    with pytest.raises(TwinCheckError, match="rigid object 'cup_7': at rest it moved 5.0") as e:
        check_twin(compile_spec(build_spec(twin)), twin)
    assert _failures(e) == {("cup_7", "rest")}


def test_a_door_whose_limit_is_not_held_fails_the_pull_check():
    """A soft joint limit (constraint time constant 0.2 s) lets a door slammed by the 10 N·m pull
    pass its limit by more than 2°."""
    cfg = SimConfig(contact=ContactConfig(limit_timeconst=0.2))
    twin = F.single(F.door_cabinet)
    with pytest.raises(TwinCheckError, match="part 'door_0': pulled open it passed its upper limit") as e:
        check_twin(compile_spec(build_spec(twin, cfg)), twin, cfg)
    assert ("door_0", "pull") in _failures(e)


def test_unstable_simulation_is_caught_through_the_warning_counters():
    """Explicit Euler with an unlimited servo 100x stiffer than the step can integrate diverges; MuJoCo
    resets the state (no NaN reaches qpos) but counts warnings: the check names the part."""
    cfg = SimConfig(integrator="euler", prismatic=JointConfig(damping=10.0, armature=0.0, frictionloss=0.0,
                                                                speed=0.5, drive_tau=1e-5, effort=1e12))
    twin = F.single(F.drawer_cabinet)
    with pytest.raises(NonFiniteError, match="part 'drawer_0': drive test: the simulation is not healthy .*BADQACC"):
        check_twin(compile_spec(build_spec(twin, cfg)), twin, cfg)


def test_unloadable_model_file_is_an_input_error(tmp_path):
    (tmp_path / "scene.xml").write_text("<mujoco><worldbody><geom type='mesh' mesh='nope'/></worldbody></mujoco>")
    with pytest.raises(InputError, match="scene.xml: MuJoCo cannot load it"):
        check_twin(tmp_path / "scene.xml", TwinModel())


def test_model_that_does_not_match_the_twin_is_named():
    twin = F.single(F.door_cabinet)
    changed = TwinModel(static_collision=twin.static_collision,
                        parts=[dataclasses.replace(twin.parts[0], limits=(0.0, 1.0))])
    with pytest.raises(TwinCheckError, match="part 'door_0': the model's joint"):
        check_twin(compile_spec(build_spec(twin)), changed)


def test_tiny_part_drives_stably():
    """A 3 x 3 cm drawer (~10 g, inertia ~1e-6 kg·m^2) opens under its drive without
    warnings (the armature and the implicit servo keep it well conditioned)."""
    shapes = F.drawer_box(-0.015, 0.015, 0.001, 0.021, 0.0, 0.03)  # 1 mm above the floor it would rub on
    part = F.PartBody(id="tiny", kind="prismatic", axis_origin=np.zeros(3), axis_direction=np.array([0.0, -1.0, 0.0]),
                      limits=(0.0, 0.025), visual=[], collision=shapes, density=600.0)
    twin = TwinModel(static_collision=[F.floor()], parts=[part])
    cfg = SimConfig(prismatic=JointConfig(damping=0.1, armature=0.0, frictionloss=0.01, speed=0.5))
    m = set_drives(compile_spec(build_spec(twin, cfg)), True)
    ix = part_index(m, "tiny")
    assert m.body_mass[ix["body"]] == pytest.approx(part.mass_properties().mass, rel=1e-12)
    assert m.body_mass[ix["body"]] < 0.02 and m.body_inertia[ix["body"]].max() < 1e-5
    d = mujoco.MjData(m)
    d.ctrl[ix["actuator"]] = 0.5
    mujoco.mj_step(m, d, nstep=500)
    assert d.qpos[ix["qpos"]] == pytest.approx(0.025, abs=1e-3)
    assert (np.asarray(d.warning.number) == 0).all() and np.isfinite(d.qacc).all()


def _lift_up_flap(width: float = 0.6, height: float = 0.85):
    """A tall wall-cabinet flap hinged at its top edge, opening up (outward) by up to 100°:
    a 0.6 x 0.85 m x 18 mm panel of 5.5 kg whose weight acts 0.43 m from the hinge (up to
    23 N·m, more than the 10 N·m pull)."""
    x0, x1, z0, z1 = -width / 2, width / 2, 1.4, 1.4 + height
    walls = F.carcass(x0, x1, z0, z1, 0.35)
    panel = F.slab((x0 + 0.0015, -F.GAP - F.T, z0 + 0.0015), (x1 - 0.0015, -F.GAP, z1 - F.GAP))
    part = F.PartBody(id="flap_0", kind="revolute", axis_origin=np.array([0.0, -F.GAP, z1 - F.GAP]),
                      axis_direction=np.array([-1.0, 0.0, 0.0]), limits=(0.0, math.radians(100)),
                      visual=F.as_visual([panel]), collision=[panel], density=F.DENSITY)
    return TwinModel(static_collision=walls, parts=[part])


def test_a_lift_up_flap_needs_its_lift_mechanism():
    """The bare panel's weight beats the 10 N·m pull (the failure names it); with the lift's
    gravity compensation (the default) the pull opens it and its limit holds it; a door (a
    vertical hinge) gets none."""
    twin = _lift_up_flap()
    bare = SimConfig(flap_gravcomp=0.0)
    with pytest.raises(TwinCheckError, match="part 'flap_0': pulled with 10 N·m it opened only") as e:
        check_twin(compile_spec(build_spec(twin, bare)), twin, bare)
    assert ("flap_0", "pull") in _failures(e)
    m = compile_spec(build_spec(twin))
    assert m.body_gravcomp[part_index(m, "flap_0")["body"]] == 1.0
    r = check_twin(m, twin)
    assert r["parts"]["flap_0"]["pull_time_to_open_s"] < 3.0
    door = F.single(F.door_cabinet)
    md = compile_spec(build_spec(door))
    assert md.body_gravcomp[part_index(md, "door_0")["body"]] == 0.0


def _door_and_obstacle(x: tuple[float, float], y: tuple[float, float]) -> TwinModel:
    """The door cabinet (door hinged at x = 0.95, opening to -y) and a neighbouring part standing
    in front of it: a 30 cm tall box over ``x`` x ``y`` (m) on a lift joint (+z, held on its
    lower limit by gravity, so the door's sideways push cannot move it)."""
    walls, door = F.door_cabinet()
    block = F.slab((x[0], y[0], 0.2), (x[1], y[1], 0.5))
    lift = F.PartBody(id="lift_0", kind="prismatic", axis_origin=np.array([sum(x) / 2, sum(y) / 2, 0.35]),
                      axis_direction=np.array([0.0, 0.0, 1.0]), limits=(0.0, 0.1), visual=[], collision=[block],
                      density=F.DENSITY)
    return TwinModel(static_collision=[F.floor(), *walls], parts=[door, lift])


def _first_contact_angle(twin: TwinModel, step: float = 2e-4) -> float:
    """Slow reference: the door's panel turned about its hinge on a fine grid until the
    separating-axis test first finds it touching the neighbour's box."""
    from drawer_lib.geometry.boxes import OrientedBox, separated

    door, lift = twin.parts
    panel, block = door.collision[0].box, lift.collision[0].box
    h = door.axis_origin
    for th in np.arange(0.0, door.limits[1], step):
        c, s = math.cos(th), math.sin(th)
        R = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # th about -z
        if not separated(OrientedBox(h + R @ (panel.center - h), R @ panel.rotation, panel.half), block):
            return float(th)
    return door.limits[1]


def test_a_door_stops_where_its_neighbour_stands_and_the_checks_measure_that_stop():
    """A neighbour's box 7 cm right of the hinge, 35-45 cm out: the door meets it near 82 deg.
    The stop (0.5 mm into the box) is that angle plus at most 0.5 mm / 0.35 m; the door opens
    to 95 % of it under its drive and 90 % under the pull, and no check fails; in the
    simulation it rests against the box, not at its 90 deg limit."""
    twin = _door_and_obstacle((1.0, 1.02), (-0.45, -0.35))
    ref = _first_contact_angle(twin)
    assert math.radians(75) < ref < math.radians(88)
    m = compile_spec(build_spec(twin))
    r = check_twin(m, twin)
    rec = r["parts"]["door_0"]
    assert rec["stopped_by"] == "lift_0" and 0.0 <= rec["stop_q"] - ref < 0.0005 / 0.35 + 2e-4
    assert r["n_parts_stopped"] == 1 and r["travel_fraction_min"] == pytest.approx(rec["stop_q"] / (math.pi / 2))
    assert rec["drive_final_q"] < rec["stop_q"] + 0.01 < math.pi / 2
    assert r["parts"]["lift_0"]["stopped_by"] is None


def test_a_door_its_neighbour_stops_before_half_its_range_is_blocked():
    """The neighbour 36 cm right of the hinge and 30 cm out: the door meets it near 40 deg, below
    half its range: the failure names the neighbour; without part-part contacts it is free."""
    twin = _door_and_obstacle((1.30, 1.32), (-0.45, -0.30))
    with pytest.raises(TwinCheckError, match="part 'door_0': with every other part closed it runs into 'lift_0'") as e:
        check_twin(compile_spec(build_spec(twin)), twin)
    assert _failures(e) == {("door_0", "blocked")}
    assert e.value.report["parts"]["door_0"]["stop_q"] == pytest.approx(_first_contact_angle(twin), abs=0.002)
    off = SimConfig(contact=ContactConfig(part_part=False))
    r = check_twin(compile_spec(build_spec(twin, off)), twin, off)
    assert r["parts"]["door_0"]["stopped_by"] is None and r["n_parts_stopped"] == 0


@pytest.mark.parametrize("tilt_deg, holds", [(2.0, True), (6.0, False)])
def test_a_drawer_whose_axis_tilts_down_stays_shut_within_its_runner_friction(tilt_deg, holds):
    """The reconstructed axis of a drawer tilts down by ``tilt_deg``: its weight pulls it open
    with m g sin(tilt). The runners' friction (5 % of its weight, :meth:`JointConfig.friction`)
    holds it up to atan(0.05) = 2.9 deg; beyond, the rest check names the part and the tilt.
    With the old constant 1 N it rolls open at 2 deg as well."""
    walls, drawer = F.drawer_cabinet()
    t = math.radians(tilt_deg)
    drawer = dataclasses.replace(drawer, axis_direction=np.array([0.0, -math.cos(t), -math.sin(t)]))
    twin = TwinModel(static_collision=[F.floor()], parts=[drawer])  # no carcass for its tilted path to scrape
    cfg = SimConfig()
    m = compile_spec(build_spec(twin, cfg))
    mass = drawer.mass_properties().mass
    assert m.dof_frictionloss[0] == pytest.approx(0.05 * mass * 9.81)
    if holds:
        r = check_twin(m, twin, cfg)
        assert r["parts"]["drawer_0"]["rest_drift_m"] < 5e-4  # MuJoCo's soft friction creeps ~0.07 mm/s
        old = SimConfig(prismatic=dataclasses.replace(SimConfig().prismatic, friction_mu=0.0))
        m_old = compile_spec(build_spec(twin, old))
        d = mujoco.MjData(m_old)
        mujoco.mj_step(m_old, d, nstep=1000)
        assert d.qpos[0] > 0.005  # 1 N of friction does not hold it
    else:
        with pytest.raises(TwinCheckError, match=f"part 'drawer_0': as the file loads it moved .* its axis tilts "
                           f"{tilt_deg:.1f}° from level") as e:
            check_twin(m, twin, cfg)
        assert ("drawer_0", "rest") in _failures(e)
