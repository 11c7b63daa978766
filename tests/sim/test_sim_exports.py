"""URDF and USD exports load back with the same joint names, types, world axes and limits."""

import dataclasses
import math
import warnings

import numpy as np
import pytest
import trimesh
import yourdfpy
from pxr import Gf, Usd, UsdGeom, UsdPhysics

import sim_fixtures as F
from drawer_lib.bodies import TwinModel, box_shape
from drawer_lib.sim.config import SimConfig
from drawer_lib.sim.urdf import matrix_to_rpy, write_urdf
from drawer_lib.sim.mjcf import drive_gain
from drawer_lib.sim.usd import joint_frame, write_usd


def _rotated_twin() -> TwinModel:
    """The kitchen plus a tilted static box and a part with an oblique axis."""
    twin = F.kitchen()
    R = trimesh.transformations.rotation_matrix(0.4, [1, 1, 0])[:3, :3]
    tilted = box_shape([3.0, 0.5, 0.3], [0.2, 0.1, 0.05], R)
    walls, door = F.door_cabinet(cx=4.0, pid="door_oblique")
    oblique = dataclasses.replace(door, axis_direction=np.array([0.1, 0.05, -1.0]))
    return TwinModel(static_visual=twin.static_visual, static_collision=[*twin.static_collision, tilted, *walls],
                     parts=[*twin.parts, oblique], rigid=twin.rigid)


@pytest.fixture(scope="module")
def twin():
    return _rotated_twin()


def test_matrix_to_rpy_round_trip():
    rng = np.random.default_rng(0)
    for _ in range(50):
        R = trimesh.transformations.random_rotation_matrix(rng.random(3))[:3, :3]
        r, p, y = matrix_to_rpy(R)
        np.testing.assert_allclose(trimesh.transformations.euler_matrix(r, p, y, "sxyz")[:3, :3], R, atol=1e-12)
    R = trimesh.transformations.euler_matrix(0.3, math.pi / 2, -0.2, "sxyz")[:3, :3]  # gimbal lock
    np.testing.assert_allclose(trimesh.transformations.euler_matrix(*matrix_to_rpy(R), "sxyz")[:3, :3], R, atol=1e-9)


