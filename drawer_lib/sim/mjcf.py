"""The twin as a MuJoCo model (``scene.xml`` of docs/formats.md), built in code with ``mujoco.MjSpec``.

Layout: the world frame is the capture's (m, +z up, gravity -z). The static scene is a body
``static`` without joints (welded to the world) holding the static collision pieces and the
visual meshes. Each articulated part is a body ``<id>`` at its axis origin (world-aligned) with
one joint ``<id>`` (``hinge`` / ``slide`` through the body origin along the axis, range =
limits) and one velocity actuator ``<id>`` on it, off as the file loads. Each rigid object is a body ``<id>`` at its
centre of mass with a free joint ``<id>``. Geoms are named ``<owner>/col<k>`` (collision, group
3) and ``<owner>/vis<k>`` (visual, group 2, no contacts).

Decisions:

* Mesh assets are files: ``assets/<owner>.col<k>.obj`` / ``.vis<k>.obj`` (OBJ, 9 significant
  digits, in the body frame), referenced through ``<compiler meshdir="assets">``; the spec
  carries them in ``spec.assets`` so it compiles in memory, and :func:`write_mjcf` writes them
  next to ``scene.xml``. A collision mesh is written as its convex hull (what MuJoCo collides).
* Masses and inertias: explicit ``<inertial>`` per body from :func:`drawer_lib.bodies.
  mass_properties` (collision solids x density; ``inertiafromgeom="false"``), the same numbers
  the URDF and USD get.
* Contacts by ``contype`` / ``conaffinity`` bits (static 1, part 2, rigid 4): rigid objects
  collide with everything; parts with rigid objects, with each other when
  ``cfg.contact.part_part`` and with the static scene when ``cfg.contact.part_static`` (both on
  by default; the twin stage trims the overlaps at q = 0 first, :mod:`drawer_lib.sim.repair`, so
  nothing is in contact as the file loads).
* Passive as loaded: the drives are actuator group 1 (:data:`DRIVE_GROUP`), disabled by
  ``<option actuatorgroupdisable>`` unless ``cfg.drives_on_load``: the file a user loads is a
  kitchen whose parts a hand or a robot moves against their joints' damping and friction alone
  (an enabled servo at its default control 0 is a damper of gain ``kv``: a 20 N pull moves a
  5 kg drawer ~5 cm in 3 s). Whoever drives the parts turns the group on (:func:`set_drives`).
* Drives: a velocity servo, force = (kv + damping) ctrl - kv qdot (the joint's viscous damping fed
  forward, so that the steady speed is the target less only friction / (kv + damping), even for
  a light door whose kv is near its hinge's damping; at ctrl = 0 a damper of gain kv), with
  ``kv = (inertia about the joint + armature) / drive_tau`` (the
  same response for every part whatever its mass; a gain proportional to the inertia never
  outruns the integrator, even when the force limit clips it), control range +-drive speed,
  force range +-effort. Joint limits and dry friction use ``solreflimit = solreffriction =
  (limit_timeconst, 1)`` (MuJoCo's friction is a soft constraint: at its default 0.02 s a drawer
  held by friction on a 2° slope creeps 0.35 mm/s, at 0.004 s 0.07 mm/s).
"""


import math
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np

from drawer_lib.errors import InputError, InvariantError
from drawer_lib.paths import stage_name
from drawer_lib.sim.files import obj_bytes, shortest, write_entries_atomic
from drawer_lib.bodies import MassProps, PartBody, Shape, TwinModel, axis_inertia
from drawer_lib.sim.config import SimConfig

STATIC = "static"
MESHDIR = stage_name("twin", "mjcf_assets")
SCENE = stage_name("twin", "mjcf")
BIT_STATIC, BIT_PART, BIT_RIGID = 1, 2, 4
DRIVE_GROUP = 1  # the actuator group of the parts' drives (bit DRIVE_GROUP of opt.disableactuator)
GROUP_VISUAL, GROUP_COLLISION = 2, 3
_MIN_MASS, _MIN_INERTIA = 1e-9, 1e-12  # kg, kg·m^2
# the integrators by their config names (``sim.integrator``, ``stability.integrators``)
INTEGRATOR_ENUM = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                   "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST, "rk4": mujoco.mjtIntegrator.mjINT_RK4}


