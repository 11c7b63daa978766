"""The twin as a USD stage with UsdPhysics (``scene.usda``; docs/formats.md), written with ``pxr``
(usd-core); no PhysxSchema.

Stage: metres (metersPerUnit 1), kilograms, up axis Z, default prim ``/World``::

    /World/PhysicsScene                    UsdPhysics.Scene, gravity -z
    /World/static                          the fixed scene, root link of the articulation:
                                           RigidBodyAPI + ArticulationRootAPI, fixed to the
                                           world by /World/joints/static (FixedJoint)
      col<k>, vis<k>                       Cube / Mesh colliders, visual meshes
    /World/parts/<id>                      Xform at the axis origin: RigidBodyAPI, MassAPI,
                                           children col<k> (CollisionAPI), vis<k>
    /World/joints/<id>                     RevoluteJoint / PrismaticJoint, body0 = static,
                                           body1 = parts/<id>, DriveAPI (velocity servo)
    /World/rigid/<id>                      Xform at the centre of mass: RigidBodyAPI, MassAPI
                                           (free bodies, outside the articulation)

Colliders: a box is a ``Cube`` (size 2, scaled by its half extents) with ``CollisionAPI``; a
collision mesh is its convex hull with ``CollisionAPI`` + ``MeshCollisionAPI`` approximation
``convexHull`` (purpose ``guide``); visual meshes carry no collision. Joint frames: ``axis`` =
"X"; the joint frame's x axis is the world axis (``localRot0`` = ``localRot1``, ``localPos0`` the
axis origin in the static frame = world, ``localPos1`` 0 in the part frame). Limits: degrees for
revolute (UsdPhysics convention), metres for prismatic. Masses from the collision solids
(``mass``, ``centerOfMass``, ``diagonalInertia`` + ``principalAxes``). Drives: type force,
stiffness 0, damping 0 (passive, as the MJCF loads) unless ``sim.drives_on_load``, when it is
the MJCF velocity servo's gain (per degree for angular drives), which every joint also carries
as ``drawer:driveDamping``; ``targetVelocity`` 0 (to drive a part, set the damping to that gain
and the target to the drive speed), ``maxForce`` the effort.
"""

import math
from pathlib import Path

import mujoco
import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt

from drawer_lib.errors import InvariantError
from drawer_lib.paths import stage_name
from drawer_lib.sim.files import write_entries_atomic
from drawer_lib.sim.mjcf import drive_gain
from drawer_lib.bodies import MassProps, PartBody, Shape, TwinModel
from drawer_lib.sim.config import SimConfig

USD_FILE = stage_name("twin", "usd")
ROOT = "/World"


def _quatf(R: np.ndarray) -> Gf.Quatf:
    """The unit quaternion of a rotation [3, 3] (column vectors, v' = R v)."""
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, np.float64).ravel())  # w, x, y, z
    return Gf.Quatf(float(q[0]), Gf.Vec3f(float(q[1]), float(q[2]), float(q[3])))


def joint_frame(direction: np.ndarray) -> np.ndarray:
    """A rotation [3, 3] whose first column is the unit ``direction`` [3]."""
    x = direction / np.linalg.norm(direction)
    helper = np.eye(3)[int(np.argmin(np.abs(x)))]
    y = np.cross(x, helper)
    y /= np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)], 1)


def _xform(stage: Usd.Stage, path: str, translate: np.ndarray | None = None) -> UsdGeom.Xform:
    xf = UsdGeom.Xform.Define(stage, path)
    if translate is not None:
        xf.AddTranslateOp().Set(Gf.Vec3d(*[float(x) for x in translate]))
    return xf


def _shapes(stage: Usd.Stage, parent: str, shapes: list[Shape], offset: np.ndarray, collision: bool) -> None:
    role = "col" if collision else "vis"
    for k, s in enumerate(shapes):
        local = s.shifted(offset)
        path = f"{parent}/{role}{k}"
        if local.kind == "box" and collision:
            cube = UsdGeom.Cube.Define(stage, path)
            cube.CreateSizeAttr(2.0)
            cube.AddTranslateOp().Set(Gf.Vec3d(*local.box.center.tolist()))
            cube.AddOrientOp().Set(_quatf(local.box.rotation))
            cube.AddScaleOp().Set(Gf.Vec3f(*local.box.half.tolist()))
            prim = cube
        else:
            v, f = local.solid() if collision else local.triangles()
            mesh = UsdGeom.Mesh.Define(stage, path)
            mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(v, np.float32)))
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(f), 3, np.int32)))
            mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(f, np.int32).ravel()))
            mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            prim = mesh
            if collision:
                UsdPhysics.MeshCollisionAPI.Apply(mesh.GetPrim()).CreateApproximationAttr(UsdPhysics.Tokens.convexHull)
        if collision:
            UsdPhysics.CollisionAPI.Apply(prim.GetPrim())
            prim.CreatePurposeAttr(UsdGeom.Tokens.guide)


def _mass(prim: Usd.Prim, props: MassProps, frame_origin: np.ndarray) -> None:
    UsdPhysics.RigidBodyAPI.Apply(prim)
    mass = UsdPhysics.MassAPI.Apply(prim)
    mass.CreateMassAttr(float(props.mass))
    mass.CreateCenterOfMassAttr(Gf.Vec3f(*(props.com - frame_origin).tolist()))
    mass.CreateDiagonalInertiaAttr(Gf.Vec3f(*props.principal.tolist()))
    mass.CreatePrincipalAxesAttr(_quatf(props.axes))


