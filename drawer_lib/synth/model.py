"""Build the MuJoCo model of a kitchen layout in code (MjSpec) and render it offscreen.

Every piece becomes a mesh geom with metric texture coordinates (pieces of one entity, role and
material are merged into one mesh). Articulated fronts are bodies whose frame origin is their
GT axis origin, with a hinge or slide joint along the GT axis direction and the GT limits;
rigid objects get a free joint. The model is for rendering and kinematics: geoms do not
collide (the twin stage builds the simulation model from the reconstruction).

Rendering uses ``mujoco.Renderer`` offscreen with the GL backend :mod:`drawer_lib.synth.gl`
selects (``MUJOCO_GL``; EGL, else OSMesa).
"""

from dataclasses import dataclass

from drawer_lib.synth import gl  # noqa: F401  (must precede the mujoco import)

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from drawer_lib.errors import ConfigError  # noqa: E402
from drawer_lib.geometry.camera import Intrinsics  # noqa: E402
from drawer_lib.geometry.rotations import matrix_to_quat  # noqa: E402
from drawer_lib.synth.config import RenderConfig  # noqa: E402
from drawer_lib.synth.layout import Entity, KitchenLayout  # noqa: E402
from drawer_lib.synth.meshes import concat  # noqa: E402

CAMERA = "capture_cam"
_EXTENT = 5.0  # stat.extent: near/far planes are fractions of it
_ZNEAR, _ZFAR = 0.01, 6.0  # -> 5 cm and 30 m


@dataclass
class KitchenModel:
    """A compiled kitchen with the maps from MuJoCo ids back to the layout."""

    model: mujoco.MjModel
    layout: KitchenLayout
    geom_entity: np.ndarray  # [ngeom] index into layout.entities
    geom_handle: np.ndarray  # [ngeom] bool: the geom is a handle
    joint_of_entity: dict[int, int]  # entity index -> joint id (articulated and free)


def _add_entity_geoms(spec: mujoco.MjSpec, parent, e: Entity, origin: np.ndarray, prefix: str,
                      materials) -> list[tuple[str, bool]]:
    groups: dict[tuple[str, str], list] = {}
    for p in e.pieces:
        groups.setdefault((p.role, p.material), []).append(p.mesh)
    names = []
    for k, ((role, mat), meshes) in enumerate(sorted(groups.items())):
        m = concat(meshes)
        mname = f"{prefix}/{role}/{mat}/{k}"
        mesh = spec.add_mesh(name=mname)
        mesh.uservert = (m.verts - origin).ravel().tolist()
        mesh.userface = m.faces.ravel().tolist()
        mesh.usertexcoord = (m.uv / materials[mat].size_m).ravel().tolist()
        mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        g = parent.add_geom(name=mname, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mname, material=mat)
        g.contype = 0
        g.conaffinity = 0
        names.append((mname, role == "handle"))
    return names


