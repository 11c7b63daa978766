"""Fitted interior templates behind articulated fronts (DRAWER §5, the amodal interior).

DRAWER gives every door a box 1.5 x its width deep and every drawer one 1.25 x its width deep
(``isaac_sim/compose_usd.py``, 2 cm walls), whatever the cabinet. Here the depth is *measured*
on the scene mesh and *fitted* jointly over the kitchen, and the template follows the part:

| part | template | body |
|---|---|---|
| prismatic along its outward normal | drawer: open-top box (bottom, front, back, sides) | the part |
| revolute, bottom hinge, lower edge near the floor | appliance: cavity, no shelves (oven) | static |
| other revolute (door, flap) | cabinet: back, sides, top, bottom + shelves | static |
| prismatic along the front's plane (sliding) | cabinet behind the other track (shallow) | static |

(near the floor: within ``appliance_max_bottom``; drawer: direction . normal >=
``drawer_normal_cos``; shelves: one per ``shelf_spacing`` of height.)

Frame: a part's template lives in its front's frame, origin at the centre of the front's outer
face, coordinates (a, b, z) along (u, v, -normal): z is the distance behind the outer face. A
template occupies z in [start, start + depth]: ``start`` = the front's thickness (plus the step
to a sliding partner's track in front of it), ``depth`` includes the back wall; its *free depth*
= start - front thickness + depth - wall = from the front's inner face to the back wall's inner
face. Shapes are world-frame boxes at q = 0 (all closed) with proper rotations [u, v, normal].

Evidence (:func:`measure_evidence`): the wall behind (the farthest well-supported surface facing
like the front within its u-range, as a plane), caps (a counter top, a wall cabinet's underside,
an end panel continuing the front's edges backwards: their extent), the other fronts' planes
(another track of the same cabinet, or a front behind that blocks), the floor (appliance rule);
:func:`drawer_lib.articulation.probes.carcass_depth` on the points level with the front is the
fallback measurement (unrestricted, it measures the wall cabinets' fronts from a base front).

Fit (:func:`fit_depths`): minimise sum_i w_i (d_i - m_i)^2 + rho x (inside the carcass, in
front of a blocking front, drawer box >= its travel, pairwise overlap volume of the occupied
boxes (a drawer's box swept over its travel) / the smaller front area)^2 over d in [min, max]
with L-BFGS-B (overlap gradients by central differences), the penalty raised in rounds. Parts
without evidence get the median fitted carcass depth of the fronts in their plane (their run),
else of the kitchen, else ``fit.default_depth`` behind the front.
"""

import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from jaxtyping import Float
from scipy.ndimage import gaussian_filter
from scipy.optimize import minimize
from scipy.spatial import ConvexHull, QhullError

from drawer_lib.complete.cut import front_frame as cut_front_frame
from drawer_lib.articulation.config import JointsConfig
from drawer_lib.articulation.probes import carcass_depth
from drawer_lib.complete.interiors_config import (
    EvidenceConfig,
    InteriorsConfig,
    TemplateConfig,
    TextureConfig,
)
from drawer_lib.errors import ConfigError, NonFiniteError
from drawer_lib.io.parts import Front, Part

try:  # the simulator's shape type (drawer_lib/bodies.py), when present
    from drawer_lib.bodies import Shape
except ImportError:  # pragma: no cover - written against the same contract

    @dataclass(frozen=True)
    class Shape:  # type: ignore[no-redef]
        """A collision / visual shape: kind "box" (center [3], rotation [3, 3] whose columns are
        the box axes, half [3] extents) or "mesh" (vertices [V, 3], faces [F, 3])."""

        kind: str
        center: np.ndarray | None = None
        rotation: np.ndarray | None = None
        half: np.ndarray | None = None
        vertices: np.ndarray | None = None
        faces: np.ndarray | None = None


TEMPLATES = ("drawer", "cabinet", "appliance")
DRAWER_DOOR_FACTOR = 1.5  # DRAWER compose_usd.py: D = 1.5 s_y for revolute parts
DRAWER_DRAWER_FACTOR = 1.25  # and 1.25 s_y for prismatic ones
DRAWER_WALL = 0.02  # their wall thickness (m)
_MIN_HALF = 5e-4  # no box is thinner than 1 mm


# ---------------------------------------------------------------------------------------------
# oriented boxes


@dataclass(frozen=True)
class OBox:
    """An oriented box: ``center`` [3], ``rotation`` [3, 3] (columns = the box axes, det +1),
    ``half`` [3] half extents along them."""

    center: np.ndarray
    rotation: np.ndarray
    half: np.ndarray

    @property
    def volume(self) -> float:
        return float(8.0 * np.prod(self.half))

    def corners(self) -> Float[np.ndarray, "8 3"]:
        s = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
        return self.center + (s * self.half) @ self.rotation.T

    def halfspaces(self) -> tuple[Float[np.ndarray, "6 3"], Float[np.ndarray, "6"]]:
        """(A, b) with the box = {x : A x <= b}."""
        A = np.concatenate([self.rotation.T, -self.rotation.T])
        c = self.rotation.T @ self.center
        return A, np.concatenate([c + self.half, -c + self.half])

    def contains(self, points: Float[np.ndarray, "N 3"], tol: float = 1e-9) -> np.ndarray:
        """[N] bool: points inside (or within ``tol`` of) the box."""
        loc = (points - self.center) @ self.rotation
        return np.all(np.abs(loc) <= self.half + tol, axis=1)

    def shape(self) -> Shape:
        return _box_shape(self.center, self.rotation, self.half)

    def to_json(self) -> dict:
        return {"center": self.center.tolist(), "rotation": self.rotation.tolist(), "half": self.half.tolist()}


def _box_shape(center: np.ndarray, rotation: np.ndarray, half: np.ndarray) -> Shape:
    return Shape(kind="box", center=np.asarray(center, np.float64), rotation=np.asarray(rotation, np.float64),
                 half=np.asarray(half, np.float64))


