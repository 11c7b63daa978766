"""The twin's physical description in memory (what the ``twin`` exports are built from) and the
simulation config.

Conventions (docs/formats.md): one world frame, the capture's: metres, +z up, gravity along -z.
A part's joint value ``q`` is in radians (revolute) or metres (prismatic); ``q = 0`` is the
closed pose the geometry is given in and positive ``q`` opens the part (right-hand rule about
``axis_direction`` for revolute, displacement along it for prismatic). Densities are kg/m^3,
masses kg, inertias kg·m^2. Every shape is given in world coordinates at ``q = 0``.

Masses and inertias are computed here, from the collision solids and the body's density
(:func:`mass_properties`): a box analytically, a mesh as its convex hull (the solid MuJoCo
collides with) with trimesh's exact polyhedral mass properties. MuJoCo, the URDF and the USD
all receive these same numbers (explicit inertials), never a simulator's default. Overlapping
collision pieces count their overlap twice (convex decompositions overlap little).
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import trimesh
from jaxtyping import Float, Int

from drawer_lib.errors import ConfigError, InputError

SHAPE_KINDS = ("box", "mesh")
JOINT_KINDS = ("revolute", "prismatic")
RESERVED_IDS = ("world", "static")  # names the exports give the world and the static scene
MIN_VOLUME = 1e-12  # m^3: a collision solid below this is degenerate (MuJoCo rejects ~1e-15)
_ROT_TOL = 1e-6


# ----------------------------------------------------------------------------------- shapes


@dataclass(frozen=True, eq=False)
class Shape:
    """One collision or visual piece, in world coordinates at q = 0.

    ``kind="box"``: ``center`` [3] (m), ``rotation`` [3, 3] (columns = the box axes in the world,
    a proper rotation), ``half`` [3] half extents along those axes (m).
    ``kind="mesh"``: ``vertices`` [V, 3] float (m), ``faces`` [F, 3] int (vertex indices).
    A collision mesh must be convex (MuJoCo collides a mesh as its convex hull; the exports
    write the hull); use :func:`convex_pieces` for a concave one.
    Arrays are stored as read-only float64 / int64 copies. Values are checked by
    :meth:`TwinModel.validate` (which names the body), shapes here.
    """

    kind: str
    center: Float[np.ndarray, "3"] | None = None
    rotation: Float[np.ndarray, "3 3"] | None = None
    half: Float[np.ndarray, "3"] | None = None
    vertices: Float[np.ndarray, "V 3"] | None = None
    faces: Int[np.ndarray, "F 3"] | None = None

    def __post_init__(self):
        if self.kind == "box":
            if self.center is None or self.half is None:
                raise ValueError("Shape(kind='box') needs center [3] and half [3]")
            rot = np.eye(3) if self.rotation is None else self.rotation
            for name, val in (("center", self.center), ("rotation", rot), ("half", self.half)):
                a = np.array(val, dtype=np.float64)
                a.setflags(write=False)
                object.__setattr__(self, name, a)
        elif self.kind == "mesh":
            if self.vertices is None or self.faces is None:
                raise ValueError("Shape(kind='mesh') needs vertices [V, 3] and faces [F, 3]")
            v = np.array(self.vertices, dtype=np.float64)
            f = np.array(self.faces, dtype=np.int64)
            v.setflags(write=False)
            f.setflags(write=False)
            object.__setattr__(self, "vertices", v)
            object.__setattr__(self, "faces", f)
        else:
            raise ValueError(f"Shape.kind = {self.kind!r} must be one of {SHAPE_KINDS}")

    def __repr__(self) -> str:
        if self.kind == "box":
            return f"Shape(box, center={np.round(self.center, 4).tolist()}, half={np.round(self.half, 4).tolist()})"
        return f"Shape(mesh, {len(self.vertices)} vertices, {len(self.faces)} faces)"

    def shifted(self, offset: Float[np.ndarray, "3"]) -> "Shape":
        """The same shape translated by ``offset`` [3] (m): world -> a body frame at -offset."""
        if self.kind == "box":
            return Shape("box", center=self.center + offset, rotation=self.rotation, half=self.half)
        return Shape("mesh", vertices=self.vertices + offset, faces=self.faces)

    def triangles(self) -> tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]]:
        """The surface as a triangle mesh: (vertices [V, 3], faces [F, 3], outward for a box)."""
        if self.kind == "mesh":
            return self.vertices, self.faces
        return _BOX_VERTS * self.half @ self.rotation.T + self.center, _BOX_FACES

    def solid(self) -> tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]]:
        """The collision solid: a box's 12 triangles, a mesh's convex hull (vertices [V, 3],
        outward faces [F, 3]). Raises ``ValueError`` for a flat or empty mesh."""
        if self.kind == "box":
            return self.triangles()
        return np.asarray(self._hull.vertices, np.float64), np.asarray(self._hull.faces, np.int64)

    @cached_property
    def _hull(self) -> trimesh.Trimesh:
        """The convex hull of a mesh's vertices (computed once; ``ValueError`` if flat)."""
        return _hull(self.vertices)

    def unit_mass_properties(self) -> tuple[float, Float[np.ndarray, "3"], Float[np.ndarray, "3 3"]]:
        """(volume m^3, centroid [3], inertia [3, 3] about the centroid in world axes per unit
        density, m^5) of the collision solid."""
        if self.kind == "box":
            h = self.half
            vol = 8.0 * float(np.prod(h))
            local = np.diag([h[1] ** 2 + h[2] ** 2, h[0] ** 2 + h[2] ** 2, h[0] ** 2 + h[1] ** 2]) * vol / 3.0
            return vol, self.center.copy(), self.rotation @ local @ self.rotation.T
        props = self._hull.mass_properties  # exact polyhedral integrals, density 1
        return float(props["volume"]), np.asarray(props["center_mass"], np.float64), np.asarray(props["inertia"], np.float64)


