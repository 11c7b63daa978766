"""The twin as a URDF (``urdf/scene.urdf`` + ``urdf/meshes/*.obj``; docs/formats.md).

Tree: a root link ``world``; the static scene in link ``static`` fixed to it (joint
``static``); each articulated part a link ``<id>`` under ``static`` through a ``revolute`` /
``prismatic`` joint ``<id>`` whose origin is the axis origin (world-aligned, rpy 0), so the
joint's ``<axis>`` is the world axis and the link's geometry is expressed relative to the joint
frame; each rigid object a link ``<id>`` under ``world`` through a ``floating`` joint ``<id>``
at its centre of mass. Inertials are the mass properties of the collision solids (full
tensor about the centre of mass, link axes); collision = the convex pieces (boxes as
``<box>``, meshes as their convex hulls), visual = the visual meshes; mesh files are OBJ,
referenced relative to the URDF. Limits: ``lower``/``upper`` rad or m, ``velocity`` the drive
speed, ``effort`` the drive's force limit, ``<dynamics damping friction>`` from the config.
"""

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from drawer_lib.sim.files import obj_bytes, shortest, write_entries_atomic
from drawer_lib.bodies import MassProps, Shape, TwinModel
from drawer_lib.paths import stage_name
from drawer_lib.sim.config import SimConfig

URDF_DIR, URDF_FILE = stage_name("twin", "urdf").split("/")
MESH_DIR = stage_name("twin", "urdf_meshes").split("/")[1]  # inside URDF_DIR


def _fmt(a) -> str:
    return " ".join(shortest(float(x)) for x in np.atleast_1d(a))


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw [3] (rad) of a rotation [3, 3]: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cp = math.hypot(R[0, 0], R[1, 0])
    pitch = math.atan2(-R[2, 0], cp)
    if cp > 1e-9:
        roll, yaw = math.atan2(R[2, 1], R[2, 2]), math.atan2(R[1, 0], R[0, 0])
    else:  # gimbal lock: put the whole rotation about z into yaw
        roll, yaw = 0.0, math.atan2(-R[0, 1], R[1, 1])
    return np.array([roll, pitch, yaw])


def _geometries(link: ET.Element, owner: str, shapes: list[Shape], offset: np.ndarray, collision: bool,
                files: dict[str, bytes]) -> None:
    role = "col" if collision else "vis"
    for k, s in enumerate(shapes):
        local = s.shifted(offset)
        el = ET.SubElement(link, "collision" if collision else "visual", name=f"{owner}_{role}{k}")
        geo = ET.Element("geometry")
        if local.kind == "box":
            ET.SubElement(el, "origin", xyz=_fmt(local.box.center), rpy=_fmt(matrix_to_rpy(local.box.rotation)))
            ET.SubElement(geo, "box", size=_fmt(2 * local.box.half))
        else:
            v, f = local.solid() if collision else local.triangles()
            fname = f"{owner}.{role}{k}.obj"
            files[fname] = obj_bytes(v, f)
            ET.SubElement(el, "origin", xyz="0 0 0", rpy="0 0 0")
            ET.SubElement(geo, "mesh", filename=f"{MESH_DIR}/{fname}")
        el.append(geo)


def _inertial(link: ET.Element, props: MassProps, frame_origin: np.ndarray) -> None:
    el = ET.SubElement(link, "inertial")
    ET.SubElement(el, "origin", xyz=_fmt(props.com - frame_origin), rpy="0 0 0")
    ET.SubElement(el, "mass", value=_fmt(props.mass))
    I = props.inertia
    ET.SubElement(el, "inertia", ixx=_fmt(I[0, 0]), ixy=_fmt(I[0, 1]), ixz=_fmt(I[0, 2]), iyy=_fmt(I[1, 1]),
                  iyz=_fmt(I[1, 2]), izz=_fmt(I[2, 2]))


def urdf_tree(model: TwinModel, cfg: SimConfig | None = None) -> tuple[ET.ElementTree, dict[str, bytes]]:
    """The URDF element tree of ``model`` and its mesh files {name: OBJ bytes} (validated
    first: bad input raises ``InputError`` naming the part)."""
    cfg = cfg or SimConfig()
    model.validate()
    files: dict[str, bytes] = {}
    robot = ET.Element("robot", name="drawer_twin")
    ET.SubElement(robot, "link", name="world")
    static = ET.SubElement(robot, "link", name="static")
    zero = np.zeros(3)
    _geometries(static, "static", model.static_visual, zero, False, files)
    _geometries(static, "static", model.static_collision, zero, True, files)
    j = ET.SubElement(robot, "joint", name="static", type="fixed")
    ET.SubElement(j, "origin", xyz="0 0 0", rpy="0 0 0")
    ET.SubElement(j, "parent", link="world")
    ET.SubElement(j, "child", link="static")

    for p in model.parts:
        props = p.mass_properties()
        link = ET.SubElement(robot, "link", name=p.id)
        _inertial(link, props, p.axis_origin)
        _geometries(link, p.id, p.visual, -p.axis_origin, False, files)
        _geometries(link, p.id, p.collision, -p.axis_origin, True, files)
        jc = cfg.joint(p.kind)
        j = ET.SubElement(robot, "joint", name=p.id, type=p.kind)
        ET.SubElement(j, "origin", xyz=_fmt(p.axis_origin), rpy="0 0 0")
        ET.SubElement(j, "parent", link="static")
        ET.SubElement(j, "child", link=p.id)
        ET.SubElement(j, "axis", xyz=_fmt(p.unit_axis))
        ET.SubElement(j, "limit", lower=_fmt(p.limits[0]), upper=_fmt(p.limits[1]), effort=_fmt(jc.effort),
                      velocity=_fmt(jc.speed))
        ET.SubElement(j, "dynamics", damping=_fmt(jc.damping), friction=_fmt(jc.friction(props.mass, cfg.gravity)))

    for r in model.rigid:
        props = r.mass_properties()
        link = ET.SubElement(robot, "link", name=r.id)
        _inertial(link, props, props.com)
        _geometries(link, r.id, r.visual, -props.com, False, files)
        _geometries(link, r.id, r.collision, -props.com, True, files)
        j = ET.SubElement(robot, "joint", name=r.id, type="floating")
        ET.SubElement(j, "origin", xyz=_fmt(props.com), rpy="0 0 0")
        ET.SubElement(j, "parent", link="world")
        ET.SubElement(j, "child", link=r.id)

    tree = ET.ElementTree(robot)
    ET.indent(tree)
    return tree, files


def write_urdf(model: TwinModel, folder: Path | str, cfg: SimConfig | None = None) -> Path:
    """Write ``folder/urdf/scene.urdf`` and ``folder/urdf/meshes/*.obj`` atomically (the whole
    ``urdf/`` folder is replaced in one rename); returns the URDF path. Nothing is written when
    the model is invalid (``InputError`` naming the part)."""
    tree, files = urdf_tree(model, cfg)
    folder = Path(folder)

    def build(root: Path) -> None:
        meshes = root / URDF_DIR / MESH_DIR
        meshes.mkdir(parents=True)
        for name, data in files.items():
            (meshes / name).write_bytes(data)
        tree.write(root / URDF_DIR / URDF_FILE, encoding="utf-8", xml_declaration=True)

    write_entries_atomic(folder, [URDF_DIR], build)
    return folder / URDF_DIR / URDF_FILE
