"""Cut the articulated parts out of the scene mesh: each part's body (its front panel and
handle) and the static remainder with a cavity where the part's solid sweeps.

Conventions: world frame, metres, +z up (docs/formats.md#conventions); a part's front frame
has axes (u, v, n) = (``front.u``, ``front.normal`` x ``front.u``, ``front.normal``) about the
centre of its outer face; q in rad (revolute) or m (prismatic), q = 0 closed, positive opens
(as in ``drawer.parts/1``).

DRAWER's official code (``isaac_sim/compose_usd.py``, ``splat/scripts/splat_merge.py``)
removes from the static mesh only the vertices inside each door's thin slab; here every static
face the part's solid passes through while it opens is removed too, so an opened drawer or door
never shows the old surface inside it. The solid of a door,
flap or sliding panel is its front rectangle times the panel thickness; that of a drawer the
front rectangle times the drawer box's depth. The swept volume is the union of that oriented
box over q sampled on its range; each sampled box is grown by ``sweep_tol`` and the samples are
spaced so that no point of the solid moves more than twice that between neighbours: the sampled
union then contains the exact swept volume.
"""

import math
import time
from dataclasses import dataclass, field

import numpy as np
import trimesh
from jaxtyping import Bool, Float, Int

from drawer_lib.articulation.config import JointsConfig
from drawer_lib.articulation.probes import carcass_depth
from drawer_lib.complete.config import CutConfig
from drawer_lib.errors import InputError
from drawer_lib.geometry.boxes import OrientedBox, boxes_contain, front_frame
from drawer_lib.geometry.joints import joint_transform
from drawer_lib.io.parts import Front, Part, PartsFile

# ------------------------------------------------------------------------------ swept volumes


@dataclass(frozen=True, eq=False)
class Sweep:
    """The swept volume of a part's solid: the union of K oriented boxes (the solid's boxes at
    each q sample: ``q`` [K] the joint value of each, ``centers`` [K, 3], ``rotations`` [K, 3, 3],
    ``halves`` [K, 3]) grown by ``grow`` (m); it contains the exact swept volume."""

    part_id: str
    q: np.ndarray
    centers: np.ndarray
    rotations: np.ndarray
    halves: np.ndarray
    grow: float

    @property
    def n_q(self) -> int:
        """The number of q samples (each holds one box per box of the solid)."""
        return int(len(np.unique(self.q)))

    def bounds(self, inflate: float = 0.0) -> tuple[Float[np.ndarray, "3"], Float[np.ndarray, "3"]]:
        """World axis-aligned bounds (lo [3], hi [3]) of the union, grown by ``inflate`` more."""
        ext = np.einsum("kij,kj->ki", np.abs(self.rotations), self.halves + self.grow + inflate)  # [K, 3]
        return (self.centers - ext).min(0), (self.centers + ext).max(0)

    def contains(self, points: Float[np.ndarray, "N 3"], inflate: float = 0.0) -> Bool[np.ndarray, "N"]:
        """Whether each point [N, 3] lies in the swept volume (each box grown by ``grow`` +
        ``inflate``). Vectorised over points and boxes in blocks."""
        return boxes_contain(points, self.centers, self.rotations, self.halves + self.grow + inflate)

    def box(self, k: int) -> OrientedBox:
        """Box ``k`` of the union (not grown)."""
        return OrientedBox(self.centers[k], self.rotations[k], self.halves[k].copy())


# ------------------------------------------------------------------------------ part solids


def front_box(front: Front, n_lo: float, n_hi: float, inset: float = 0.0) -> OrientedBox:
    """The box over the front rectangle shrunk by ``inset`` (m) on each side (at most a quarter
    of each extent), from ``n_lo`` to ``n_hi`` (m) along the outward normal from the outer face
    (negative: behind it)."""
    if not (math.isfinite(n_lo) and math.isfinite(n_hi) and n_hi > n_lo):
        raise InputError(f"front_box: normal range [{n_lo}, {n_hi}] m is empty or not finite")
    R = front_frame(front.normal, front.u)
    w, h = front.size
    iu, iv = min(inset, w / 4), min(inset, h / 4)
    c = np.asarray(front.center, np.float64) + R[:, 2] * (n_lo + n_hi) / 2
    return OrientedBox(c, R, np.array([w / 2 - iu, h / 2 - iv, (n_hi - n_lo) / 2], np.float64))


