"""What the viewer shows of a twin folder (docs/formats.md#twin-drawertwin1), read without any web code.

A twin folder holds ``twin.json`` (bodies by part id and their Gaussian PLYs) and ``scene.xml``
(the MJCF the simulator runs). The viewer takes every pose from MuJoCo, so what it shows is what
the simulator simulates:

* **Gaussians** (``gaussians/<id>.ply``, world frame at q = 0) are turned into what a splat
  renderer draws: centres, full 3x3 covariances ``R diag(s^2) R^T``, the degree-0 colour and
  opacities. The web client stores covariances as float16, which rounds a 0.1 mm standard
  deviation (variance 1e-8 m^2) to zero and overflows above ~256 m, so scales are clamped to
  ``[min_scale, max_scale]`` and the number clamped is reported.
* **Collision geometry** is the MJCF's collision geoms (boxes and meshes, as MuJoCo collides a
  mesh: its convex hull), in world coordinates at q = 0.
* **Joints** (anchor, axis, range) are MuJoCo's at q = 0.
* **Motion**: a body's Gaussians and hulls are given at rest, so a body moves them by its
  *relative* pose ``X_b(q) X_b(0)^-1`` (:func:`relative_poses`), which is the same rigid motion
  for an articulated part, a free object and anything the user drops in.

Units: metres, radians; quaternions are wxyz (MuJoCo's and viser's order).
"""

import json
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import trimesh
from jaxtyping import Float

from drawer_lib.errors import InputError
from drawer_lib.paths import stage_name
from drawer_lib.geometry.rotations import matrix_to_quat, quat_to_matrix
from drawer_lib.splat.sh import C0
from drawer_lib.splat.ply import read_gaussian_ply

TWIN_SCHEMA = "drawer.twin/1"
STATIC = "static"
ARTICULATED = ("revolute", "prismatic")


@dataclass
class Splats:
    """Gaussians as a splat renderer draws them: ``centers`` [N, 3] (m), ``covariances``
    [N, 3, 3] (m^2), ``rgbs`` [N, 3] in [0, 1] (degree-0 colour), ``opacities`` [N, 1] in
    [0, 1]; all float32. ``n_clamped`` counts Gaussians whose scales were clamped."""

    centers: np.ndarray
    covariances: np.ndarray
    rgbs: np.ndarray
    opacities: np.ndarray
    n_clamped: int = 0

    def __len__(self) -> int:
        return len(self.centers)


@dataclass
class Joint:
    """A part's joint at q = 0 (world frame): ``anchor`` [3] (m), unit ``axis`` [3] (positive q
    opens), ``range`` (lo, hi) in rad or m."""

    kind: str
    anchor: np.ndarray
    axis: np.ndarray
    range: tuple[float, float]


@dataclass
class ViewBody:
    """One body of the twin: ``id`` (the part id, or ``static``), ``kind`` (``static``,
    ``revolute``, ``prismatic`` or ``rigid``), its Gaussians (None when it has none), its
    collision hulls as (vertices [V, 3], faces [F, 3]) in world coordinates at rest, its joint
    (articulated parts only) and its MuJoCo body id."""

    id: str
    kind: str
    splats: Splats | None
    hulls: list[tuple[np.ndarray, np.ndarray]]
    joint: Joint | None
    mj_body: int
    confidence: float | None = None  # the type decision's probability (parts.json), None when unknown
    low_margin: bool = False  # the decision's margin over the runner-up was low: check this part

    @property
    def articulated(self) -> bool:
        return self.kind in ARTICULATED


