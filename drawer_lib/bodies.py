"""The body model: the twin's physical description in memory, what the ``complete`` stage builds
and the ``twin`` exports (MJCF, URDF, USD) are made from. A leaf: shapes, mass properties and the
bodies, with nothing of the stages that make or export them.

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

from drawer_lib.errors import InputError
from drawer_lib.geometry.boxes import OrientedBox

SHAPE_KINDS = ("box", "mesh")
JOINT_KINDS = ("revolute", "prismatic")
RESERVED_IDS = ("world", "static")  # names the exports give the world and the static scene
MIN_VOLUME = 1e-12  # m^3: a collision solid below this is degenerate (MuJoCo rejects ~1e-15)
_ROT_TOL = 1e-6


# ----------------------------------------------------------------------------------- shapes


@dataclass(frozen=True, eq=False)
class Shape:
    """One collision or visual piece, in world coordinates at q = 0.

    ``kind="box"``: ``box`` an :class:`~drawer_lib.geometry.boxes.OrientedBox` (the box's
    centre, rotation and half extents; :func:`box_shape` builds one).
    ``kind="mesh"``: ``vertices`` [V, 3] float (m), ``faces`` [F, 3] int (vertex indices).
    A collision mesh must be convex (MuJoCo collides a mesh as its convex hull; the exports
    write the hull); use :func:`convex_pieces` for a concave one.
    Arrays are stored as read-only float64 / int64 copies. Values are checked by
    :meth:`TwinModel.validate` (which names the body), shapes here.
    """

    kind: str
    box: OrientedBox | None = None
    vertices: Float[np.ndarray, "V 3"] | None = None
    faces: Int[np.ndarray, "F 3"] | None = None

    def __post_init__(self):
        if self.kind == "box":
            if not isinstance(self.box, OrientedBox):
                raise ValueError("Shape(kind='box') needs box: an OrientedBox")
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
            return f"Shape({self.box!r})"
        return f"Shape(mesh, {len(self.vertices)} vertices, {len(self.faces)} faces)"

    def shifted(self, offset: Float[np.ndarray, "3"]) -> "Shape":
        """The same shape translated by ``offset`` [3] (m): world -> a body frame at -offset."""
        if self.kind == "box":
            b = self.box
            return Shape("box", box=OrientedBox(b.center + offset, b.rotation, b.half))
        return Shape("mesh", vertices=self.vertices + offset, faces=self.faces)

    def triangles(self) -> tuple[Float[np.ndarray, "V 3"], Int[np.ndarray, "F 3"]]:
        """The surface as a triangle mesh: (vertices [V, 3], faces [F, 3], outward for a box)."""
        if self.kind == "mesh":
            return self.vertices, self.faces
        return self.box.triangles()

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
            h, R = self.box.half, self.box.rotation
            vol = 8.0 * float(np.prod(h))
            local = np.diag([h[1] ** 2 + h[2] ** 2, h[0] ** 2 + h[2] ** 2, h[0] ** 2 + h[1] ** 2]) * vol / 3.0
            return vol, self.box.center.copy(), R @ local @ R.T
        props = self._hull.mass_properties  # exact polyhedral integrals, density 1
        return float(props["volume"]), np.asarray(props["center_mass"], np.float64), np.asarray(props["inertia"], np.float64)


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
    R = np.eye(3) if rotation is None else np.asarray(rotation, np.float64)
    return Shape("box", box=OrientedBox(np.asarray(center, np.float64), R, np.asarray(half, np.float64)))


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
                a = getattr(s.box, name)
                if not np.isfinite(a).all():
                    raise InputError(f"{what} {k}: box {name} {a.tolist()} is not finite")
            if not (s.box.half > 0).all():
                raise InputError(f"{what} {k}: box half extents {s.box.half.tolist()} must be > 0")
            R = s.box.rotation
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