def part_solid(part: Part, depth: float, cfg: CutConfig) -> list[OrientedBox]:
    """The part's solid at q = 0 as boxes: a door, flap or sliding panel is its front rectangle
    times ``depth`` (the panel thickness) behind the outer face; a drawer is its front panel
    (``panel_thickness``) plus, behind it down to ``depth`` (m), its box: the rectangle shrunk by
    ``drawer_inset`` on each side (a drawer box is narrower than its front, which overlaps the
    carcass)."""
    if not (math.isfinite(depth) and depth > 0):
        raise InputError(f"part {part.id}: solid depth {depth} m must be finite and > 0")
    if part.front is None:
        raise InputError(f"part {part.id}: a {part.kind} part has no front")
    t = min(cfg.panel_thickness, depth)
    boxes = [front_box(part.front, -t, 0.0)]
    if is_drawer(part, cfg) and depth > t:
        boxes.append(front_box(part.front, -depth, -t, cfg.drawer_inset))
    return boxes


def is_drawer(part: Part, cfg: CutConfig) -> bool:
    """A prismatic part moving within acos(``drawer_normal_cos``) of its outward normal."""
    return (part.kind == "prismatic"
            and abs(float(np.dot(part.axis.direction, part.front.normal))) >= cfg.drawer_normal_cos)


def part_depth(part: Part, cfg: CutConfig, depth: float | None = None,
               mesh_points: Float[np.ndarray, "P 3"] | None = None,
               mesh_normals: Float[np.ndarray, "P 3"] | None = None) -> tuple[float, str]:
    """(depth of the part's solid (m), where it came from). A door, flap or sliding panel:
    ``panel_thickness`` ("panel"). A drawer: ``depth`` when given ("given"); else the carcass
    depth minus ``drawer_back_clearance`` (at least ``drawer_min_depth``), from the part's
    ``carcass_depth`` ("carcass") or measured on ``mesh_points`` [P, 3] / ``mesh_normals``
    [P, 3] with :func:`~drawer_lib.articulation.probes.carcass_depth` ("measured"); else
    ``drawer_default_depth`` ("default")."""
    if not is_drawer(part, cfg):
        return cfg.panel_thickness, "panel"
    if depth is not None:
        if not (math.isfinite(depth) and depth > 0):
            raise InputError(f"part {part.id}: given drawer depth {depth} m must be finite and > 0")
        return float(depth), "given"
    c, src = part.extra.get("carcass_depth"), "carcass"
    if c is None and mesh_points is not None and mesh_normals is not None and len(mesh_points):
        c, src = carcass_depth(part.front, mesh_points, mesh_normals, JointsConfig()), "measured"
    if c is not None and math.isfinite(c) and c > 0:
        return max(float(c) - cfg.drawer_back_clearance, cfg.drawer_min_depth), src
    return cfg.drawer_default_depth, "default"


def sweep_part(part: Part, depth: float, cfg: CutConfig) -> Sweep:
    """The swept volume of the part's solid (:func:`part_solid` with ``depth`` m) over q in
    [min(0, lower), max(0, upper)]. Samples: a point at distance r from a hinge moves r dq, on a
    slide dq; they are spaced so that this stays within 2 ``sweep_tol`` between neighbours (at
    most ``max_q_samples``; beyond, the growth rises to match)."""
    if not part.articulated:
        raise InputError(f"part {part.id}: a {part.kind} part has no joint to sweep")
    boxes = part_solid(part, depth, cfg)
    q0, q1 = min(0.0, float(part.limits[0])), max(0.0, float(part.limits[1]))
    o, d = np.asarray(part.axis.origin, np.float64), np.asarray(part.axis.direction, np.float64)
    if part.kind == "revolute":
        rel = np.concatenate([b.corners() for b in boxes]) - o
        rate = float(np.linalg.norm(rel - np.outer(rel @ d, d), axis=1).max())  # m per rad at the farthest corner
    else:
        rate = 1.0
    span = (q1 - q0) * rate  # longest path of a solid point (m)
    n = 1 if span <= 0 else min(cfg.max_q_samples, int(math.ceil(span / (2 * cfg.sweep_tol))) + 1)
    grow = cfg.sweep_tol if n == 1 else max(cfg.sweep_tol, span / (n - 1) / 2)
    q = np.linspace(q0, q1, n) if n > 1 else np.array([q0])
    T = np.stack([joint_transform(part.kind, o, d, float(x)) for x in q])  # [Q, 4, 4] (loop over q samples)
    c0 = np.stack([b.center for b in boxes])  # [S, 3]
    r0 = np.stack([b.rotation for b in boxes])  # [S, 3, 3]
    centers = np.einsum("qij,sj->qsi", T[:, :3, :3], c0) + T[:, None, :3, 3]  # [Q, S, 3]
    rotations = np.einsum("qij,sjl->qsil", T[:, :3, :3], r0)  # [Q, S, 3, 3]
    halves = np.broadcast_to(np.stack([b.half for b in boxes]), (n, len(boxes), 3))
    return Sweep(part.id, np.repeat(q, len(boxes)), centers.reshape(-1, 3), rotations.reshape(-1, 3, 3),
                 halves.reshape(-1, 3).copy(), float(grow))