# unit box [-1, 1]^3: corners (bit 0 -> x, bit 1 -> y, bit 2 -> z) and 12 outward triangles
_BOX_VERTS = np.array([[(i & 1) * 2 - 1, (i >> 1 & 1) * 2 - 1, (i >> 2 & 1) * 2 - 1] for i in range(8)], np.float64)
_BOX_FACES = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                       [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], np.int64)


def _hull(vertices: np.ndarray) -> trimesh.Trimesh:
    """Convex hull of ``vertices`` [V, 3]; ``ValueError`` when it spans no volume."""
    if len(vertices) < 4:
        raise ValueError(f"{len(vertices)} vertices span no volume")
    try:
        with np.errstate(invalid="ignore", divide="ignore"):  # trimesh divides by a flat hull's volume 0
            hull = trimesh.convex.convex_hull(np.asarray(vertices, np.float64), qhull_options="QbB Pp Qt")
    except Exception as e:  # qhull: flat or duplicate input
        raise ValueError(f"no convex hull ({type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''})") from None
    tri = np.asarray(hull.vertices)[np.asarray(hull.faces)]  # [F, 3, 3]
    volume = float(np.einsum("fi,fi->f", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6.0
    if not abs(volume) >= MIN_VOLUME:
        raise ValueError(f"hull volume {abs(volume):.3g} m^3")
    return hull


def box_shape(center: Sequence[float] | np.ndarray, half: Sequence[float] | np.ndarray,
              rotation: Sequence[Sequence[float]] | np.ndarray | None = None) -> Shape:
    """A box of half extents ``half`` [3] (m) centred at ``center`` [3] (m), axes the columns of
    ``rotation`` [3, 3] (identity: axis-aligned)."""
    return Shape("box", center=np.asarray(center, np.float64), half=np.asarray(half, np.float64),
                 rotation=np.eye(3) if rotation is None else np.asarray(rotation, np.float64))


def mesh_shape(vertices: Sequence[Sequence[float]] | np.ndarray, faces: Sequence[Sequence[int]] | np.ndarray) -> Shape:
    """A triangle mesh: ``vertices`` [V, 3] (m), ``faces`` [F, 3] vertex indices."""
    return Shape("mesh", vertices=np.asarray(vertices, np.float64), faces=np.asarray(faces, np.int64))


def convex_pieces(mesh_vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"], max_hulls: int = 16,
                  resolution: int = 100_000, max_vertices_per_hull: int = 64, max_recursion_depth: int = 10,
                  min_volume: float = MIN_VOLUME) -> list[Shape]:
    """Approximate convex decomposition (V-HACD via ``trimesh.decomposition.convex_decomposition``
    and vhacdx) of a closed mesh into at most ``max_hulls`` convex collision Shapes.

    Args: ``mesh_vertices`` [V, 3] (m), ``faces`` [F, 3]; ``resolution`` voxels of V-HACD's
    volume grid; ``max_vertices_per_hull``; ``max_recursion_depth`` of its splits (smaller is
    faster and coarser). Pieces below ``min_volume`` (m^3) are dropped.
    Returns: a list of ``Shape(kind="mesh")``, each the convex hull of one piece, world frame.
    Raises ``ValueError`` for an empty mesh or when nothing of volume remains.
    """
    v = np.asarray(mesh_vertices, np.float64)
    f = np.asarray(faces, np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4 or f.ndim != 2 or f.shape[1] != 3 or len(f) < 4:
        raise ValueError(f"convex_pieces: need vertices [V>=4, 3] and faces [F>=4, 3], got {v.shape}, {f.shape}")
    if max_hulls < 1:
        raise ValueError(f"convex_pieces: max_hulls = {max_hulls} must be >= 1")
    from trimesh.decomposition import convex_decomposition

    mesh = trimesh.Trimesh(vertices=v, faces=f, process=False)
    pieces = convex_decomposition(mesh, maxConvexHulls=int(max_hulls), resolution=int(resolution),
                                  maxNumVerticesPerCH=int(max_vertices_per_hull),
                                  maxRecursionDepth=int(max_recursion_depth), asyncACD=False)
    out = []
    for p in pieces:
        try:
            hull = _hull(np.asarray(p["vertices"], np.float64))
        except ValueError:
            continue
        if hull.volume >= min_volume:
            out.append(mesh_shape(hull.vertices, hull.faces))
    if not out:
        raise ValueError("convex_pieces: the decomposition left no piece with volume")
    return out


# ------------------------------------------------------------------------------ mass properties


@dataclass(frozen=True)
class MassProps:
    """Rigid-body mass properties in world axes: ``mass`` (kg), ``com`` [3] (m),
    ``inertia`` [3, 3] about the com (kg·m^2), its eigen-decomposition ``principal`` [3]
    (kg·m^2, ascending) and ``axes`` [3, 3] (columns = principal axes, a proper rotation)."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray
    principal: np.ndarray
    axes: np.ndarray
    volume: float


def mass_properties(shapes: Sequence[Shape], density: float) -> MassProps:
    """Mass properties of the union of collision ``shapes`` (each a convex solid) at ``density``
    (kg/m^3), by the parallel-axis theorem over the pieces (their overlaps count twice)."""
    if not shapes:
        raise ValueError("mass_properties: no shapes")
    props = [s.unit_mass_properties() for s in shapes]
    vol = np.array([p[0] for p in props])  # [P]
    cen = np.stack([p[1] for p in props])  # [P, 3]
    ine = np.stack([p[2] for p in props])  # [P, 3, 3]
    total = float(vol.sum())
    com = (vol[:, None] * cen).sum(0) / total
    d = cen - com  # [P, 3]
    shift = (d * d).sum(1)[:, None, None] * np.eye(3) - d[:, :, None] * d[:, None, :]
    inertia = density * (ine + vol[:, None, None] * shift).sum(0)
    inertia = 0.5 * (inertia + inertia.T)
    principal, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    return MassProps(mass=density * total, com=com, inertia=inertia, principal=principal, axes=axes, volume=total)


def axis_inertia(props: MassProps, kind: str, origin: np.ndarray, direction: np.ndarray) -> float:
    """The inertia a joint drives: about the axis line (kg·m^2) for revolute, the mass (kg) for
    prismatic."""
    if kind == "prismatic":
        return props.mass
    n = direction / np.linalg.norm(direction)
    r = props.com - origin
    r_perp = r - (r @ n) * n
    return float(n @ props.inertia @ n + props.mass * (r_perp @ r_perp))


# ---------------------------------------------------------------------------------- the twin


@dataclass(frozen=True, eq=False)
class PartBody:
    """An articulated part: ``id`` (from parts.json), ``kind`` revolute | prismatic, the joint
    line through ``axis_origin`` [3] (m) along ``axis_direction`` [3] (non-zero; normalised on
    export; positive q opens), ``limits`` (lo, hi) in rad or m with lo <= 0 < hi (q = 0 is the
    closed pose of the geometry), ``visual`` meshes, convex ``collision`` pieces (at least one)
    and the ``density`` (kg/m^3) of the collision solids."""

    id: str
    kind: str
    axis_origin: Float[np.ndarray, "3"]
    axis_direction: Float[np.ndarray, "3"]
    limits: tuple[float, float]
    visual: list[Shape]
    collision: list[Shape]
    density: float

    def __post_init__(self):
        for name in ("axis_origin", "axis_direction"):
            a = np.array(getattr(self, name), np.float64)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "limits", (float(self.limits[0]), float(self.limits[1])))

    @property
    def unit_axis(self) -> np.ndarray:
        """``axis_direction`` normalised [3]."""
        return self.axis_direction / np.linalg.norm(self.axis_direction)

    def mass_properties(self) -> MassProps:
        return mass_properties(self.collision, self.density)


@dataclass(frozen=True, eq=False)
class RigidBody:
    """A free object: ``id``, ``visual`` meshes, convex ``collision`` pieces (at least one),
    ``density`` (kg/m^3); its pose is that of its geometry (world frame)."""

    id: str
    visual: list[Shape]
    collision: list[Shape]
    density: float

    def mass_properties(self) -> MassProps:
        return mass_properties(self.collision, self.density)


@dataclass(frozen=True, eq=False)
class TwinModel:
    """The whole twin at q = 0: the fixed scene (``static_visual`` meshes, convex
    ``static_collision`` pieces), articulated ``parts`` and free ``rigid`` objects."""

    static_visual: list[Shape] = field(default_factory=list)
    static_collision: list[Shape] = field(default_factory=list)
    parts: list[PartBody] = field(default_factory=list)
    rigid: list[RigidBody] = field(default_factory=list)

    def bodies(self) -> list[PartBody | RigidBody]:
        return [*self.parts, *self.rigid]

    def validate(self) -> "TwinModel":
        """Raise :class:`InputError` naming the part (or static piece) for: a bad or duplicate
        id, an unknown kind, a zero or non-finite axis, NaN anywhere, limits with hi <= lo, hi <=
        0, lo > 0 or non-finite, a body without collision geometry, a density <= 0, a box with
        half extents <= 0 or a non-rotation, a mesh with out-of-range faces, and a degenerate
        (zero-volume) collision mesh. Returns ``self``."""
        seen: set[str] = set()
        for b in self.bodies():
            what = f"part {b.id!r}" if isinstance(b, PartBody) else f"rigid object {b.id!r}"
            if not isinstance(b.id, str) or not b.id.isidentifier() or not b.id.isascii():
                raise InputError(f"{what}: the id must be an ASCII identifier ([A-Za-z_][A-Za-z0-9_]*), "
                                 "a valid MJCF, URDF and USD prim name")
            if b.id in RESERVED_IDS:
                raise InputError(f"{what}: the id is reserved for the exports ({', '.join(RESERVED_IDS)})")
            if b.id in seen:
                raise InputError(f"{what}: duplicate id")
            seen.add(b.id)
            if isinstance(b, PartBody):
                _check_joint(b, what)
            if not (isinstance(b.density, (int, float)) and math.isfinite(b.density) and b.density > 0):
                raise InputError(f"{what}: density {b.density!r} kg/m^3 must be finite and > 0")
            if not b.collision:
                raise InputError(f"{what}: no collision geometry (a moving body needs a solid)")
            _check_shapes(b.collision, f"{what}: collision piece", collision=True)
            _check_shapes(b.visual, f"{what}: visual piece", collision=False)
        _check_shapes(self.static_collision, "static scene: collision piece", collision=True)
        _check_shapes(self.static_visual, "static scene: visual piece", collision=False)
        return self


def _check_joint(p: PartBody, what: str) -> None:
    if p.kind not in JOINT_KINDS:
        raise InputError(f"{what}: kind {p.kind!r} must be one of {JOINT_KINDS}")
    if not np.isfinite(p.axis_origin).all():
        raise InputError(f"{what}: axis origin {p.axis_origin.tolist()} is not finite")
    n = float(np.linalg.norm(p.axis_direction)) if np.isfinite(p.axis_direction).all() else math.nan
    if not (math.isfinite(n) and n > 1e-9):
        raise InputError(f"{what}: axis direction {p.axis_direction.tolist()} is zero or not finite")
    lo, hi = p.limits
    unit = "rad" if p.kind == "revolute" else "m"
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InputError(f"{what}: limits [{lo}, {hi}] {unit} are not finite")
    if not lo < hi:
        raise InputError(f"{what}: limits [{lo}, {hi}] {unit} are an empty range (need lo < hi)")
    if not (lo <= 0.0 < hi):
        raise InputError(f"{what}: limits [{lo}, {hi}] {unit} must contain the closed pose q = 0 "
                         "and open to hi > 0")
    if p.kind == "revolute" and (hi - lo) > 2 * math.pi:
        raise InputError(f"{what}: limits [{lo}, {hi}] rad span more than a full turn")


def _check_shapes(shapes: Sequence[Shape], what: str, collision: bool) -> None:
    for k, s in enumerate(shapes):
        if not isinstance(s, Shape):
            raise InputError(f"{what} {k} is a {type(s).__name__}, not a Shape")
        if s.kind == "box":
            for name in ("center", "rotation", "half"):
                a = getattr(s, name)
                if not np.isfinite(a).all():
                    raise InputError(f"{what} {k}: box {name} {a.tolist()} is not finite")
            if not (s.half > 0).all():
                raise InputError(f"{what} {k}: box half extents {s.half.tolist()} must be > 0")
            R = s.rotation
            if np.abs(R.T @ R - np.eye(3)).max() > _ROT_TOL or np.linalg.det(R) < 0:
                raise InputError(f"{what} {k}: box rotation is not a proper rotation matrix")
            continue
        v, f = s.vertices, s.faces
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise InputError(f"{what} {k}: mesh needs vertices [V, 3] and faces [F>0, 3], got {v.shape}, {f.shape}")
        if not np.isfinite(v).all():
            raise InputError(f"{what} {k}: mesh has {int((~np.isfinite(v)).any(1).sum())} non-finite vertices")
        if f.min() < 0 or f.max() >= len(v):
            raise InputError(f"{what} {k}: mesh faces index outside [0, {len(v)})")
        if collision:
            try:
                vol = s.unit_mass_properties()[0]
            except ValueError as e:
                raise InputError(f"{what} {k}: degenerate collision mesh, {e}") from None
            if not vol >= MIN_VOLUME:
                raise InputError(f"{what} {k}: degenerate collision mesh (hull volume {vol:.3g} m^3)")
        else:
            e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
            if not np.linalg.norm(np.cross(e1, e2), axis=1).sum() > 0:
                raise InputError(f"{what} {k}: visual mesh has zero area")


# ---------------------------------------------------------------------------------- config


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ConfigError(msg)


@dataclass(frozen=True)
class JointConfig:
    """Joint and drive of one joint kind (SI units; "force" is N·m for revolute, N for
    prismatic; speeds rad/s or m/s).

    ``damping`` (force per unit speed), ``armature`` (reflected inertia, kg·m^2 or kg),
    ``frictionloss`` (dry friction force), ``speed`` (the drive's target speed and control
    limit). The drive is MuJoCo's velocity servo, force = kv (target - speed), with
    ``kv = (inertia about the joint + armature) / drive_tau``: every part, whatever its mass,
    reaches the target speed with the same time constant ``drive_tau`` (s) and the same
    acceleration, and the servo is never stiffer than the implicit integrator resolves
    (drive_tau >> timestep); the passive damping and friction slow it by
    (damping + frictionloss / speed) / (kv + damping) (~5 % for a 5 kg drawer or a 0.35 kg·m^2
    door). ``effort``: the drive's force limit (MJCF ``forcerange``, URDF ``<limit effort>``)."""

    damping: float
    armature: float
    frictionloss: float
    speed: float
    drive_tau: float = 0.02
    effort: float = 50.0

    def __post_init__(self):
        for k in ("damping", "armature", "frictionloss"):
            v = getattr(self, k)
            _check(math.isfinite(v) and v >= 0, f"joint.{k} = {v} must be finite and >= 0")
        _check(math.isfinite(self.speed) and self.speed > 0, f"joint.speed = {self.speed} must be > 0")
        _check(math.isfinite(self.drive_tau) and self.drive_tau > 0, f"joint.drive_tau = {self.drive_tau} must be > 0")
        _check(math.isfinite(self.effort) and self.effort > 0, f"joint.effort = {self.effort} must be > 0")


# Hinges: a cabinet hinge is lightly damped; 1 N·m·s/rad lets a 10 N·m pull swing a 0.5 m
# door open in well under a second (terminal speed 10 rad/s) yet stops a released door within
# a fraction of a turn; dry friction 0.05 N·m holds a door at rest against small disturbances
# (a real hinge has ~0.02-0.2 N·m). Drawer slides: ball-bearing runners roll with ~1 N dry
# friction (μ ~ 0.02-0.05 of a loaded drawer's weight) and ~10 N·s/m of viscous loss (a 20 N pull
# gives 2 m/s terminal speed, and a drawer pushed at 0.5 m/s coasts ~ m/c = 0.3 s).
# DRAWER's Isaac drives use damping 1e10 as an ideal velocity source; here the ideal velocity
# source is the servo (drive_tau) and the joint keeps realistic passive damping, so a person's
# pull (checks) and a robot see a plausible cabinet. Armature (a small reflected inertia) keeps
# light parts well conditioned; the revolute speed is DRAWER's 50 deg/s, prismatic 0.5 m/s.
def _revolute_default() -> "JointConfig":
    return JointConfig(damping=1.0, armature=0.005, frictionloss=0.05, speed=math.radians(50.0), drive_tau=0.02,
                       effort=20.0)


def _prismatic_default() -> "JointConfig":
    return JointConfig(damping=10.0, armature=0.05, frictionloss=1.0, speed=0.5, drive_tau=0.02, effort=150.0)


@dataclass(frozen=True)
class DensityConfig:
    """Densities (kg/m^3) a stage gives the bodies it builds: ``part`` wood / MDF fronts and
    carcass interiors (MDF ~600-800, chipboard ~650), ``rigid`` household objects as solids
    (a filled cup's hull; ceramics ~2300 but hollow)."""

    part: float = 600.0
    rigid: float = 800.0

    def __post_init__(self):
        _check(self.part > 0 and self.rigid > 0, "densities: part and rigid must be > 0")


@dataclass(frozen=True)
class ContactConfig:
    """Contacts. ``part_static``: parts collide with the static scene (default off: a joint's
    limits are its stops, and reconstructed carcass hulls that overlap a drawer slightly would
    otherwise jam it; the checks measure part-vs-static penetration geometrically either way).
    ``part_part``: parts collide with each other. Rigid objects always collide with the static
    scene, parts and each other. ``friction`` sliding coefficient (wood on wood, ceramic on
    wood ~0.3-0.6), torsional and rolling as MuJoCo's defaults. ``limit_timeconst`` (s): the
    joint limits' constraint time constant (MuJoCo solref; >= 2 timesteps), short so a door
    slammed by a 10 N·m pull stops within 2° of its limit (MuJoCo's default 0.02 s lets it
    overshoot ~4°)."""

    part_static: bool = False
    part_part: bool = True
    friction: float = 0.6
    friction_torsion: float = 0.005
    friction_roll: float = 0.0001
    limit_timeconst: float = 0.004

    def __post_init__(self):
        _check(self.friction >= 0 and self.friction_torsion >= 0 and self.friction_roll >= 0,
               "contact: friction coefficients must be >= 0")
        _check(self.limit_timeconst > 0, "contact.limit_timeconst must be > 0")


@dataclass(frozen=True)
class CheckConfig:
    """Physical checks of a built twin (:func:`drawer_lib.sim.checks.check_twin`). Angles rad,
    lengths m, times s (simulated), forces N / N·m.

    Drive: with its velocity target at the drive speed every part reaches ``open_fraction`` of
    its upper limit within ``open_time`` (or 1.2 x range / speed when that is longer) and never
    passes the limit by more than ``drive_overshoot_rad`` / ``drive_overshoot_m``.
    Pull (actuators off): ``pull_force`` along a drawer's axis, ``pull_torque`` about a hinge
    open it to ``pull_fraction`` of its range within ``open_time``, overshoot <=
    ``pull_overshoot_rad`` / ``pull_overshoot_m``. Penetration: at q = 0 a part intersects the
    static scene or another part by <= ``penetration``; along its path (``path_samples`` poses in
    (0, hi]) the static scene by <= ``path_penetration``. Rest: rigid objects move <
    ``rest_drift`` in ``rest_time``."""

    open_fraction: float = 0.95
    open_time: float = 3.0
    drive_overshoot_rad: float = math.radians(1.0)
    drive_overshoot_m: float = 0.001
    pull_force: float = 20.0
    pull_torque: float = 10.0
    pull_fraction: float = 0.9
    pull_overshoot_rad: float = math.radians(2.0)
    pull_overshoot_m: float = 0.005
    penetration: float = 0.002
    path_penetration: float = 0.002
    path_samples: int = 8
    rest_time: float = 2.0
    rest_drift: float = 0.01

    def __post_init__(self):
        _check(0 < self.open_fraction <= 1 and 0 < self.pull_fraction <= 1, "checks: fractions must be in (0, 1]")
        _check(self.open_time > 0 and self.rest_time > 0, "checks: open_time and rest_time must be > 0")
        _check(self.path_samples >= 1, "checks.path_samples must be >= 1")
        for k in ("drive_overshoot_rad", "drive_overshoot_m", "pull_force", "pull_torque", "pull_overshoot_rad",
                  "pull_overshoot_m", "penetration", "path_penetration", "rest_drift"):
            _check(getattr(self, k) >= 0, f"checks.{k} must be >= 0")


@dataclass(frozen=True)
class SimConfig:
    """Simulation of the twin (MuJoCo option and the joints, drives, densities, contacts and
    checks). ``timestep`` (s), ``integrator`` one of MuJoCo's (implicitfast integrates the
    velocity servos and joint damping implicitly, stable for any gain), ``gravity`` (m/s^2, along
    -z). ``flap_gravcomp``: the fraction of a flap's weight (a part hinged about an axis more
    than 45° from vertical) its mechanism carries (MuJoCo body ``gravcomp``): up-opening flaps
    ride on gas struts or lift fittings and down-opening ones on balancing springs, so a hand
    moves them as it moves a door; 0 leaves the bare panel (a tall lift-up flap then needs more
    than the 10 N·m pull to open)."""

    timestep: float = 0.002
    integrator: str = "implicitfast"
    gravity: float = 9.81
    flap_gravcomp: float = 1.0
    revolute: JointConfig = field(default_factory=_revolute_default)
    prismatic: JointConfig = field(default_factory=_prismatic_default)
    densities: DensityConfig = field(default_factory=DensityConfig)
    contact: ContactConfig = field(default_factory=ContactConfig)
    checks: CheckConfig = field(default_factory=CheckConfig)

    def __post_init__(self):
        _check(0 < self.timestep <= 0.01, f"sim.timestep = {self.timestep} must be in (0, 0.01] s")
        _check(self.integrator in ("euler", "implicit", "implicitfast", "rk4"),
               f"sim.integrator = {self.integrator!r} must be euler, implicit, implicitfast or rk4")
        _check(math.isfinite(self.gravity) and self.gravity >= 0, "sim.gravity must be finite and >= 0")
        _check(0.0 <= self.flap_gravcomp <= 1.0, f"sim.flap_gravcomp = {self.flap_gravcomp} must be in [0, 1]")
        _check(self.contact.limit_timeconst >= 2 * self.timestep,
               f"sim.contact.limit_timeconst = {self.contact.limit_timeconst} must be >= 2 x timestep "
               f"({2 * self.timestep}) to stay stable")

    def joint(self, kind: str) -> JointConfig:
        return self.revolute if kind == "revolute" else self.prismatic