def _joint(stage: Usd.Stage, p: PartBody, cfg: SimConfig) -> None:
    path = f"{ROOT}/joints/{p.id}"
    revolute = p.kind == "revolute"
    joint = (UsdPhysics.RevoluteJoint if revolute else UsdPhysics.PrismaticJoint).Define(stage, path)
    joint.CreateBody0Rel().SetTargets([Sdf.Path(f"{ROOT}/static")])
    joint.CreateBody1Rel().SetTargets([Sdf.Path(f"{ROOT}/parts/{p.id}")])
    joint.CreateAxisAttr(UsdPhysics.Tokens.x)
    rot = _quatf(joint_frame(p.unit_axis))
    joint.CreateLocalPos0Attr(Gf.Vec3f(*p.axis_origin.tolist()))
    joint.CreateLocalRot0Attr(rot)
    joint.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.0))
    joint.CreateLocalRot1Attr(rot)
    lo, hi = p.limits
    scale = 180.0 / math.pi if revolute else 1.0
    joint.CreateLowerLimitAttr(float(lo * scale))
    joint.CreateUpperLimitAttr(float(hi * scale))
    jc = cfg.joint(p.kind)
    drive = UsdPhysics.DriveAPI.Apply(joint.GetPrim(), "angular" if revolute else "linear")
    drive.CreateTypeAttr("force")
    drive.CreateStiffnessAttr(0.0)
    gain = float(drive_gain(p, cfg) / scale)
    # passive unless asked: a drive's damping at target velocity 0 brakes the part (DRAWER's
    # 1e10); the servo's gain stays on the prim for whoever drives it
    drive.CreateDampingAttr(gain if cfg.drives_on_load else 0.0)
    joint.GetPrim().CreateAttribute("drawer:driveDamping", Sdf.ValueTypeNames.Float).Set(gain)
    drive.CreateTargetVelocityAttr(0.0)
    drive.CreateMaxForceAttr(float(jc.effort))


def usd_stage(model: TwinModel, cfg: SimConfig | None = None) -> Usd.Stage:
    """The in-memory USD stage of ``model`` (validated first: bad input raises ``InputError``
    naming the part); layout in the module docstring."""
    cfg = cfg or SimConfig()
    model.validate()
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    world = _xform(stage, ROOT)
    stage.SetDefaultPrim(world.GetPrim())
    scene = UsdPhysics.Scene.Define(stage, f"{ROOT}/PhysicsScene")
    scene.CreateGravityDirectionAttr(Gf.Vec3f(0.0, 0.0, -1.0))
    scene.CreateGravityMagnitudeAttr(float(cfg.gravity))

    zero = np.zeros(3)
    static = _xform(stage, f"{ROOT}/static").GetPrim()
    UsdPhysics.RigidBodyAPI.Apply(static)
    UsdPhysics.ArticulationRootAPI.Apply(static)
    _shapes(stage, f"{ROOT}/static", model.static_collision, zero, True)
    _shapes(stage, f"{ROOT}/static", model.static_visual, zero, False)
    UsdGeom.Scope.Define(stage, f"{ROOT}/joints")
    fixed = UsdPhysics.FixedJoint.Define(stage, f"{ROOT}/joints/static")  # body0 unset: the world
    fixed.CreateBody1Rel().SetTargets([static.GetPath()])
    if model.parts:
        _xform(stage, f"{ROOT}/parts")
    for p in model.parts:
        path = f"{ROOT}/parts/{p.id}"
        xf = _xform(stage, path, p.axis_origin)
        _mass(xf.GetPrim(), p.mass_properties(), p.axis_origin)
        _shapes(stage, path, p.collision, -p.axis_origin, True)
        _shapes(stage, path, p.visual, -p.axis_origin, False)
        _joint(stage, p, cfg)
    if model.rigid:
        _xform(stage, f"{ROOT}/rigid")
    for r in model.rigid:
        props = r.mass_properties()
        path = f"{ROOT}/rigid/{r.id}"
        xf = _xform(stage, path, props.com)
        _mass(xf.GetPrim(), props, props.com)
        _shapes(stage, path, r.collision, -props.com, True)
        _shapes(stage, path, r.visual, -props.com, False)
    return stage


def write_usd(model: TwinModel, folder: Path | str, cfg: SimConfig | None = None) -> Path:
    """Write ``folder/scene.usda`` atomically (exported and reopened in a temporary folder, then
    renamed into place); returns its path. Nothing is written when the model is invalid
    (``InputError`` naming the part)."""
    stage = usd_stage(model, cfg)
    folder = Path(folder)

    def build(root: Path) -> None:
        path = root / USD_FILE
        if not stage.GetRootLayer().Export(str(path)):
            raise InvariantError(f"write_usd: USD could not export {path}")
        if Usd.Stage.Open(str(path)) is None:
            raise InvariantError(f"write_usd: the written {USD_FILE} does not open")

    write_entries_atomic(folder, [USD_FILE], build)
    return folder / USD_FILE
