"""The MJCF export: names, joints, masses, contacts, files (``scene.xml``, docs/formats.md)."""

import dataclasses
import math
import shutil

import mujoco
import numpy as np
import pytest

import sim_fixtures as F
from drawer_lib.sim.mjcf import (BIT_PART, BIT_RIGID, BIT_STATIC, GROUP_COLLISION, build_spec, compile_spec,
                                 contact_bits, drive_gain, part_index, write_mjcf)
from drawer_lib.bodies import TwinModel
from drawer_lib.sim.config import ContactConfig, SimConfig


@pytest.fixture(scope="module")
def kitchen():
    twin = F.kitchen()
    return twin, compile_spec(build_spec(twin))


def _id(m, obj, name):
    return mujoco.mj_name2id(m, obj, name)


def test_names_joints_and_actuators_follow_the_twin(kitchen):
    twin, m = kitchen
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    for p in twin.parts:
        ix = part_index(m, p.id)
        assert min(ix.values()) >= 0
        j = ix["joint"]
        assert m.jnt_bodyid[j] == ix["body"] and m.body_jntnum[ix["body"]] == 1
        assert m.jnt_type[j] == (mujoco.mjtJoint.mjJNT_HINGE if p.kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE)
        np.testing.assert_allclose(d.xaxis[j], p.unit_axis, atol=1e-12)  # world axis
        np.testing.assert_allclose(d.xanchor[j], p.axis_origin, atol=1e-12)  # world anchor
        np.testing.assert_allclose(m.jnt_range[j], p.limits, atol=1e-15)
        assert m.jnt_limited[j]
        jc = SimConfig().joint(p.kind)
        assert (m.dof_damping[ix["dof"]], m.dof_armature[ix["dof"]], m.dof_frictionloss[ix["dof"]]) == pytest.approx(
            (jc.damping, jc.armature, jc.friction(m.body_mass[ix["body"]], 9.81)))
        a = ix["actuator"]
        assert m.actuator_trnid[a, 0] == j
        kv = drive_gain(p, SimConfig())
        # force = (kv + damping) ctrl - kv qdot: the joint's damping fed forward
        assert m.actuator_gainprm[a, 0] == pytest.approx(kv + jc.damping) and m.actuator_biasprm[a, 2] == pytest.approx(-kv)
        np.testing.assert_allclose(m.actuator_ctrlrange[a], [-jc.speed, jc.speed])
    for r in twin.rigid:
        j = _id(m, mujoco.mjtObj.mjOBJ_JOINT, r.id)
        assert m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE and m.jnt_bodyid[j] == _id(m, mujoco.mjtObj.mjOBJ_BODY, r.id)
    assert m.nu == len(twin.parts)
    assert m.opt.timestep == 0.002 and m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    np.testing.assert_allclose(m.opt.gravity, [0, 0, -9.81])


def test_geometry_stays_in_the_world_frame(kitchen):
    """Every geom's world position equals its input's (boxes: centre; meshes: the hull's)."""
    twin, m = kitchen
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    for p in twin.parts:
        for k, s in enumerate(p.collision):
            g = _id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{p.id}/col{k}")
            np.testing.assert_allclose(d.geom_xpos[g], s.box.center, atol=1e-9)
            np.testing.assert_allclose(m.geom_size[g], s.box.half, atol=1e-12)
    cup = twin.rigid[1]
    g = _id(m, mujoco.mjtObj.mjOBJ_GEOM, "cup_1/col0")
    mid = m.geom_dataid[g]
    verts = m.mesh_vert[m.mesh_vertadr[mid]:m.mesh_vertadr[mid] + m.mesh_vertnum[mid]]
    world = verts @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
    v = cup.collision[0].vertices
    np.testing.assert_allclose([world.min(0), world.max(0)], [v.min(0), v.max(0)], atol=1e-6)
    np.testing.assert_allclose(d.xipos[_id(m, mujoco.mjtObj.mjOBJ_BODY, cup.id)], cup.mass_properties().com, atol=1e-12)