def _separated(a: OBox, b: OBox) -> bool:
    """Separating-axis test of two boxes (15 axes)."""
    axes = [a.rotation[:, k] for k in range(3)] + [b.rotation[:, k] for k in range(3)]
    axes += [np.cross(a.rotation[:, i], b.rotation[:, j]) for i in range(3) for j in range(3)]
    d = b.center - a.center
    for ax in axes:
        n = np.linalg.norm(ax)
        if n < 1e-9:
            continue
        ax = ax / n
        ra = np.sum(a.half * np.abs(a.rotation.T @ ax))
        rb = np.sum(b.half * np.abs(b.rotation.T @ ax))
        if abs(d @ ax) >= ra + rb:
            return True
    return False


_TRIPLES = np.array([(i, j, k) for i in range(12) for j in range(i + 1, 12) for k in range(j + 1, 12)])


def obox_overlap_volume(a: OBox, b: OBox) -> float:
    """Volume (m^3) of the intersection of two oriented boxes: the vertices of the intersection
    polytope (every feasible intersection point of three of the 12 face planes) and their convex
    hull. 0 for disjoint, touching or flat intersections.

    >>> I = np.eye(3)
    >>> round(obox_overlap_volume(OBox(np.zeros(3), I, np.ones(3)), OBox(np.array([1.0, 0, 0]), I, np.ones(3))), 6)
    4.0
    """
    if _separated(a, b):
        return 0.0
    Aa, ba = a.halfspaces()
    Ab, bb = b.halfspaces()
    A, bvec = np.concatenate([Aa, Ab]), np.concatenate([ba, bb])  # [12, 3], [12]
    M = A[_TRIPLES]  # [T, 3, 3]
    rhs = bvec[_TRIPLES]  # [T, 3]
    ok = np.abs(np.linalg.det(M)) > 1e-12
    if not ok.any():
        return 0.0
    X = np.linalg.solve(M[ok], rhs[ok][..., None])[..., 0]  # [T', 3]
    scale = 1e-9 * max(1.0, float(np.abs(bvec).max()))
    X = X[np.all(X @ A.T <= bvec + scale, axis=1)]
    if len(X) < 4:
        return 0.0
    X = np.unique(np.round(X, 12), axis=0)
    if len(X) < 4:
        return 0.0
    try:
        return float(ConvexHull(X).volume)
    except QhullError:  # flat: touching faces
        return 0.0


# ---------------------------------------------------------------------------------------------
# parts, frames, templates


def check_part(part: Part) -> None:
    """Raise :class:`NonFiniteError` naming the part when its front, axis or limits hold NaN or
    inf, and ValueError when it is not an articulated part with a front."""
    if not part.articulated or part.front is None:
        raise ValueError(f"part {part.id}: interiors need an articulated part with a front (kind {part.kind!r})")
    f = part.front
    for name, val in (("front.center", f.center), ("front.normal", f.normal), ("front.u", f.u),
                      ("front.size", f.size), ("axis.origin", part.axis.origin if part.axis else ()),
                      ("axis.direction", part.axis.direction if part.axis else ()), ("limits", part.limits or ())):
        a = np.asarray(val, np.float64)
        if not np.all(np.isfinite(a)):
            raise NonFiniteError(f"part {part.id}: {name} = {list(a)} is not finite")
    if min(f.size) <= 0:
        raise ValueError(f"part {part.id}: front.size = {list(f.size)} must be positive")


def front_frame(front: Front) -> tuple[np.ndarray, np.ndarray]:
    """(origin [3] = centre of the outer face, rotation [3, 3] = columns [u, v, normal], det +1)."""
    return np.asarray(front.center, np.float64), cut_front_frame(front)


def _local_box(origin: np.ndarray, R: np.ndarray, lo, hi) -> OBox:
    """The box [lo, hi] in front coordinates (a, b, z = depth behind the outer face)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    mid = (lo + hi) / 2
    half = np.maximum((hi - lo) / 2, _MIN_HALF)
    return OBox(origin + R @ np.array([mid[0], mid[1], -mid[2]]), R.copy(), half)


def template_kind(part: Part, floor_z: float | None, cfg: TemplateConfig) -> tuple[str, str]:
    """(template, reason): ``drawer`` | ``cabinet`` | ``appliance`` (table in the module doc)."""
    f = part.front
    n, u = np.asarray(f.normal), np.asarray(f.u)
    d = np.asarray(part.axis.direction)
    if part.kind == "prismatic":
        if d @ n >= cfg.drawer_normal_cos:
            return "drawer", "prismatic along the outward normal"
        return "cabinet", "sliding door: a shallow cabinet behind its track"
    horizontal = abs(d @ u) > 0.7
    below = (np.asarray(part.axis.origin) - np.asarray(f.center)) @ f.v < 0
    if horizontal and below:
        bottom_z = float(f.corners()[:, 2].min())
        if floor_z is not None and bottom_z - floor_z <= cfg.appliance_max_bottom:
            return "appliance", f"bottom-hinged, lower edge {bottom_z - floor_z:.2f} m above the floor: oven-like"
        return "cabinet", "bottom-hinged flap above the floor"
    return "cabinet", "hinged door or flap"


def travel(part: Part) -> float:
    """How far a drawer's front moves inward-outward at its upper limit (m); 0 for others."""
    if part.kind != "prismatic":
        return 0.0
    return float(max(part.limits[1], 0.0) * max(np.asarray(part.axis.direction) @ np.asarray(part.front.normal), 0.0))