def contact_bits(cfg: SimConfig) -> dict[str, tuple[int, int]]:
    """(contype, conaffinity) of the collision geoms of ``static``, ``part`` and ``rigid`` bodies
    (MuJoCo collides two geoms when ``contype1 & conaffinity2 or contype2 & conaffinity1``)."""
    part_aff = BIT_RIGID | (BIT_PART if cfg.contact.part_part else 0) | (BIT_STATIC if cfg.contact.part_static else 0)
    static_aff = BIT_RIGID | (BIT_PART if cfg.contact.part_static else 0)
    return {"static": (BIT_STATIC, static_aff), "part": (BIT_PART, part_aff),
            "rigid": (BIT_RIGID, BIT_STATIC | BIT_PART | BIT_RIGID)}


def _quat(R: np.ndarray) -> list[float]:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, np.float64).ravel())
    return q.tolist()


def _add_shapes(spec: mujoco.MjSpec, body: mujoco.MjsBody, owner: str, shapes: list[Shape], offset: np.ndarray,
                collision: bool, bits: tuple[int, int], cfg: SimConfig, assets: dict[str, bytes]) -> None:
    """Geoms of ``shapes`` (world frame) in ``body``, whose frame is world-aligned at -offset."""
    role = "col" if collision else "vis"
    for k, s in enumerate(shapes):
        name = f"{owner}/{role}{k}"
        local = s.shifted(offset)
        if local.kind == "box":
            g = body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=local.box.half.tolist(),
                              pos=local.box.center.tolist(), quat=_quat(local.box.rotation))
        else:
            v, f = local.solid() if collision else local.triangles()
            fname = f"{owner}.{role}{k}.obj"
            assets[fname] = obj_bytes(v, f)
            mesh = spec.add_mesh(name=name, file=fname)
            mesh.inertia = (mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX if collision
                            else mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL)
            g = body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name)
        if collision:
            g.contype, g.conaffinity = bits
            g.group = GROUP_COLLISION
            g.friction = [cfg.contact.friction, cfg.contact.friction_torsion, cfg.contact.friction_roll]
            g.rgba = [0.6, 0.6, 0.9, 0.4]
        else:
            g.contype = g.conaffinity = 0
            g.group = GROUP_VISUAL
            g.rgba = [0.8, 0.75, 0.7, 1.0]


def _set_inertial(body: mujoco.MjsBody, props: MassProps, frame_origin: np.ndarray) -> None:
    body.explicitinertial = True
    body.mass = props.mass
    body.ipos = (props.com - frame_origin).tolist()
    body.iquat = _quat(props.axes)
    body.inertia = props.principal.tolist()


def drive_gain(part: PartBody, cfg: SimConfig, props: MassProps | None = None) -> float:
    """``kv`` of a part's velocity servo (N·m·s/rad or N·s/m): (inertia about its joint +
    armature) / drive_tau, see :class:`drawer_lib.bodies.JointConfig`."""
    props = props or part.mass_properties()
    jc = cfg.joint(part.kind)
    return (axis_inertia(props, part.kind, part.axis_origin, part.unit_axis) + jc.armature) / jc.drive_tau