def test_masses_are_density_times_volume(kitchen):
    """Analytic for the box parts; and equal to MuJoCo's own computation from the collision
    geoms at the same density (mass, centre, full inertia), for boxes and the cup's mesh."""
    twin, m = kitchen
    drawer = twin.parts[0]
    vol = sum(8 * np.prod(s.box.half) for s in drawer.collision)
    assert m.body_mass[_id(m, mujoco.mjtObj.mjOBJ_BODY, drawer.id)] == pytest.approx(600.0 * vol, rel=1e-12)
    door = twin.parts[1]
    assert m.body_mass[_id(m, mujoco.mjtObj.mjOBJ_BODY, door.id)] == pytest.approx(
        600.0 * 8 * np.prod(door.collision[0].box.half), rel=1e-12)

    spec = build_spec(twin)
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE
    spec.compiler.inertiagrouprange = [GROUP_COLLISION, GROUP_COLLISION]
    density = {b.id: b.density for b in twin.bodies()}
    for g in spec.geoms:
        g.density = density.get(g.name.split("/")[0], 1.0)
    ref = spec.compile()

    def full(model, b):
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, model.body_iquat[b])
        R = R.reshape(3, 3)
        return R @ np.diag(model.body_inertia[b]) @ R.T

    for body in twin.bodies():
        b = _id(m, mujoco.mjtObj.mjOBJ_BODY, body.id)
        assert m.body_mass[b] == pytest.approx(ref.body_mass[b], rel=1e-6)
        np.testing.assert_allclose(m.body_ipos[b], ref.body_ipos[b], atol=1e-7)
        np.testing.assert_allclose(full(m, b), full(ref, b), rtol=1e-5, atol=1e-9)


def test_contacts_default_and_exclusions(kitchen):
    """By default everything collides with everything (parts with the static scene and each
    other, rigid objects with all); either part contact can be switched off; visual geoms
    collide with nothing."""
    twin, m = kitchen
    bits = contact_bits(SimConfig())
    assert bits["static"] == (BIT_STATIC, BIT_PART | BIT_RIGID)
    assert bits["part"] == (BIT_PART, BIT_STATIC | BIT_PART | BIT_RIGID)
    assert bits["rigid"] == (BIT_RIGID, BIT_STATIC | BIT_PART | BIT_RIGID)

    def collide(a, b, bits=bits):
        return bool(bits[a][0] & bits[b][1] or bits[b][0] & bits[a][1])

    assert all(collide(a, b) for a in bits for b in bits if not a == b == "static")
    off = contact_bits(SimConfig(contact=ContactConfig(part_static=False, part_part=True)))
    assert not collide("part", "static", off) and collide("part", "part", off) and collide("rigid", "static", off)
    on = contact_bits(SimConfig(contact=ContactConfig(part_static=True, part_part=False)))
    assert on["part"][1] & BIT_STATIC and not on["part"][1] & BIT_PART and on["static"][1] & BIT_PART
    vis = m.geom_group != GROUP_COLLISION
    assert (m.geom_contype[vis] == 0).all() and (m.geom_conaffinity[vis] == 0).all()
    assert (m.geom_contype[~vis] > 0).all()