@dataclass(frozen=True)
class Interior:
    """One part's interior. ``walls`` (world boxes at q = 0) with ``wall_names``; ``body``: the
    part's id (a drawer box moves with it) or "static"; ``free``: the empty inside; ``outer``:
    the template's whole extent (what to carve out of the static collision); ``occupied``: the
    outer box swept over the part's travel (drawer) — what neighbours must not enter."""

    part_id: str
    template: str
    body: str
    walls: list
    wall_names: list[str]
    free: OBox
    outer: OBox
    occupied: OBox
    start: float
    depth: float
    wall: float
    front_thickness: float
    shelves: int
    record: dict = field(default_factory=dict)

    @property
    def free_depth(self) -> float:
        """From the front's inner face to the back wall's inner face (m)."""
        return float(self.start - self.front_thickness + self.depth - self.wall)

    def to_json(self) -> dict:
        return {"part": self.part_id, "template": self.template, "body": self.body, "start": self.start,
                "depth": self.depth, "free_depth": self.free_depth, "wall": self.wall, "shelves": self.shelves,
                "walls": [{"name": nm, "center": s.center.tolist(), "rotation": s.rotation.tolist(),
                           "half": s.half.tolist()} for nm, s in zip(self.wall_names, self.walls)],
                "free": self.free.to_json(), "outer": self.outer.to_json(), **self.record}


Footprint = tuple[float, float, float, float]  # (a0, a1, b0, b1) in the front's (u, v) coordinates


def full_footprint(front: Front) -> Footprint:
    w, h = front.size
    return (-w / 2, w / 2, -h / 2, h / 2)


def _inset(lo: float, hi: float, a: float, b: float, frac: float) -> tuple[float, float]:
    ext = hi - lo
    return lo + min(a, frac * ext), hi - min(b, frac * ext)


def template_footprint(template: str, fp: Footprint, cfg: TemplateConfig) -> Footprint:
    """The template's outer extent in the front's (u, v): a drawer box inset in the opening,
    a cavity inset by ``cavity_inset``."""
    a0, a1, b0, b1 = fp
    if template == "drawer":
        a0, a1 = _inset(a0, a1, cfg.drawer_side, cfg.drawer_side, cfg.max_inset_frac)
        b0, b1 = _inset(b0, b1, cfg.drawer_bottom, cfg.drawer_top, cfg.max_inset_frac)
    else:
        a0, a1 = _inset(a0, a1, cfg.cavity_inset, cfg.cavity_inset, cfg.max_inset_frac)
        b0, b1 = _inset(b0, b1, cfg.cavity_inset, cfg.cavity_inset, cfg.max_inset_frac)
    return a0, a1, b0, b1


def occupied_box(part: Part, template: str, start: float, depth: float, fp: Footprint, cfg: TemplateConfig) -> OBox:
    """The space a template takes: its outer box, for a drawer swept over its travel."""
    o, R = front_frame(part.front)
    a0, a1, b0, b1 = template_footprint(template, fp, cfg)
    tr = travel(part) if template == "drawer" else 0.0
    return _local_box(o, R, (a0, b0, start - tr), (a1, b1, start + depth))


def build_template(part: Part, template: str, start: float, depth: float, cfg: TemplateConfig,
                   footprint: Footprint | None = None, wall: float | None = None, shelves: bool = True) -> Interior:
    """The boxes of ``template`` behind ``part``'s front, occupying z in [start, start + depth]
    within ``footprint`` (default: the whole front). ``wall`` overrides ``cfg.wall``;
    ``shelves=False`` leaves a cabinet empty (DRAWER's 1 x 1 grid)."""
    if template not in TEMPLATES:
        raise ValueError(f"part {part.id}: unknown template {template!r} (known: {TEMPLATES})")
    if not (np.isfinite(start) and np.isfinite(depth)) or depth <= 0:
        raise NonFiniteError(f"part {part.id}: template depth {depth} / start {start} must be finite and > 0")
    o, R = front_frame(part.front)
    fp = footprint if footprint is not None else full_footprint(part.front)
    a0, a1, b0, b1 = template_footprint(template, fp, cfg)
    wall = cfg.wall if wall is None else wall
    z0, z1 = float(start), float(start + depth)
    boxes: list[tuple[str, tuple, tuple]] = []
    if template == "drawer":
        t = min(wall, cfg.max_wall_frac * min(a1 - a0, b1 - b0, depth))
        boxes += [("bottom", (a0, b0, z0), (a1, b0 + t, z1)),
                  ("front", (a0, b0 + t, z0), (a1, b1, z0 + t)),
                  ("back", (a0, b0 + t, z1 - t), (a1, b1, z1)),
                  ("left", (a0, b0 + t, z0 + t), (a0 + t, b1, z1 - t)),
                  ("right", (a1 - t, b0 + t, z0 + t), (a1, b1, z1 - t))]
        free = _local_box(o, R, (a0 + t, b0 + t, z0 + t), (a1 - t, b1, z1 - t))
        n_shelves = 0
        body = part.id
    else:
        t = min(wall, cfg.max_wall_frac * min(a1 - a0, b1 - b0, depth))
        boxes += [("back", (a0, b0, z1 - t), (a1, b1, z1)),
                  ("left", (a0, b0, z0), (a0 + t, b1, z1 - t)),
                  ("right", (a1 - t, b0, z0), (a1, b1, z1 - t)),
                  ("bottom", (a0 + t, b0, z0), (a1 - t, b0 + t, z1 - t)),
                  ("top", (a0 + t, b1 - t, z0), (a1 - t, b1, z1 - t))]
        inner_h = (b1 - b0) - 2 * t
        n_shelves = 0
        if template == "cabinet" and shelves and z0 + cfg.shelf_setback < z1 - t:
            n_shelves = max(0, int(round(inner_h / cfg.shelf_spacing)) - 1)
            for k in range(1, n_shelves + 1):
                bk = b0 + t + k * inner_h / (n_shelves + 1)
                boxes.append((f"shelf_{k}", (a0 + t, bk - t / 2, z0 + cfg.shelf_setback), (a1 - t, bk + t / 2, z1 - t)))
        free = _local_box(o, R, (a0 + t, b0 + t, z0), (a1 - t, b1 - t, z1 - t))
        body = "static"
    occupied = occupied_box(part, template, z0, float(depth), fp, cfg)
    outer = _local_box(o, R, (a0, b0, z0), (a1, b1, z1))
    walls = [_local_box(o, R, lo, hi) for _, lo, hi in boxes]
    for nm, bx in zip([b[0] for b in boxes], walls):
        if not (np.all(np.isfinite(bx.center)) and np.all(bx.half > 0)):
            raise NonFiniteError(f"part {part.id}: wall {nm} is not a valid box ({bx.center}, {bx.half})")
    return Interior(part.id, template, body, [w.shape() for w in walls], [b[0] for b in boxes], free, outer,
                    occupied, z0, float(depth), float(t), cfg.front_thickness, n_shelves)