@dataclass
class TwinScene:
    """A loaded twin: its folder, ``scene.xml`` and compiled model, the static body and the moving
    bodies in ``twin.json`` order, and the rest pose of every MuJoCo body (``rest_xpos`` [B, 3],
    ``rest_xquat`` [B, 4], wxyz) that :func:`relative_poses` measures motion from."""

    folder: Path
    xml: Path
    model: mujoco.MjModel
    static: ViewBody
    bodies: list[ViewBody]
    rest_xpos: np.ndarray
    rest_xquat: np.ndarray

    @property
    def n_clamped(self) -> int:
        """Gaussians drawn with clamped scales (see :func:`splats_of`)."""
        return sum(b.splats.n_clamped for b in [self.static, *self.bodies] if b.splats is not None)

    @property
    def n_gaussians(self) -> int:
        return sum(len(b.splats) for b in [self.static, *self.bodies] if b.splats is not None)

    def body(self, pid: str) -> ViewBody:
        for b in self.bodies:
            if b.id == pid:
                return b
        raise KeyError(f"{pid!r} is not a body of {self.folder} (bodies: {[b.id for b in self.bodies]})")

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) [3] of the Gaussian centres (2nd and 98th percentile: robust to floaters), or
        of the collision hulls when there are no Gaussians."""
        pts = [b.splats.centers for b in [self.static, *self.bodies] if b.splats is not None and len(b.splats)]
        if pts:
            p = np.concatenate(pts)
            return np.percentile(p, 2, axis=0), np.percentile(p, 98, axis=0)
        v = np.concatenate([h[0] for b in [self.static, *self.bodies] for h in b.hulls] or [np.zeros((1, 3))])
        return v.min(0), v.max(0)


def covariances(quats: Float[np.ndarray, "N 4"], scales: Float[np.ndarray, "N 3"]) -> Float[np.ndarray, "N 3 3"]:
    """``R diag(scales^2) R^T`` per Gaussian; ``quats`` wxyz of any non-zero norm."""
    q = np.asarray(quats, np.float64)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if not np.all(n > 0):
        raise ValueError(f"covariances: {int(np.sum(n <= 0))} zero quaternions")
    R = quat_to_matrix(q / n)
    s2 = np.asarray(scales, np.float64) ** 2
    return np.einsum("nij,nj,nkj->nik", R, s2, R)


def splats_of(g, min_scale: float = 1e-3, max_scale: float = 10.0, what: str = "Gaussians") -> Splats:
    """:class:`Splats` of activated :class:`~drawer_lib.splat.render.Gaussians` (only the
    degree-0 colour: the web renderer has no view dependence). Scales are clamped to
    ``[min_scale, max_scale]`` m (float16 covariances, see the module docstring); a non-finite
    value is an :class:`InputError` naming ``what``."""
    means, quats, scales = (t.detach().cpu().numpy().astype(np.float64) for t in (g.means, g.quats, g.scales))
    opac = g.opacities.detach().cpu().numpy().astype(np.float64)
    dc = g.sh[:, 0].detach().cpu().numpy().astype(np.float64)
    for name, a in (("means", means), ("quats", quats), ("scales", scales), ("opacities", opac), ("colours", dc)):
        bad = ~np.isfinite(a).reshape(len(a), -1).all(1) if len(a) else np.zeros(0, bool)
        if bad.any():
            raise InputError(f"{what}: {int(bad.sum())} Gaussians with non-finite {name} (first at index {int(np.argmax(bad))})")
    clamped = (scales < min_scale) | (scales > max_scale)
    cov = covariances(quats, np.clip(scales, min_scale, max_scale))
    return Splats(centers=means.astype(np.float32), covariances=cov.astype(np.float32),
                  rgbs=np.clip(0.5 + C0 * dc, 0.0, 1.0).astype(np.float32),
                  opacities=np.clip(opac, 0.0, 1.0)[:, None].astype(np.float32),
                  n_clamped=int(clamped.any(1).sum()))


def box_mesh(half: Float[np.ndarray, "3"]) -> tuple[np.ndarray, np.ndarray]:
    """(vertices [8, 3], faces [12, 3]) of a box of half-extents ``half`` centred at the origin,
    faces outward (counter-clockwise seen from outside)."""
    m = trimesh.creation.box(extents=2 * np.asarray(half, float))
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def geom_hull(m: mujoco.MjModel, d: mujoco.MjData, g: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices [V, 3] world, faces [F, 3]) of collision geom ``g`` at ``d``'s pose, as MuJoCo
    collides it (a mesh as its convex hull); None for a type the viewer does not draw (planes)."""
    t = m.geom_type[g]
    size = m.geom_size[g]
    if t == mujoco.mjtGeom.mjGEOM_BOX:
        v, f = box_mesh(size)
    elif t == mujoco.mjtGeom.mjGEOM_MESH:
        mid = m.geom_dataid[g]
        a, n = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
        # mesh vertices are stored in the mesh's own frame, which the compiled geom pose includes
        hull = trimesh.convex.convex_hull(np.asarray(m.mesh_vert[a:a + n], float))
        v, f = np.asarray(hull.vertices, float), np.asarray(hull.faces, np.int64)
    elif t == mujoco.mjtGeom.mjGEOM_SPHERE:
        s = trimesh.creation.icosphere(subdivisions=2, radius=float(size[0]))
        v, f = np.asarray(s.vertices, float), np.asarray(s.faces, np.int64)
    elif t == mujoco.mjtGeom.mjGEOM_CAPSULE:
        s = trimesh.creation.capsule(height=2 * float(size[1]), radius=float(size[0]))
        v, f = np.asarray(s.vertices, float), np.asarray(s.faces, np.int64)
    elif t == mujoco.mjtGeom.mjGEOM_CYLINDER:
        s = trimesh.creation.cylinder(radius=float(size[0]), height=2 * float(size[1]))
        v, f = np.asarray(s.vertices, float), np.asarray(s.faces, np.int64)
    else:
        return None
    R = d.geom_xmat[g].reshape(3, 3)
    return v @ R.T + d.geom_xpos[g], f