def build_spec(model: TwinModel, cfg: SimConfig | None = None) -> mujoco.MjSpec:
    """The MuJoCo spec of ``model`` (validated first: bad input raises ``InputError`` naming the
    part). It compiles in memory (``spec.compile()``: mesh files live in ``spec.assets``);
    :func:`write_mjcf` writes it. See the module docstring for names, frames and decisions."""
    cfg = cfg or SimConfig()
    model.validate()
    bits = contact_bits(cfg)
    spec = mujoco.MjSpec()
    spec.modelname = "drawer_twin"
    spec.compiler.degree = False
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.compiler.autolimits = True
    # floors for slivers (a 1 mm^3 piece): below MuJoCo's minimum a body would not compile; a
    # real part's mass (> 1 g) and inertia (> 1e-8 kg·m^2) are far above them and stay exact
    spec.compiler.boundmass = _MIN_MASS
    spec.compiler.boundinertia = _MIN_INERTIA
    spec.meshdir = MESHDIR
    spec.option.timestep = cfg.timestep
    spec.option.integrator = INTEGRATOR_ENUM[cfg.integrator]
    spec.option.gravity = [0.0, 0.0, -cfg.gravity]
    spec.option.disableactuator = 0 if cfg.drives_on_load else 1 << DRIVE_GROUP
    assets: dict[str, bytes] = {}
    zero = np.zeros(3)

    static = spec.worldbody.add_body(name=STATIC)
    _add_shapes(spec, static, STATIC, model.static_collision, zero, True, bits["static"], cfg, assets)
    _add_shapes(spec, static, STATIC, model.static_visual, zero, False, bits["static"], cfg, assets)

    for p in model.parts:
        props = p.mass_properties()
        origin = p.axis_origin
        jc = cfg.joint(p.kind)
        body = spec.worldbody.add_body(name=p.id, pos=origin.tolist())
        _set_inertial(body, props, origin)
        if p.kind == "revolute" and abs(p.unit_axis[2]) < math.sqrt(0.5):  # a flap: its lift / spring
            body.gravcomp = cfg.flap_gravcomp
        body.add_joint(name=p.id, type=mujoco.mjtJoint.mjJNT_HINGE if p.kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE,
                       pos=[0.0, 0.0, 0.0], axis=p.unit_axis.tolist(), range=list(p.limits),
                       limited=mujoco.mjtLimited.mjLIMITED_TRUE, damping=jc.damping, armature=jc.armature,
                       frictionloss=jc.friction(props.mass, cfg.gravity),
                       solref_limit=[cfg.contact.limit_timeconst, 1.0],
                       solref_friction=[cfg.contact.limit_timeconst, 1.0])
        _add_shapes(spec, body, p.id, p.collision, -origin, True, bits["part"], cfg, assets)
        _add_shapes(spec, body, p.id, p.visual, -origin, False, bits["part"], cfg, assets)
        act = spec.add_actuator(name=p.id, target=p.id, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        kv = drive_gain(p, cfg, props)
        act.set_to_velocity(kv=kv)
        gain = np.array(act.gainprm)
        gain[0] = kv + jc.damping  # feed-forward of the joint's damping: force = (kv + b) u - kv qdot
        act.gainprm = gain
        act.group = DRIVE_GROUP
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = [-jc.speed, jc.speed]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-jc.effort, jc.effort]

    for r in model.rigid:
        props = r.mass_properties()
        body = spec.worldbody.add_body(name=r.id, pos=props.com.tolist())
        _set_inertial(body, props, props.com)
        body.add_freejoint(name=r.id)
        _add_shapes(spec, body, r.id, r.collision, -props.com, True, bits["rigid"], cfg, assets)
        _add_shapes(spec, body, r.id, r.visual, -props.com, False, bits["rigid"], cfg, assets)

    spec.assets = assets
    return spec