# ---------------------------------------------------------------------------------------------
# evidence


@dataclass(frozen=True)
class Evidence:
    """What the mesh and the other fronts say about the depth behind one front (distances from
    its outer face, m). ``extent``: the measured carcass extent (None: no evidence), from
    ``source``; ``support``: points behind it; ``start``: where its interior starts; ``limit``:
    how far its interior may reach (the wall or a blocking front; None: unbounded)."""

    part_id: str
    template: str
    reason: str
    wall: float | None
    wall_points: int
    caps: dict
    carcass_depth: float | None
    tracks: list[str]
    blocking: float | None
    blocking_id: str | None
    start: float
    extent: float | None
    support: int
    source: str
    floor_z: float | None

    @property
    def limit(self) -> float | None:
        vals = [x for x in (self.wall, self.blocking) if x is not None]
        return min(vals) if vals else None

    def to_json(self) -> dict:
        return {"template": self.template, "reason": self.reason, "wall": self.wall, "wall_points": self.wall_points,
                "caps": {k: {"extent": e, "points": n} for k, (e, n) in self.caps.items()},
                "carcass_depth": self.carcass_depth, "tracks": self.tracks, "blocking": self.blocking,
                "blocking_id": self.blocking_id, "start": self.start, "extent": self.extent,
                "support": self.support, "source": self.source}


def floor_height(points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                 up_cos: float = 0.9) -> float | None:
    """Height of the floor: the 1st percentile of z of the up-facing points (None without any)."""
    up = normals[:, 2] >= up_cos
    if up.sum() < 10:
        return None
    return float(np.percentile(points[up, 2], 1.0))


@dataclass(frozen=True)
class LocalPoints:
    """Mesh points near one front in its frame: ``a``, ``b`` along (u, v), ``z`` behind its
    outer face; ``n`` [K, 3] their normals in (u, v, normal) coordinates; ``world`` [K, 3]."""

    a: np.ndarray
    b: np.ndarray
    z: np.ndarray
    n: np.ndarray
    world: np.ndarray
    world_n: np.ndarray


def local_points(front: Front, points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                 cfg: EvidenceConfig) -> LocalPoints:
    """The points within reach of every measurement on ``front`` (its extent grown by
    ``cap_band`` / ``v_band``, from 5 cm in front of it to ``max_behind``)."""
    c, R = front_frame(front)
    w, h = front.size
    loc = (points - c) @ R  # [N, 3]
    keep = ((np.abs(loc[:, 0]) <= w / 2 + cfg.cap_band) & (np.abs(loc[:, 1]) <= h / 2 + max(cfg.v_band, cfg.cap_band))
            & (loc[:, 2] < 0.05) & (loc[:, 2] > -cfg.max_behind))
    loc = loc[keep]
    return LocalPoints(loc[:, 0], loc[:, 1], -loc[:, 2], normals[keep] @ R, points[keep], normals[keep])


def wall_behind(front: Front, lp: LocalPoints, cfg: EvidenceConfig) -> tuple[float, int] | None:
    """(distance from the front's centre to the wall plane behind it, points on it), or None:
    the farthest histogram bin of the points facing like the front (within its u-range and
    ``v_band`` of its v-range) holding max(``min_points``, ``min_frac`` x the fullest bin)."""
    w, h = front.size
    a, b, z = lp.a, lp.b, lp.z
    sel = ((lp.n[:, 2] >= cfg.normal_cos) & (np.abs(a) <= cfg.u_frac * w / 2) & (np.abs(b) <= h / 2 + cfg.v_band)
           & (z > cfg.min_behind) & (z < cfg.max_behind))
    if sel.sum() < cfg.min_points:
        return None
    edges = np.arange(cfg.min_behind, cfg.max_behind + cfg.bin, cfg.bin)
    hist, _ = np.histogram(z[sel], edges)
    ok = np.nonzero(hist >= max(cfg.min_points, cfg.min_frac * hist.max()))[0]
    if len(ok) == 0:
        return None
    k = ok[-1]
    win = sel & (z >= edges[k] - cfg.bin) & (z <= edges[k + 1] + cfg.bin)
    cen = lp.world[win].mean(0)
    nw = lp.world_n[win].mean(0)
    nw /= np.linalg.norm(nw)
    return float((np.asarray(front.center) - cen) @ nw), int(win.sum())


_EDGES = {"top": (1, 1.0), "bottom": (1, -1.0), "right": (0, 1.0), "left": (0, -1.0)}


def cap_points(front: Front, lp: LocalPoints, cfg: EvidenceConfig, edge: str) -> np.ndarray:
    """[K] bool: the points of the surface continuing ``edge`` (top | bottom | left | right) of
    the front backwards: facing away from the edge, within ``cap_band`` beyond it."""
    ax, sgn = _EDGES[edge]
    coord, other = (lp.a, lp.b) if ax == 0 else (lp.b, lp.a)
    half, other_half = front.size[ax] / 2, front.size[1 - ax] / 2
    off = sgn * coord - half
    return ((sgn * lp.n[:, ax] >= cfg.normal_cos) & (off > -0.02) & (off < cfg.cap_band)
            & (np.abs(other) < cfg.u_frac * other_half) & (lp.z > -0.05) & (lp.z < cfg.max_behind))