def test_write_mjcf_loads_from_its_folder_alone(tmp_path):
    twin = F.kitchen()
    spec = build_spec(twin)
    path = write_mjcf(spec, tmp_path / "twin")
    assert path == tmp_path / "twin" / "scene.xml"
    moved = tmp_path / "elsewhere"
    shutil.copytree(tmp_path / "twin", moved)
    shutil.rmtree(tmp_path / "twin")
    m = mujoco.MjModel.from_xml_path(str(moved / "scene.xml"))
    ref = compile_spec(build_spec(twin))
    assert (m.nbody, m.njnt, m.nu, m.ngeom, m.nmesh) == (ref.nbody, ref.njnt, ref.nu, ref.ngeom, ref.nmesh)
    # exact numbers: the file holds what the spec holds (MuJoCo's own writer rounds to 6 digits)
    for field in ("body_mass", "body_pos", "body_ipos", "body_inertia", "jnt_range", "jnt_axis", "geom_size",
                  "geom_pos", "actuator_gainprm", "actuator_biasprm", "actuator_ctrlrange", "dof_damping"):
        np.testing.assert_array_equal(getattr(m, field), getattr(ref, field), err_msg=field)
    np.testing.assert_allclose(m.mesh_vert, ref.mesh_vert, atol=1e-7)  # OBJ: 9 significant digits
    xml = (moved / "scene.xml").read_text()
    assert 'meshdir="assets"' in xml and "vertex=" not in xml
    files = sorted(p.name for p in (moved / "assets").iterdir())
    assert files == sorted(spec.assets) and all(f.endswith(".obj") for f in files)
    assert sorted(p.name for p in moved.iterdir()) == ["assets", "scene.xml"]  # no temporary leftovers


def test_write_mjcf_keeps_other_files_and_replaces_its_own(tmp_path):
    out = tmp_path / "twin"
    out.mkdir()
    (out / "twin.json").write_text("{}")
    write_mjcf(build_spec(F.kitchen()), out)
    write_mjcf(build_spec(F.single(F.door_cabinet)), out)  # fewer meshes: stale ones must go
    m = mujoco.MjModel.from_xml_path(str(out / "scene.xml"))
    assert m.nu == 1 and (out / "twin.json").exists()
    assert not any(p.name.startswith("cup") or p.name.startswith("drawer") for p in (out / "assets").iterdir())
    assert sorted(p.name for p in out.iterdir()) == ["assets", "scene.xml", "twin.json"]


def test_empty_scene_and_static_only():
    m = compile_spec(build_spec(TwinModel()))
    assert m.nbody == 2 and m.nu == 0
    m = compile_spec(build_spec(TwinModel(static_collision=[F.floor()], rigid=[F.cup(0, 0, 0)])))
    assert m.nu == 0 and m.njnt == 1


def test_revolute_joint_of_a_tilted_axis():
    """An arbitrary (non-unit, tilted) axis direction is normalised and kept exactly."""
    walls, door = F.door_cabinet()
    tilted = np.array([0.1, -0.2, -2.0])
    twin = TwinModel(static_collision=walls, parts=[dataclasses.replace(door, axis_direction=tilted)])
    m = compile_spec(build_spec(twin))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    np.testing.assert_allclose(d.xaxis[0], tilted / np.linalg.norm(tilted), atol=1e-12)
    assert math.isclose(m.jnt_range[0, 1], math.pi / 2)


def test_a_light_doors_drive_reaches_its_target_speed_against_the_hinge_damping():
    """A light door's servo gain (inertia / drive_tau) is near its hinge's damping; without the
    damping fed forward it would turn at kv / (kv + b) of the target speed."""
    from drawer_lib.sim.mjcf import set_drives

    walls, door = F.door_cabinet()
    door = dataclasses.replace(door, density=40.0)  # a 0.5 x 0.7 m foam panel
    twin = TwinModel(static_visual=F.as_visual([F.floor(), *walls]), static_collision=[F.floor(), *walls],
                     parts=[door])
    cfg = SimConfig()
    m = set_drives(compile_spec(build_spec(twin, cfg)), True)
    kv, b, speed = drive_gain(door, cfg), cfg.revolute.damping, cfg.revolute.speed
    assert kv / (kv + b) < 0.7  # the case this guards: a bare velocity servo would lag by > 30 %
    d = mujoco.MjData(m)
    d.ctrl[0] = speed
    for _ in range(int(0.4 / m.opt.timestep)):  # 0.35 rad, well inside the 90 deg range
        mujoco.mj_step(m, d)
    friction = m.dof_frictionloss[0]
    assert d.qvel[0] == pytest.approx(speed - friction / (kv + b), rel=0.02)
    assert d.qvel[0] >= 0.9 * speed