def body_hulls(m: mujoco.MjModel, d: mujoco.MjData, body: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """World-frame hulls of the collision geoms (``contype | conaffinity`` non-zero) of ``body``."""
    out = []
    for g in np.flatnonzero(m.geom_bodyid == body):
        if m.geom_contype[g] or m.geom_conaffinity[g]:
            h = geom_hull(m, d, int(g))
            if h is not None:
                out.append(h)
    return out


def relative_poses(xpos: Float[np.ndarray, "B 3"], xquat: Float[np.ndarray, "B 4"], rest_xpos: Float[np.ndarray, "B 3"],
                   rest_xquat: Float[np.ndarray, "B 4"]) -> tuple[np.ndarray, np.ndarray]:
    """(position [B, 3], wxyz [B, 4]) of ``X(t) X(0)^-1`` per body: the rigid motion that takes
    a point given at rest (world frame) to where the body has carried it,
    ``p -> R(t) R(0)^T (p - x(0)) + x(t)``."""
    R = quat_to_matrix(xquat) @ np.swapaxes(quat_to_matrix(rest_xquat), -1, -2)
    return xpos - np.einsum("bij,bj->bi", R, rest_xpos), matrix_to_quat(R)


def _twin_json(folder: Path) -> dict:
    path = folder / stage_name("twin", "index")
    if not path.is_file():
        hint = " (a twin folder is what the twin stage writes: out/<scene>/twin)"
        raise InputError(f"{path}: missing{hint}" if folder.is_dir() else f"{folder}: no such folder{hint}")
    try:
        tj = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not JSON ({e})") from e
    if tj.get("schema") != TWIN_SCHEMA:
        raise InputError(f"{path}: schema {tj.get('schema')!r}, expected {TWIN_SCHEMA!r}")
    return tj


def _splats(folder: Path, rel: str | None, what: str, min_scale: float) -> Splats | None:
    if not rel:
        return None
    path = folder / rel
    if not path.is_file():
        raise InputError(f"{path}: missing (listed for {what} in {folder / stage_name('twin', 'index')})")
    return splats_of(read_gaussian_ply(path), min_scale=min_scale, what=str(path))


def load_twin_scene(folder: Path | str, min_scale: float = 1e-3) -> TwinScene:
    """Read a twin folder (``twin.json``, ``scene.xml``, ``gaussians/``). A missing or broken file,
    or a part of ``twin.json`` that ``scene.xml`` lacks, is an :class:`InputError` naming it."""
    folder = Path(folder)
    tj = _twin_json(folder)
    xml = folder / stage_name("twin", "mjcf")
    if not xml.is_file():
        raise InputError(f"{xml}: missing (the simulator model {stage_name('twin', 'index')} refers to)")
    try:
        m = mujoco.MjModel.from_xml_path(str(xml))
    except ValueError as e:
        raise InputError(f"{xml}: MuJoCo cannot load it ({e})") from e
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)

    def mj_body(name: str) -> int:
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        if b < 0:
            raise InputError(f"{xml}: no body named {name!r} (listed in {folder / stage_name('twin', 'index')})")
        return b

    st = tj.get("static") or {}
    sb = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, st.get("body", STATIC))
    static = ViewBody(STATIC, STATIC, _splats(folder, st.get("gaussians"), "the static scene", min_scale),
                      body_hulls(m, d, sb if sb >= 0 else 0), None, sb if sb >= 0 else 0)
    bodies = []
    for p in tj.get("parts", []):
        pid, kind = p.get("id"), p.get("kind")
        if not pid or kind not in (*ARTICULATED, "rigid"):
            raise InputError(f"{folder / stage_name('twin', 'index')}: part {pid!r} has kind {kind!r} (expected revolute, prismatic or rigid)")
        b = mj_body(p.get("body") or pid)
        joint = None
        if kind in ARTICULATED:
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, p.get("joint") or pid)
            want = mujoco.mjtJoint.mjJNT_HINGE if kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE
            if j < 0 or m.jnt_type[j] != want:
                raise InputError(f"{xml}: part {pid!r} ({kind}) has no {'hinge' if kind == 'revolute' else 'slide'} "
                                 f"joint named {p.get('joint') or pid!r}")
            lo, hi = (float(x) for x in m.jnt_range[j])
            joint = Joint(kind, d.xanchor[j].copy(), d.xaxis[j].copy(), (lo, hi))
        conf = p.get("confidence")
        bodies.append(ViewBody(pid, kind, _splats(folder, p.get("gaussians"), f"part {pid!r}", min_scale),
                               body_hulls(m, d, b), joint, b, None if conf is None else float(conf),
                               bool(p.get("low_margin", False))))
    return TwinScene(folder, xml, m, static, bodies, d.xpos.copy(), d.xquat.copy())