def caps(front: Front, lp: LocalPoints, cfg: EvidenceConfig) -> dict[str, tuple[float, int]]:
    """{edge: (extent behind the outer face, points)} of the caps that start at the front."""
    out = {}
    for edge in _EDGES:
        sel = cap_points(front, lp, cfg, edge)
        if sel.sum() < cfg.cap_min_points:
            continue
        zs = lp.z[sel]
        ext = float(np.percentile(zs, cfg.cap_percentile))
        if np.percentile(zs, 5.0) < cfg.cap_reach and ext > cfg.cap_min_extent:
            out[edge] = (ext, int(sel.sum()))
    return out


def _projected_overlap(fi: Front, fj: Front) -> tuple[float, float, float]:
    """(overlap along u, overlap along v, fraction of front i covered) of front j's rectangle
    projected on front i's plane."""
    c, R = front_frame(fi)
    loc = (fj.corners() - c) @ R
    w, h = fi.size
    ou = min(w / 2, loc[:, 0].max()) - max(-w / 2, loc[:, 0].min())
    ov = min(h / 2, loc[:, 1].max()) - max(-h / 2, loc[:, 1].min())
    frac = max(ou, 0.0) * max(ov, 0.0) / (w * h)
    return float(ou), float(ov), float(frac)


def _swept_front(p: Part, in_plane_cos: float = 0.5) -> Front:
    """The rectangle a sliding panel covers over its range (its front extended along its axis
    when the axis lies in the front's plane); any other part's front as it is."""
    f = p.front
    d = np.asarray(p.axis.direction, np.float64) if p.axis is not None else None
    if p.kind != "prismatic" or d is None or abs(d @ np.asarray(f.normal)) >= in_plane_cos or p.limits is None:
        return f
    lo, hi = p.limits
    travel = hi - lo
    du, dv = abs(float(d @ np.asarray(f.u))), abs(float(d @ np.asarray(f.v)))
    c = np.asarray(f.center) + d * (lo + hi) / 2
    return Front(tuple(c.tolist()), f.normal, f.u, (f.size[0] + du * travel, f.size[1] + dv * travel))


def _neighbours(parts: Sequence[Part], cfg: EvidenceConfig, t_front: float, min_step: float = 0.008):
    """Per part: (start, track ids, blocking distance, blocking id) from the other fronts. A
    sliding panel counts as a track of the fronts its swept rectangle (:func:`_swept_front`)
    overlaps: the panels of a sliding pair abut at q = 0 and pass each other when opened."""
    out = []
    for i, pi in enumerate(parts):
        fi = pi.front
        ni, ci = np.asarray(fi.normal), np.asarray(fi.center)
        start, tracks, block, block_id = t_front, [], None, None
        for j, pj in enumerate(parts):
            fj = pj.front
            if i == j or ni @ np.asarray(fj.normal) < cfg.normal_cos:
                continue
            delta = float((ci - np.asarray(fj.center)) @ ni)  # > 0: j lies behind i
            if delta <= min_step:
                continue
            ou, ov, frac = _projected_overlap(fi, fj)
            su, sv, _ = _projected_overlap(fi, _swept_front(pj))
            if delta < cfg.track_gap and su > 0 and sv > 0:
                start = max(start, delta + t_front)
                tracks.append(pj.id)
            elif ou <= 0 or ov <= 0:
                continue
            elif frac >= cfg.blocking_overlap and (block is None or delta < block):
                block, block_id = delta, pj.id
        out.append((start, tracks, block, block_id))
    return out


def measure_evidence(parts: Sequence[Part], points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                     cfg: InteriorsConfig, floor_z: float | None = None) -> list[Evidence]:
    """The evidence of every articulated part (in order). ``points`` / ``normals``: samples of
    the scene mesh (visible surface, world frame, unit normals); ``floor_z``: the floor height
    (default: :func:`floor_height`)."""
    parts = [p for p in parts if p.articulated]
    for p in parts:
        check_part(p)
    points = np.asarray(points, np.float64)
    normals = np.asarray(normals, np.float64)
    if not (np.all(np.isfinite(points)) and np.all(np.isfinite(normals))):
        raise NonFiniteError("measure_evidence: the mesh points or normals hold NaN or inf")
    if floor_z is None and len(points):
        floor_z = floor_height(points, normals)
    ec, tc = cfg.evidence, cfg.template
    nb = _neighbours(parts, ec, tc.front_thickness)
    jc = JointsConfig()
    out = []
    for p, (start, tracks, block, block_id) in zip(parts, nb):
        tmpl, reason = template_kind(p, floor_z, tc)
        f = p.front
        if len(points):
            lp = local_points(f, points, normals, ec)
            wb = wall_behind(f, lp, ec)
            cp = caps(f, lp, ec)
            level = np.abs(lp.b) <= f.size[1] / 2
            cd = carcass_depth(f, lp.world[level], lp.world_n[level], jc)
        else:
            wb, cp, cd = None, {}, None
        wall, wall_n = (wb if wb is not None else (None, 0))
        extent, support, source = None, 0, "none"
        if cp and wall is not None and max(e for e, _ in cp.values()) > wall + ec.cap_short:
            wall, wall_n = None, 0  # a cap reaches behind it: a surface in front of the carcass
        if cp:
            edge = max(cp, key=lambda k: cp[k][0])
            cap_ext, cap_n = cp[edge]
            if wall is None or cap_ext < wall - ec.cap_short:
                extent, support, source = cap_ext, cap_n, f"cap:{edge}"
        if extent is None and wall is not None:
            extent, support, source = wall, wall_n, "wall"
        if extent is None and cd is not None:
            extent, support, source = cd, jc.carcass_min_points, "carcass_depth"
        out.append(Evidence(p.id, tmpl, reason, wall, wall_n, cp, cd, tracks, block, block_id, float(start), extent,
                            int(support), source, floor_z))
    return out


# ---------------------------------------------------------------------------------------------
# joint fit