# ------------------------------------------------------------------------------------ cutting


@dataclass(eq=False)
class PartCut:
    """One articulated part cut out: its ``body`` (front panel and handle faces, world frame at
    q = 0), the input face ids of the body ``body_faces`` [B] and of the static faces its sweep
    removed ``cavity_faces`` [C], the depth of its solid and where it came from, its sweep."""

    id: str
    kind: str
    solid: str  # drawer | panel
    body: trimesh.Trimesh
    body_faces: np.ndarray
    cavity_faces: np.ndarray
    depth: float
    depth_source: str
    sweep: Sweep
    wall_s: float

    def stats(self) -> dict:
        return {"kind": self.kind, "solid": self.solid, "n_body_faces": int(len(self.body_faces)),
                "n_cavity_faces": int(len(self.cavity_faces)), "depth_m": round(self.depth, 4),
                "depth_source": self.depth_source, "n_q": self.sweep.n_q,
                "sweep_grow_m": round(self.sweep.grow, 5), "wall_s": round(self.wall_s, 4)}


@dataclass(eq=False)
class CutResult:
    """The scene mesh split: the ``static`` remainder (input face ids ``static_faces`` [S]) and
    each articulated part by id."""

    static: trimesh.Trimesh
    static_faces: np.ndarray
    parts: dict[str, PartCut] = field(default_factory=dict)
    wall_s: float = 0.0

    def stats(self) -> dict:
        return {"n_static_faces": int(len(self.static_faces)), "wall_s": round(self.wall_s, 4),
                "parts": {k: p.stats() for k, p in self.parts.items()}}


def submesh(vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"], keep: Int[np.ndarray, "K"]
            ) -> trimesh.Trimesh:
    """The faces ``keep`` [K] of a mesh with only the vertices they use (order kept)."""
    f = faces[keep]
    used, inv = np.unique(f.reshape(-1), return_inverse=True)
    return trimesh.Trimesh(vertices[used], inv.reshape(-1, 3), process=False)


def _check_mesh(mesh: trimesh.Trimesh, what: str) -> tuple[np.ndarray, np.ndarray]:
    V = np.asarray(mesh.vertices, np.float64)
    F = np.asarray(mesh.faces, np.int64)
    if F.ndim != 2 or F.shape[1:] != (3,) or V.ndim != 2 or V.shape[1:] != (3,):
        raise InputError(f"{what}: expected vertices [V, 3] and faces [F, 3], got {V.shape}, {F.shape}")
    if len(F) and (F.min() < 0 or F.max() >= len(V)):
        raise InputError(f"{what}: face indices outside [0, {len(V)})")
    if not np.all(np.isfinite(V)):
        raise InputError(f"{what}: {int((~np.isfinite(V)).any(1).sum())} non-finite vertices")
    return V, F