def build_model(layout: KitchenLayout, cam: Intrinsics, render: RenderConfig | None = None) -> KitchenModel:
    """Compile the MuJoCo model of ``layout`` with an offscreen camera of intrinsics ``cam``.

    ``cam`` must have square pixels and a centred principal point (MuJoCo's pinhole)."""
    render = render or RenderConfig()
    if abs(cam.fx - cam.fy) > 1e-6 * cam.fx or abs(cam.cx - cam.width / 2) > 1e-6 or abs(cam.cy - cam.height / 2) > 1e-6:
        raise ConfigError("build_model: MuJoCo cameras need square pixels and a centred principal point")
    spec = mujoco.MjSpec()
    spec.modelname = f"kitchen_{layout.seed}"
    spec.compiler.degree = False
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.stat.extent = _EXTENT
    spec.stat.center = ((layout.room_lo + layout.room_hi) / 2).tolist()
    spec.visual.map.znear = _ZNEAR
    spec.visual.map.zfar = _ZFAR
    spec.visual.global_.offwidth = max(cam.width, 64)
    spec.visual.global_.offheight = max(cam.height, 64)
    spec.visual.quality.offsamples = render.multisamples
    spec.visual.quality.shadowsize = render.shadow_size
    spec.visual.headlight.ambient = [0.32, 0.32, 0.32]  # view-independent ambient term only
    spec.visual.headlight.diffuse = [0.0, 0.0, 0.0]
    spec.visual.headlight.specular = [0.0, 0.0, 0.0]

    for m in layout.materials.values():
        h, w, _ = m.texture.shape
        t = spec.add_texture(name=m.name, type=mujoco.mjtTexture.mjTEXTURE_2D, width=w, height=h, nchannel=3)
        t.data = np.ascontiguousarray(m.texture).tobytes()
        mat = spec.add_material(name=m.name)
        slots = list(mat.textures)
        slots[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = m.name
        mat.textures = slots
        mat.specular = m.specular
        mat.shininess = m.shininess

    for li in layout.lights:
        light = spec.worldbody.add_light(pos=list(li.pos), dir=list(li.dir))
        light.diffuse = [li.diffuse] * 3
        light.specular = [0.05] * 3
        light.castshadow = li.castshadow

    geom_names: list[tuple[str, int, bool]] = []
    joint_names: dict[int, str] = {}
    for ei, e in enumerate(layout.entities):
        if e.joint is None:
            for n, is_h in _add_entity_geoms(spec, spec.worldbody, e, np.zeros(3), e.name, layout.materials):
                geom_names.append((n, ei, is_h))
            continue
        if e.joint == "free":
            lo, hi = e.mesh().bounds
            origin = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
        else:
            origin = np.asarray(e.axis_origin, np.float64)
        body = spec.worldbody.add_body(name=e.name, pos=origin.tolist())
        lo, hi = e.mesh().bounds - origin
        size = np.maximum(hi - lo, 1e-3)
        body.mass = e.mass
        body.ipos = ((lo + hi) / 2).tolist()
        body.inertia = (e.mass / 12.0 * np.array([size[1] ** 2 + size[2] ** 2, size[0] ** 2 + size[2] ** 2,
                                                   size[0] ** 2 + size[1] ** 2])).tolist()
        body.explicitinertial = True
        if e.joint == "free":
            body.add_freejoint(name=f"{e.name}/joint")
        else:
            j = body.add_joint(name=f"{e.name}/joint")
            j.type = mujoco.mjtJoint.mjJNT_HINGE if e.joint == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE
            j.axis = np.asarray(e.axis_dir, np.float64).tolist()
            j.pos = [0.0, 0.0, 0.0]
            j.range = list(e.limits)
            j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            j.damping = [1.0, 0.0, 0.0]
        joint_names[ei] = f"{e.name}/joint"
        for n, is_h in _add_entity_geoms(spec, body, e, origin, e.name, layout.materials):
            geom_names.append((n, ei, is_h))

    cam_ = spec.worldbody.add_camera(name=CAMERA)
    cam_.fovy = float(np.rad2deg(2 * np.arctan(0.5 * cam.height / cam.fy)))
    model = spec.compile()

    geom_entity = np.zeros(model.ngeom, np.int32)
    geom_handle = np.zeros(model.ngeom, bool)
    for n, ei, is_h in geom_names:
        gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n)
        geom_entity[gid] = ei
        geom_handle[gid] = is_h
    joints = {ei: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for ei, n in joint_names.items()}
    return KitchenModel(model, layout, geom_entity, geom_handle, joints)


class KitchenRenderer:
    """Offscreen RGB, z-depth and segmentation (entity index, handle flag) of a kitchen model."""

    def __init__(self, km: KitchenModel, cam: Intrinsics):
        self.km, self.cam = km, cam
        self.data = mujoco.MjData(km.model)
        self.cam_id = mujoco.mj_name2id(km.model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA)
        self.renderer = mujoco.Renderer(km.model, cam.height, cam.width)
        mujoco.mj_forward(km.model, self.data)

    def set_joint(self, entity_name: str, q: float) -> None:
        """Pose one articulated part at joint value ``q`` (rad or m) for the next renders."""
        ei = next(i for i, e in enumerate(self.km.layout.entities) if e.name == entity_name)
        self.data.qpos[self.km.model.jnt_qposadr[self.km.joint_of_entity[ei]]] = q
        mujoco.mj_forward(self.km.model, self.data)

    def set_camera(self, c2w_gl: np.ndarray) -> None:
        """Place the camera (OpenGL camera-to-world: MuJoCo cameras look along their -z)."""
        self.km.model.cam_pos[self.cam_id] = c2w_gl[:3, 3]
        self.km.model.cam_quat[self.cam_id] = matrix_to_quat(c2w_gl[:3, :3])
        mujoco.mj_forward(self.km.model, self.data)

    def render(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(rgb uint8 [H, W, 3], depth float32 [H, W] metres, entity int32 [H, W] (-1 = none),
        handle bool [H, W]) from the current camera."""
        r = self.renderer
        r.disable_depth_rendering()
        r.disable_segmentation_rendering()
        r.update_scene(self.data, camera=self.cam_id)
        rgb = r.render().copy()
        r.enable_depth_rendering()
        r.update_scene(self.data, camera=self.cam_id)
        depth = r.render().copy()
        r.disable_depth_rendering()
        r.enable_segmentation_rendering()
        r.update_scene(self.data, camera=self.cam_id)
        seg = r.render().copy()
        r.disable_segmentation_rendering()
        gid, gtype = seg[..., 0], seg[..., 1]
        is_geom = (gtype == int(mujoco.mjtObj.mjOBJ_GEOM)) & (gid >= 0)
        ent = np.full(gid.shape, -1, np.int32)
        ent[is_geom] = self.km.geom_entity[gid[is_geom]]
        handle = np.zeros(gid.shape, bool)
        handle[is_geom] = self.km.geom_handle[gid[is_geom]]
        return rgb, depth, ent, handle

    def close(self) -> None:
        self.renderer.close()