def partition_footprints(parts: Sequence[Part], cfg: EvidenceConfig) -> list[Footprint]:
    """Each front's footprint, cut at the middle of any overlap with a near-parallel front less
    than ``track_gap`` in front of or behind it (neighbours in one cabinet, the two panels of a
    sliding pair), across the axis of the smaller overlap, so such neighbours never share
    interior space (depth cannot resolve a side-by-side overlap)."""
    fps = []
    for i, pi in enumerate(parts):
        a0, a1, b0, b1 = full_footprint(pi.front)
        c, R = front_frame(pi.front)
        for j, pj in enumerate(parts):
            if i == j or np.asarray(pi.front.normal) @ np.asarray(pj.front.normal) < cfg.normal_cos:
                continue
            if abs(float((c - np.asarray(pj.front.center)) @ R[:, 2])) >= cfg.track_gap:
                continue
            loc = (pj.front.corners() - c) @ R
            ja0, ja1, jb0, jb1 = loc[:, 0].min(), loc[:, 0].max(), loc[:, 1].min(), loc[:, 1].max()
            ou = min(a1, ja1) - max(a0, ja0)
            ov = min(b1, jb1) - max(b0, jb0)
            if ou <= 0 or ov <= 0:
                continue
            if ou <= ov:
                mid = (max(a0, ja0) + min(a1, ja1)) / 2
                if (ja0 + ja1) / 2 > (a0 + a1) / 2:
                    a1 = min(a1, mid)
                else:
                    a0 = max(a0, mid)
            else:
                mid = (max(b0, jb0) + min(b1, jb1)) / 2
                if (jb0 + jb1) / 2 > (b0 + b1) / 2:
                    b1 = min(b1, mid)
                else:
                    b0 = max(b0, mid)
        fps.append((float(a0), float(a1), float(b0), float(b1)))
    return fps


@dataclass
class FitResult:
    depths: np.ndarray  # [P] fitted template depths
    records: list[dict]
    default_extent: float  # the kitchen's median fitted carcass extent (m behind the outer face), else the config's
    default_source: str  # "kitchen_median" | "config"
    objective: float
    iterations: int
    success: bool


def fit_depths(parts: Sequence[Part], evidence: Sequence[Evidence], cfg: InteriorsConfig,
               footprints: Sequence[Footprint] | None = None) -> FitResult:
    """Fit all template depths jointly (module doc). ``parts`` and ``evidence`` align (the
    articulated parts, in order)."""
    parts = [p for p in parts if p.articulated]
    if len(parts) != len(evidence):
        raise ValueError(f"fit_depths: {len(parts)} articulated parts but {len(evidence)} evidence records")
    fc, tc = cfg.fit, cfg.template
    P = len(parts)
    fps = list(footprints) if footprints is not None else partition_footprints(parts, cfg.evidence)
    start = np.array([e.start for e in evidence])
    clear = np.array([tc.drawer_back_clearance if e.template == "drawer" else 0.0 for e in evidence])
    has = np.array([e.extent is not None for e in evidence], bool)
    ext = np.array([e.extent if e.extent is not None else np.nan for e in evidence])
    w = np.where(has, np.array([e.support / (e.support + cfg.evidence.support) for e in evidence]), fc.default_weight)
    ub = np.array([(e.limit - s) if e.limit is not None else np.inf for e, s in zip(evidence, start)])
    lb = np.minimum(np.array([travel(p) if e.template == "drawer" else 0.0 for p, e in zip(parts, evidence)]),
                    fc.max_depth)
    area = np.array([(fp[1] - fp[0]) * (fp[3] - fp[2]) for fp in fps])

    def box(i: int, d: float) -> OBox:
        b = occupied_box(parts[i], evidence[i].template, start[i], d, fps[i], tc)
        return replace(b, half=np.maximum(b.half - fc.overlap_tol, _MIN_HALF))

    def overlap(i: int, j: int, di: float, dj: float) -> float:
        return obox_overlap_volume(box(i, di), box(j, dj))

    # the pairs whose boxes meet at some depths in range (at the deepest, if at all)
    pairs = [(i, j, max(min(area[i], area[j]), 1e-6)) for i in range(P) for j in range(i + 1, P)
             if overlap(i, j, fc.max_depth, fc.max_depth) > 1e-12]

    def run(target: np.ndarray, weight: np.ndarray):
        """L-BFGS-B on the penalised objective, the penalty raised 10x per round from
        ``penalty`` / 1000 (continuation: the stiff final problem starts near its solution)."""
        h = fc.fd_step

        def f(x, rho):
            r = x - target
            val = float(np.sum(weight * r * r))
            g = 2 * weight * r
            a = np.maximum(x - ub, 0.0)
            b = np.maximum(lb - x, 0.0)
            val += rho * float(np.sum(a * a) + np.sum(b * b))
            g += 2 * rho * (a - b)
            for i, j, ar in pairs:
                o = overlap(i, j, x[i], x[j]) / ar
                if o <= 0:
                    continue
                val += rho * o * o
                gi = (overlap(i, j, x[i] + h, x[j]) - overlap(i, j, x[i] - h, x[j])) / (2 * h * ar)
                gj = (overlap(i, j, x[i], x[j] + h) - overlap(i, j, x[i], x[j] - h)) / (2 * h * ar)
                g[i] += 2 * rho * o * gi
                g[j] += 2 * rho * o * gj
            return val, g

        x = np.clip(np.minimum(target, np.where(np.isfinite(ub), ub, np.inf)), fc.min_depth, fc.max_depth)
        x = np.clip(np.maximum(x, lb), fc.min_depth, fc.max_depth)
        nit = 0
        for rho in fc.penalty * np.array([1e-3, 1e-2, 1e-1, 1.0]):
            res = minimize(f, x, args=(rho,), jac=True, method="L-BFGS-B",
                           bounds=[(fc.min_depth, fc.max_depth)] * P, options={"maxiter": fc.max_iter})
            x, nit = res.x, nit + res.nit
        if not np.all(np.isfinite(x)):
            raise NonFiniteError("fit_depths: the optimiser returned non-finite depths")
        res.nit = nit
        return res

    # pass 1: the parts with evidence (the others pulled weakly to the config default); pass 2
    # with each part without evidence pulled to the median of its run, else of the kitchen
    default_ext, default_src = tc.front_thickness + fc.default_depth, "config"
    target = np.where(has, ext - start - clear, default_ext - start - clear)
    part_src = np.where(has, "", "config").astype(object)
    if P == 0:
        return FitResult(np.zeros(0), [], default_ext, default_src, 0.0, 0, True)
    res = run(target, w)
    if has.any():
        fitted_ext = res.x + start + clear  # carcass extents behind the outer faces
        default_ext, default_src = float(np.median(fitted_ext[has])), "kitchen_median"
    if has.any() and (~has).any():
        for i in np.nonzero(~has)[0]:  # coplanar fronts (one run) share their carcass depth
            ni, ci = np.asarray(parts[i].front.normal), np.asarray(parts[i].front.center)
            co = [j for j in np.nonzero(has)[0]
                  if ni @ np.asarray(parts[j].front.normal) >= cfg.evidence.normal_cos
                  and abs((np.asarray(parts[j].front.center) - ci) @ ni) <= fc.coplanar_tol]
            e_i, part_src[i] = ((float(np.median(fitted_ext[co])), "coplanar_median") if co
                                else (default_ext, "kitchen_median"))
            target[i] = e_i - start[i] - clear[i]
        res = run(target, w)

    d = np.asarray(res.x, np.float64)
    tol = fc.active_tol
    t0 = np.clip(target, fc.min_depth, fc.max_depth)
    records = []
    for i, (p, e) in enumerate(zip(parts, evidence)):
        active = []
        if target[i] > ub[i] + tol:
            active.append("blocking_front" if (e.blocking is not None and e.limit == e.blocking) else "inside_carcass")
        if target[i] < lb[i] - tol:
            active.append("drawer_travel")
        if target[i] < fc.min_depth - tol:
            active.append("min_depth")
        if target[i] > fc.max_depth + tol:
            active.append("max_depth")
        records.append({"part": p.id, "template": e.template, "evidence": e.source,
                        "measured_depth": float(target[i]) if has[i] else None,
                        "default_depth": None if has[i] else float(target[i]),
                        "default_source": part_src[i] or None,
                        "fitted_depth": float(d[i]), "start": float(start[i]), "weight": float(w[i]),
                        "active": active, "overlap_with": []})
    for i, j, ar in pairs:
        before = overlap(i, j, t0[i], t0[j]) / ar
        after = overlap(i, j, d[i], d[j]) / ar
        if before > tol:
            records[i]["active"].append(f"overlap:{parts[j].id}")
            records[j]["active"].append(f"overlap:{parts[i].id}")
        if after > 0:
            records[i]["overlap_with"].append({"part": parts[j].id, "m": float(after)})
            records[j]["overlap_with"].append({"part": parts[i].id, "m": float(after)})
    return FitResult(d, records, default_ext, default_src, float(res.fun), int(res.nit), bool(res.success))