def body_owner(centroids: Float[np.ndarray, "F 3"], parts: list[Part], cfg: CutConfig) -> Int[np.ndarray, "F"]:
    """Index into ``parts`` of the part whose front slab holds each face centroid [F, 3], -1 for
    none. Slab: |u| <= w/2 + margin, |v| <= h/2 + margin, -back <= n <= protrusion; a face in
    several slabs goes to the one it lies deepest inside (largest distance to the rectangle's
    edges)."""
    owner = np.full(len(centroids), -1, np.int64)
    best = np.full(len(centroids), -np.inf)
    for k, p in enumerate(parts):  # loop over parts
        f = p.front
        local = (centroids - np.asarray(f.center)) @ front_frame(f.normal, f.u)  # [F, 3] (u, v, n)
        hw, hh = f.size[0] / 2, f.size[1] / 2
        inside = ((np.abs(local[:, 0]) <= hw + cfg.margin) & (np.abs(local[:, 1]) <= hh + cfg.margin)
                  & (local[:, 2] >= -cfg.back) & (local[:, 2] <= cfg.protrusion))
        inset = np.minimum(hw - np.abs(local[:, 0]), hh - np.abs(local[:, 1]))
        take = inside & (inset > best)
        owner[take], best[take] = k, inset[take]
    return owner


def faces_in_sweep(vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"], candidates: Int[np.ndarray, "K"],
                   sweep: Sweep, inflate: float = 0.0) -> Int[np.ndarray, "M"]:
    """The faces among ``candidates`` [K] with their centroid or a vertex inside ``sweep``."""
    if len(candidates) == 0:
        return candidates
    lo, hi = sweep.bounds(inflate)
    f = faces[candidates]  # [K, 3]
    tri = vertices[f]  # [K, 3, 3]
    near = np.all((tri.max(1) >= lo) & (tri.min(1) <= hi), axis=1)  # face bounds meet the sweep's bounds
    cand, f, tri = candidates[near], f[near], tri[near]
    if len(cand) == 0:
        return cand
    used, inv = np.unique(f.reshape(-1), return_inverse=True)
    v_in = sweep.contains(vertices[used], inflate)[inv].reshape(-1, 3).any(1)
    c_in = sweep.contains(tri.mean(1), inflate)
    return cand[v_in | c_in]


def cut_parts(mesh: trimesh.Trimesh, parts: PartsFile, cfg: CutConfig,
              depths: dict[str, float] | None = None) -> CutResult:
    """Split the scene ``mesh`` (world frame, m) into each articulated part's body and the static
    remainder with a cavity per part (see the module doc).

    Args: ``parts``: the ``drawer.parts/1`` parts (rigid ones are ignored here); ``depths``:
    drawer box depths (m) by part id (from the interiors; missing ones use the carcass depth;
    a depth given for a door, flap or sliding panel is not used: its solid is the panel).
    Returns: :class:`CutResult` (static mesh and its input face ids [S]; per part the body mesh,
    its face ids [B], the removed cavity face ids [C], depth, sweep, time).
    """
    t0 = time.perf_counter()
    V, F = _check_mesh(mesh, "cut_parts: scene mesh")
    depths = depths or {}
    art = [p for p in parts.parts if p.articulated]
    unknown = sorted(set(depths) - {p.id for p in art})
    if unknown:
        raise InputError(f"cut_parts: depths given for unknown articulated parts {unknown}")
    C = V[F].mean(1) if len(F) else np.zeros((0, 3))  # [F, 3] centroids
    owner = body_owner(C, art, cfg)
    removed = np.zeros(len(F), bool)
    normals = None
    out: dict[str, PartCut] = {}
    for k, p in enumerate(art):  # loop over parts
        t1 = time.perf_counter()
        if is_drawer(p, cfg) and p.id not in depths and p.extra.get("carcass_depth") is None and normals is None:
            normals = np.asarray(mesh.face_normals, np.float64) if len(F) else np.zeros((0, 3))
        depth, src = part_depth(p, cfg, depths.get(p.id), C if normals is not None else None, normals)
        sw = sweep_part(p, depth, cfg)
        cav = faces_in_sweep(V, F, np.flatnonzero((owner < 0) & ~removed), sw)
        removed[cav] = True
        body_faces = np.flatnonzero(owner == k)
        out[p.id] = PartCut(p.id, p.kind, "drawer" if is_drawer(p, cfg) else "panel", submesh(V, F, body_faces),
                            body_faces, cav, depth, src, sw, time.perf_counter() - t1)
    static_faces = np.flatnonzero((owner < 0) & ~removed)
    return CutResult(submesh(V, F, static_faces), static_faces, out, time.perf_counter() - t0)