def test_urdf_loads_with_the_same_joints(twin, tmp_path):
    path = write_urdf(twin, tmp_path / "twin")
    assert path == tmp_path / "twin" / "urdf" / "scene.urdf"
    robot = yourdfpy.URDF.load(str(path), load_meshes=True, build_collision_scene_graph=True,
                               load_collision_meshes=True)
    joints = {j.name: j for j in robot.robot.joints}
    assert robot.base_link == "world"
    assert set(joints) == {"static", *(p.id for p in twin.parts), *(r.id for r in twin.rigid)}
    cfg = SimConfig()
    for p in twin.parts:
        j = joints[p.id]
        assert j.type == p.kind and j.parent == "static" and j.child == p.id
        T = robot.get_transform(frame_to=p.id, frame_from="world")  # the joint frame at q = 0
        np.testing.assert_allclose(T[:3, :3] @ j.axis, p.unit_axis, atol=1e-12)  # world axis
        np.testing.assert_allclose(T[:3, 3], p.axis_origin, atol=1e-12)
        assert (j.limit.lower, j.limit.upper) == pytest.approx(p.limits, abs=1e-12)
        assert j.limit.velocity == pytest.approx(cfg.joint(p.kind).speed)
        assert float(j.dynamics.damping) == pytest.approx(cfg.joint(p.kind).damping)  # yourdfpy keeps a str
        link = robot.link_map[p.id]
        props = p.mass_properties()
        assert link.inertial.mass == pytest.approx(props.mass, rel=1e-11)
        np.testing.assert_allclose(link.inertial.inertia, props.inertia, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(T[:3, :3] @ link.inertial.origin[:3, 3] + T[:3, 3], props.com, atol=1e-11)
        assert len(link.collisions) == len(p.collision) and len(link.visuals) == len(p.visual)
    for r in twin.rigid:
        assert joints[r.id].type == "floating" and joints[r.id].parent == "world"
    # collision boxes land where the input is, in the world
    for p in twin.parts:
        T = robot.get_transform(frame_to=p.id, frame_from="world")
        for col, s in zip(robot.link_map[p.id].collisions, p.collision):
            np.testing.assert_allclose((T @ col.origin)[:3, 3], s.box.center, atol=1e-11)
            np.testing.assert_allclose((T @ col.origin)[:3, :3], s.box.rotation, atol=1e-12)
    static = robot.link_map["static"]
    tilted = twin.static_collision[-6]
    col = [c for c in static.collisions if c.geometry.box is not None][-6]
    np.testing.assert_allclose(col.origin[:3, :3], tilted.box.rotation, atol=1e-12)
    np.testing.assert_allclose(col.geometry.box.size, 2 * tilted.box.half, atol=1e-12)
    n_mesh = 0
    for lk in robot.link_map.values():  # mesh files are relative to the URDF and exist
        for c in lk.collisions + lk.visuals:
            if c.geometry.mesh is not None:
                n_mesh += 1
                assert not c.geometry.mesh.filename.startswith("/")
                assert (path.parent / c.geometry.mesh.filename).exists()
    assert n_mesh == len(list((path.parent / "meshes").iterdir()))


def _world_frames(stage: Usd.Stage, joint: UsdPhysics.Joint) -> list[tuple[np.ndarray, np.ndarray]]:
    """The joint's world (axis, anchor) at rest as body0 and as body1 see it."""
    cache = UsdGeom.XformCache()
    axis = {"X": Gf.Vec3d(1, 0, 0), "Y": Gf.Vec3d(0, 1, 0), "Z": Gf.Vec3d(0, 0, 1)}[joint.GetAxisAttr().Get()]
    out = []
    for i, (rel, pos, rot) in enumerate(((joint.GetBody0Rel(), joint.GetLocalPos0Attr(), joint.GetLocalRot0Attr()),
                                         (joint.GetBody1Rel(), joint.GetLocalPos1Attr(), joint.GetLocalRot1Attr()))):
        M = cache.GetLocalToWorldTransform(stage.GetPrimAtPath(rel.GetTargets()[0]))
        q = rot.Get()
        local = Gf.Rotation(Gf.Quatd(q.GetReal(), Gf.Vec3d(q.GetImaginary()))).TransformDir(axis)
        out.append((np.array(M.TransformDir(local)), np.array(M.Transform(Gf.Vec3d(pos.Get())))))
    return out


def test_usd_reopens_with_the_same_joints(twin, tmp_path):
    path = write_usd(twin, tmp_path / "twin")
    assert path == tmp_path / "twin" / "scene.usda"
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0 and UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert any(p.IsA(UsdPhysics.Scene) for p in stage.Traverse())
    joints = {p.GetName(): p for p in stage.Traverse() if p.IsA(UsdPhysics.Joint)}
    assert set(joints) == {"static", *(p.id for p in twin.parts)}
    assert joints["static"].IsA(UsdPhysics.FixedJoint)
    for p in twin.parts:
        prim = joints[p.id]
        typed = UsdPhysics.RevoluteJoint(prim) if p.kind == "revolute" else UsdPhysics.PrismaticJoint(prim)
        assert prim.IsA(UsdPhysics.RevoluteJoint if p.kind == "revolute" else UsdPhysics.PrismaticJoint)
        scale = 180 / math.pi if p.kind == "revolute" else 1.0
        assert typed.GetLowerLimitAttr().Get() == pytest.approx(p.limits[0] * scale, abs=1e-4)
        assert typed.GetUpperLimitAttr().Get() == pytest.approx(p.limits[1] * scale, rel=1e-6)
        (axis0, anchor0), (axis1, anchor1) = _world_frames(stage, typed)
        np.testing.assert_allclose(axis0, p.unit_axis, atol=1e-6)
        np.testing.assert_allclose(axis1, p.unit_axis, atol=1e-6)  # both frames agree: no violation at rest
        np.testing.assert_allclose(anchor0, p.axis_origin, atol=1e-6)
        np.testing.assert_allclose(anchor1, p.axis_origin, atol=1e-6)
        body = stage.GetPrimAtPath(typed.GetBody1Rel().GetTargets()[0])
        assert body.GetName() == p.id and body.HasAPI(UsdPhysics.RigidBodyAPI)
        mass = UsdPhysics.MassAPI(body)
        props = p.mass_properties()
        assert mass.GetMassAttr().Get() == pytest.approx(props.mass, rel=1e-6)
        np.testing.assert_allclose(mass.GetDiagonalInertiaAttr().Get(), props.principal, rtol=1e-5)
        cols = [c for c in body.GetChildren() if c.HasAPI(UsdPhysics.CollisionAPI)]
        assert len(cols) == len(p.collision)
        # passive as it loads: the drive neither holds nor brakes; its servo gain is on the prim
        drive = UsdPhysics.DriveAPI(prim, "angular" if p.kind == "revolute" else "linear")
        assert drive.GetStiffnessAttr().Get() == 0 and drive.GetDampingAttr().Get() == 0
        assert prim.GetAttribute("drawer:driveDamping").Get() == pytest.approx(drive_gain(p, SimConfig()) / scale,
                                                                              rel=1e-6)
    static = stage.GetPrimAtPath("/World/static")
    assert static.HasAPI(UsdPhysics.ArticulationRootAPI)
    for r in twin.rigid:
        prim = stage.GetPrimAtPath(f"/World/rigid/{r.id}")
        assert prim.HasAPI(UsdPhysics.RigidBodyAPI) and prim.HasAPI(UsdPhysics.MassAPI)
        meshes = [c for c in prim.GetChildren() if c.HasAPI(UsdPhysics.MeshCollisionAPI)]
        assert UsdPhysics.MeshCollisionAPI(meshes[0]).GetApproximationAttr().Get() == "convexHull"


def test_usd_parses_as_one_fixed_base_articulation(twin, tmp_path):
    """UsdPhysics' own parser (what a simulator reads) finds one articulation rooted at the
    static scene, with every part's body and joint, and the rigid objects outside it."""
    stage = Usd.Stage.Open(str(write_usd(twin, tmp_path / "twin")))
    with warnings.catch_warnings():  # deprecated in favour of a name the Python binding lacks
        warnings.simplefilter("ignore", DeprecationWarning)
        parsed = UsdPhysics.LoadUsdPhysicsFromRange(stage, ["/"])
    arts = parsed[UsdPhysics.ObjectType.Articulation][1]
    assert len(arts) == 1
    bodies = {str(b) for b in arts[0].articulatedBodies}
    assert {f"/World/parts/{p.id}" for p in twin.parts} <= bodies
    assert not any("rigid" in b for b in bodies)
    rev = {str(d.primPath).rsplit("/", 1)[1]: d for d in parsed[UsdPhysics.ObjectType.RevoluteJoint][1]}
    assert set(rev) == {p.id for p in twin.parts if p.kind == "revolute"}
    assert rev["door_0"].limit.upper == pytest.approx(90.0)


def test_cube_collider_is_placed_like_the_box(twin, tmp_path):
    stage = Usd.Stage.Open(str(write_usd(twin, tmp_path / "twin")))
    k = len(twin.static_collision) - 6
    tilted = twin.static_collision[k]
    prim = stage.GetPrimAtPath(f"/World/static/col{k}")
    M = np.array(UsdGeom.XformCache().GetLocalToWorldTransform(prim)).T  # column-vector convention
    size = UsdGeom.Cube(prim).GetSizeAttr().Get()
    np.testing.assert_allclose(M[:3, :3] * size / 2, tilted.box.rotation * tilted.box.half, atol=1e-6)
    np.testing.assert_allclose(M[:3, 3], tilted.box.center, atol=1e-9)


def test_joint_frame_is_a_rotation_with_the_axis_first():
    for d in (np.array([0, 0, -1.0]), np.array([1.0, 0, 0]), np.array([0.3, -0.4, 0.5])):
        R = joint_frame(d)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        np.testing.assert_allclose(R[:, 0], d / np.linalg.norm(d))


def test_writers_replace_their_own_outputs_only(twin, tmp_path):
    out = tmp_path / "twin"
    write_usd(twin, out)
    write_urdf(twin, out)
    write_urdf(F.single(F.door_cabinet), out)
    assert sorted(p.name for p in out.iterdir()) == ["scene.usda", "urdf"]
    meshes = {p.name.split(".")[0] for p in (out / "urdf" / "meshes").iterdir()}
    assert meshes == {"static", "door_0"}