# ---------------------------------------------------------------------------------------------
# the whole thing, and DRAWER's rule


@dataclass
class InteriorsResult:
    interiors: list[Interior]
    evidence: list[Evidence]
    fit: FitResult

    def to_json(self) -> dict:
        return {"interiors": [x.to_json() for x in self.interiors],
                "default_extent": self.fit.default_extent, "default_source": self.fit.default_source,
                "objective": self.fit.objective, "iterations": self.fit.iterations, "success": self.fit.success}


def build_interiors(parts: Sequence[Part], points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                    cfg: InteriorsConfig, floor_z: float | None = None) -> InteriorsResult:
    """Measure, fit and build the interior of every articulated part (rigid parts are
    skipped). ``points`` / ``normals``: the scene mesh's visible surface, sampled."""
    arts = [p for p in parts if p.articulated]
    ev = measure_evidence(arts, points, normals, cfg, floor_z)
    fps = partition_footprints(arts, cfg.evidence)
    fit = fit_depths(arts, ev, cfg, fps)
    out = []
    for p, e, fp, d, rec in zip(arts, ev, fps, fit.depths, fit.records):
        it = build_template(p, e.template, e.start, float(d), cfg.template, fp)
        rec = rec | {"free_depth": it.free_depth, "shelves": it.shelves, "reason": e.reason,
                     "evidence_detail": e.to_json()}
        out.append(replace(it, record=rec))
    return InteriorsResult(out, ev, fit)


def drawer_rule_depth(part: Part) -> float:
    """DRAWER's fixed depth (``compose_usd.py``): 1.5 x the door's extent across its hinge (its
    width for a side-hinged door, its height for a flap) for revolute parts, 1.25 x the front's
    width for prismatic ones.

    >>> from drawer_lib.io.parts import Axis
    >>> f = Front((0.0, 0.0, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.4, 0.7))
    >>> round(drawer_rule_depth(Part("d", "revolute", Axis((-0.2, 0.0, 0.5), (0.0, 0.0, -1.0)), (0.0, 1.5), f)), 6)
    0.6
    """
    check_part(part)
    f = part.front
    if part.kind == "prismatic":
        return DRAWER_DRAWER_FACTOR * f.size[0]
    across_u = abs(np.asarray(part.axis.direction) @ f.v) >= abs(np.asarray(part.axis.direction) @ np.asarray(f.u))
    return DRAWER_DOOR_FACTOR * (f.size[0] if across_u else f.size[1])


def drawer_rule_interiors(parts: Sequence[Part], cfg: InteriorsConfig, floor_z: float | None = None) -> list[Interior]:
    """DRAWER's interiors for comparison: the same templates at the fixed depth of
    :func:`drawer_rule_depth`, 2 cm walls, no shelves, right behind the front."""
    out = []
    for p in (p for p in parts if p.articulated):
        check_part(p)
        tmpl, _ = template_kind(p, floor_z, cfg.template)
        d = drawer_rule_depth(p)
        it = build_template(p, tmpl, cfg.template.front_thickness, d, cfg.template, wall=DRAWER_WALL, shelves=False)
        out.append(replace(it, record={"rule": "drawer", "depth": d}))
    return out