def compile_spec(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """``spec.compile()``, a MuJoCo compile error raised as ``InvariantError`` (the input was
    validated, so a compile error is a bug)."""
    try:
        return spec.compile()
    except ValueError as e:
        raise InvariantError(f"MuJoCo could not compile the twin: {e}") from e


# XML attributes MuJoCo's writer rounds to 6 significant digits, per element tag: attribute ->
# field of the spec element of the same name (``inertial`` reads its parent body)
_PRECISE = {
    "option": {"timestep": "timestep", "gravity": "gravity"},
    "body": {"pos": "pos", "quat": "quat"},
    "inertial": {"pos": "ipos", "quat": "iquat", "mass": "mass", "diaginertia": "inertia"},
    "joint": {"pos": "pos", "axis": "axis", "range": "range", "damping": "damping", "armature": "armature",
              "frictionloss": "frictionloss", "solreflimit": "solref_limit", "solreffriction": "solref_friction"},
    "geom": {"pos": "pos", "quat": "quat", "size": "size", "friction": "friction"},
    "general": {"gainprm": "gainprm", "biasprm": "biasprm", "ctrlrange": "ctrlrange", "forcerange": "forcerange"},
}


def full_precision_xml(spec: mujoco.MjSpec) -> str:
    """``spec.to_xml()`` with the numbers of :data:`_PRECISE` written exactly (shortest round-trip
    decimals)
    (MuJoCo's writer keeps 6, which would move a 2 m coordinate by up to 10 µm and a range of
    pi / 2 by 4e-6 rad between the spec and the file)."""
    root = ET.fromstring(spec.to_xml())
    finders = {"body": spec.body, "joint": spec.joint, "geom": spec.geom, "general": spec.actuator}

    def rewrite(el: ET.Element, obj, attrs: dict[str, str]) -> None:
        for attr, fld in attrs.items():
            old = el.get(attr)
            if old is None or obj is None:
                continue
            vals = np.atleast_1d(np.asarray(getattr(obj, fld), np.float64)).ravel()
            k = len(old.split())
            if k <= len(vals) and np.isfinite(vals[:k]).all():
                el.set(attr, " ".join(shortest(v) for v in vals[:k]))

    for el in root.iter():
        if el.tag == "option":
            rewrite(el, spec.option, _PRECISE["option"])
        elif el.tag in finders and el.get("name"):
            obj = finders[el.tag](el.get("name"))
            rewrite(el, obj, _PRECISE[el.tag])
            if el.tag == "body":
                for inertial in el.findall("inertial"):
                    rewrite(inertial, obj, _PRECISE["inertial"])
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def write_mjcf(spec: mujoco.MjSpec, folder: Path | str) -> Path:
    """Write ``folder/scene.xml`` and its meshes ``folder/assets/*.obj`` atomically (built and
    loaded back in a temporary folder, then renamed into place; other files of ``folder`` are
    kept). Returns the path of ``scene.xml``, which ``mujoco.MjModel.from_xml_path`` loads with
    no other file."""
    folder = Path(folder)
    compile_spec(spec)
    xml = full_precision_xml(spec)
    assets = dict(spec.assets)

    def build(root: Path) -> None:
        (root / MESHDIR).mkdir()
        for name, data in assets.items():
            (root / MESHDIR / name).write_bytes(data)
        (root / SCENE).write_text(xml)
        try:
            mujoco.MjModel.from_xml_path(str(root / SCENE))
        except ValueError as e:
            raise InvariantError(f"write_mjcf: the written {SCENE} does not load: {e}") from e

    write_entries_atomic(folder, [MESHDIR, SCENE], build)
    return folder / SCENE


def set_drives(m: mujoco.MjModel, on: bool) -> mujoco.MjModel:
    """Turn the parts' drives (actuator group :data:`DRIVE_GROUP`) on or off in the compiled
    model ``m`` (in place; returned for chaining). As the twin loads they are off."""
    bit = 1 << DRIVE_GROUP
    m.opt.disableactuator = (int(m.opt.disableactuator) & ~bit) if on else (int(m.opt.disableactuator) | bit)
    return m


def drives_on(m: mujoco.MjModel) -> bool:
    """Whether the parts' drives act in ``m`` (actuation enabled and their group not disabled)."""
    return not (int(m.opt.disableactuator) >> DRIVE_GROUP) & 1 and not (
        int(m.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION))


def part_index(m: mujoco.MjModel, pid: str) -> dict[str, int]:
    """MuJoCo ids of part ``pid``: body, joint, actuator (-1 when absent), qpos and dof address."""
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, pid)
    joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, pid)
    act = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, pid)
    return {"body": body, "joint": joint, "actuator": act,
            "qpos": int(m.jnt_qposadr[joint]) if joint >= 0 else -1,
            "dof": int(m.jnt_dofadr[joint]) if joint >= 0 else -1}





def load_twin(twin_dir: Path, parts_path: Path) -> tuple[Path, mujoco.MjModel]:
    """(``scene.xml``, its compiled model) of a written twin, after checking that the twin and
    the parts file it was built from exist; a missing or unloadable file is an
    :class:`~drawer_lib.errors.InputError` naming it."""
    xml = Path(twin_dir) / SCENE
    for p, what in ((xml, "twin"), (Path(parts_path), "articulate")):
        if not p.is_file():
            raise InputError(f"{p}: missing (run the {what} stage first)")
    try:
        return xml, mujoco.MjModel.from_xml_path(str(xml))
    except ValueError as e:
        raise InputError(f"{xml}: MuJoCo cannot load it ({e})") from e