# ---------------------------------------------------------------------------------------------
# texture


@dataclass(frozen=True)
class InteriorTexture:
    """``base``: {wall name: RGB in [0, 1]} (already darkened); ``patch``: [P, P, 3] tileable
    multiplicative detail with mean 1 (a wall's texture = base x patch); ``source``: whose
    colours were used (carcass | front | default)."""

    base: dict
    patch: np.ndarray
    source: str


def _ao(z: float, cfg: TextureConfig) -> float:
    return float(1.0 - cfg.ao_strength * (1.0 - np.exp(-max(z, 0.0) / cfg.ao_length)))


def interior_colours(interior: Interior, front_rgb: Float[np.ndarray, "N 3"],
                     carcass_rgb: Float[np.ndarray, "M 3"] | None, cfg: TextureConfig) -> InteriorTexture:
    """Per-wall base colours and a procedural patch for ``interior`` from the colours observed
    on its cabinet (RGB samples in [0, 1]): the carcass's when there are ``min_samples`` of
    them (a carcass is usually the colour of its inside), else the front's, else mid grey;
    each wall darkened by the ambient occlusion at its depth (``top_shade`` more on the
    ceiling); the patch carries the samples' per-channel spread (at most 15 %), smoothed.
    ``texturer: learned`` raises :class:`ConfigError` naming the missing model."""
    if cfg.texturer == "learned":
        raise ConfigError(
            f"complete.interiors.texture.texturer = 'learned' needs the learned texturer model "
            f"{cfg.learned_model!r} (DRAWER's MatFuse: Hugging Face gvecchio/MatFuse, checkpoint matfuse-full.ckpt), "
            "which is not installed; use texturer: observed")
    samples, source = None, "default"
    for name, s in (("carcass", carcass_rgb), ("front", front_rgb)):
        if s is None:
            continue
        s = np.asarray(s, np.float64).reshape(-1, 3)
        s = s[np.all(np.isfinite(s), axis=1)]
        if len(s) >= cfg.min_samples:
            samples, source = np.clip(s, 0, 1), name
            break
    mean = samples.mean(0) if samples is not None else np.full(3, 0.5)
    spread = np.minimum(samples.std(0) / np.maximum(mean, 1e-3), 0.15) if samples is not None else np.full(3, 0.03)
    depth_of = {"back": interior.start + interior.depth, "front": interior.start}
    mid = interior.start + interior.depth / 2
    base = {}
    for nm in interior.wall_names:
        k = _ao(depth_of.get(nm, mid) - interior.start, cfg)
        if nm == "top":
            k *= cfg.top_shade
        base[nm] = np.clip(mean * k, 0, 1)
    rng = np.random.default_rng([cfg.seed, zlib.crc32(interior.part_id.encode())])
    P = cfg.patch_size
    noise = rng.standard_normal((P, P, 3))
    if cfg.patch_grain > 0:
        noise = np.stack([gaussian_filter(noise[..., c], cfg.patch_grain, mode="wrap") for c in range(3)], -1)
    noise = (noise - noise.mean((0, 1))) / np.maximum(noise.std((0, 1)), 1e-12)
    patch = np.clip(1.0 + noise * spread, 0.0, 2.0)
    return InteriorTexture(base, patch, source)


def front_sample_points(front: Front, n: int = 8, frac: float = 0.8, offset: float = 0.002) -> Float[np.ndarray, "K 3"]:
    """An n x n grid over the central ``frac`` of the front, ``offset`` in front of its face."""
    c, R = front_frame(front)
    g = (np.arange(n) + 0.5) / n - 0.5
    A, B = np.meshgrid(g * frac * front.size[0], g * frac * front.size[1])
    return c + A.reshape(-1, 1) * R[:, 0] + B.reshape(-1, 1) * R[:, 1] + offset * R[:, 2]


def carcass_sample_points(front: Front, points: Float[np.ndarray, "N 3"], normals: Float[np.ndarray, "N 3"],
                          cfg: EvidenceConfig) -> Float[np.ndarray, "K 3"]:
    """Mesh points on the carcass around a front: its side caps (end panels) and its bottom cap
    (a wall cabinet's underside); the top cap is left out (usually a counter)."""
    lp = local_points(front, np.asarray(points, np.float64), np.asarray(normals, np.float64), cfg)
    sel = np.zeros(len(lp.z), bool)
    for edge in ("left", "right", "bottom"):
        sel |= cap_points(front, lp, cfg, edge)
    return lp.world[sel]


def observed_colours(points: Float[np.ndarray, "K 3"], cameras: Sequence, images: Sequence, raycaster,
                     occlusion_tol: float = 0.02, max_views: int | None = None) -> Float[np.ndarray, "S 3"]:
    """RGB samples in [0, 1] of ``points`` in the views that see them: each point projected into
    each camera (:class:`drawer_lib.geometry.camera.Camera`) with its image (uint8 [H, W, 3]),
    kept where the mesh (``raycaster``: :class:`drawer_lib.geometry.raycast.Raycaster`) does
    not hide it (the first hit along the ray is within ``occlusion_tol`` of it)."""
    from drawer_lib.geometry.camera import pixel_of

    out = []
    views = list(zip(cameras, images))[:max_views] if max_views else list(zip(cameras, images))
    for cam, img in views:
        i, j, _, inside = pixel_of(points, cam.w2c, cam.intrinsics)
        if not inside.any():
            continue
        o = cam.center
        dvec = points[inside] - o
        dist = np.linalg.norm(dvec, axis=1)
        t, _, _ = raycaster.cast(np.broadcast_to(o, dvec.shape).copy(), dvec / dist[:, None])
        vis = t >= dist - occlusion_tol
        if vis.any():
            out.append(np.asarray(img)[i[inside][vis], j[inside][vis]].astype(np.float64) / 255.0)
    return np.concatenate(out) if out else np.zeros((0, 3))
