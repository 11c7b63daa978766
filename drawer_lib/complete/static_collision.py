"""Static collision geometry as boxes.

MuJoCo collides a mesh geom as its convex hull, so the static kitchen cannot be one mesh (it
would be one convex blob). Here it becomes a few hundred boxes: an occupancy grid of the scene
(from the SDF field: s < iso at a cell centre), carved where the parts sweep and the interiors
sit, merged greedily into boxes.

Conventions: world frame, metres, +z up. The grid is turned about +z by ``yaw`` (the mesh's
dominant horizontal direction, so that boxes align with the cabinets); ``rotation`` [3, 3] =
Rz(yaw) maps grid coordinates to the world (columns = the grid axes), and every box carries it.
Cell (i, j, k) spans ``origin + [i, j, k] * cell`` to ``origin + [i + 1, j + 1, k + 1] * cell`` in
grid coordinates.

Without a field (``source: mesh``) the occupancy is a heuristic from the visual mesh alone: the
cells its surface passes through, plus every cell whose nearest surface cell above it (in its
column) faces up (a counter top, a floor: the solid under them down to the next surface). It
gives closed cabinets and a thick floor; surfaces seen only from below (the underside of a wall
cabinet whose top is unseen) stay one cell thick.
"""

import itertools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
import trimesh
from jaxtyping import Bool, Float, Int
from scipy import ndimage

from drawer_lib.complete.config import StaticCollisionConfig
from drawer_lib.errors import InputError
from drawer_lib.geometry.sampling import sample_triangles
from drawer_lib.bodies import Shape, box_shape


# ----------------------------------------------------------------------------------- the frame


def yaw_rotation(yaw: float) -> Float[np.ndarray, "3 3"]:
    """Rz(``yaw``) [3, 3] (rad): columns = the grid axes in the world."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def dominant_yaw(mesh: trimesh.Trimesh, cfg: StaticCollisionConfig) -> float:
    """The mesh's dominant horizontal direction (rad, in [-pi/4, pi/4)): the peak of the
    area-weighted histogram of its vertical faces' normal angles mod 90 degrees (faces within
    ``vertical_deg`` of vertical; bins of ``yaw_bin_deg``, circularly smoothed), refined by the
    circular mean of 4 x angle over the faces within two bins of the peak. 0 without vertical
    faces."""
    N = np.asarray(mesh.face_normals, np.float64)  # [F, 3]
    A = np.asarray(mesh.area_faces, np.float64)  # [F]
    sel = (np.abs(N[:, 2]) < math.sin(math.radians(cfg.vertical_deg))) & (A > 0) & np.isfinite(N).all(1)
    if not sel.any():
        return 0.0
    a = np.mod(np.arctan2(N[sel, 1], N[sel, 0]), math.pi / 2)  # [S] in [0, pi/2)
    w = A[sel]
    nb = max(4, int(round(90.0 / cfg.yaw_bin_deg)))
    h, _ = np.histogram(a, bins=nb, range=(0.0, math.pi / 2), weights=w)
    h = (np.roll(h, 1) + 2 * h + np.roll(h, -1)) / 4  # circular smoothing
    peak = (np.argmax(h) + 0.5) * (math.pi / 2) / nb
    d = np.mod(a - peak + math.pi / 4, math.pi / 2) - math.pi / 4  # circular offset from the peak
    near = np.abs(d) <= 2.0 * (math.pi / 2) / nb
    phi = math.atan2(float((w[near] * np.sin(4 * a[near])).sum()), float((w[near] * np.cos(4 * a[near])).sum())) / 4
    return float(np.mod(phi + math.pi / 4, math.pi / 2) - math.pi / 4)


@dataclass(frozen=True, eq=False)
class VoxelGrid:
    """Occupancy ``occ`` [X, Y, Z] bool on cells of ``cell`` (m) from ``origin`` [3] (grid
    coordinates, m), grid axes ``rotation`` [3, 3] (= Rz(yaw), columns in the world)."""

    occ: np.ndarray
    origin: np.ndarray
    cell: float
    rotation: np.ndarray

    def centers(self, idx: Int[np.ndarray, "N 3"]) -> Float[np.ndarray, "N 3"]:
        """World centres [N, 3] (m) of cells ``idx`` [N, 3] (i, j, k)."""
        return (self.origin + (idx + 0.5) * self.cell) @ self.rotation.T

    def with_occ(self, occ: np.ndarray) -> "VoxelGrid":
        """The same grid with occupancy ``occ`` [X, Y, Z]."""
        return VoxelGrid(occ, self.origin, self.cell, self.rotation)


def grid_box(points: Float[np.ndarray, "N 3"], rotation: Float[np.ndarray, "3 3"], cell: float, margin_cells: int,
             clip: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[Float[np.ndarray, "3"], tuple[int, int, int]]:
    """(origin [3] in grid coordinates, shape (X, Y, Z)) of a grid of ``cell`` covering
    ``points`` [N, 3] (world) plus ``margin_cells``, clipped to the world box ``clip`` = (lo [3],
    hi [3]) when given."""
    if len(points) == 0:
        raise InputError("grid_box: no points to cover")
    local = points @ rotation  # [N, 3]
    lo, hi = local.min(0) - margin_cells * cell, local.max(0) + margin_cells * cell
    if clip is not None:
        c = np.array([[x, y, z] for x in (clip[0][0], clip[1][0]) for y in (clip[0][1], clip[1][1])
                      for z in (clip[0][2], clip[1][2])]) @ rotation
        lo, hi = np.maximum(lo, c.min(0)), np.minimum(hi, c.max(0))
    if np.any(hi <= lo):
        raise InputError("grid_box: the mesh lies outside the field's box")
    shape = np.maximum(np.ceil((hi - lo) / cell).astype(np.int64), 1)
    return lo, (int(shape[0]), int(shape[1]), int(shape[2]))


def _all_cells(shape: tuple[int, int, int]) -> Int[np.ndarray, "N 3"]:
    return np.stack(np.meshgrid(*(np.arange(s) for s in shape), indexing="ij"), -1).reshape(-1, 3)


# ------------------------------------------------------------------------------- occupancy


def occupancy_from_field(sdf: Callable, field_lo: Float[np.ndarray, "3"], field_hi: Float[np.ndarray, "3"],
                         mesh: trimesh.Trimesh, cfg: StaticCollisionConfig, yaw: float) -> VoxelGrid:
    """Occupancy from an SDF: ``sdf`` maps world points torch [N, 3] float32 to signed distances
    [N] (m, positive in free space); it is evaluated at the cell centres of a grid over the visual
    ``mesh``'s extent (plus ``margin_cells``) inside the field's box [``field_lo``, ``field_hi``];
    occupied where s < ``iso``. Cells outside the field's box are free."""
    R = yaw_rotation(yaw)
    origin, shape = grid_box(np.asarray(mesh.vertices, np.float64), R, cfg.cell, cfg.margin_cells,
                             (np.asarray(field_lo, np.float64), np.asarray(field_hi, np.float64)))
    grid = VoxelGrid(np.zeros(shape, bool), origin, cfg.cell, R)
    idx = _all_cells(shape)  # [X*Y*Z, 3]
    P = grid.centers(idx)
    inside = np.all((P >= field_lo) & (P <= field_hi), axis=1)
    occ = np.zeros(len(P), bool)
    todo = np.flatnonzero(inside)
    with torch.no_grad():
        for a in range(0, len(todo), cfg.chunk):  # blocks of points, not a loop over cells
            sl = todo[a:a + cfg.chunk]
            s = sdf(torch.from_numpy(P[sl].astype(np.float32))).reshape(-1).detach().cpu().numpy()
            if not np.all(np.isfinite(s)):
                bad = int((~np.isfinite(s)).sum())
                raise InputError(f"occupancy_from_field: the SDF returned {bad} non-finite values")
            occ[sl] = s < cfg.iso
    return grid.with_occ(occ.reshape(shape))


def occupancy_from_mesh(mesh: trimesh.Trimesh, cfg: StaticCollisionConfig, yaw: float, seed: int = 0) -> VoxelGrid:
    """Occupancy from the visual mesh alone (heuristic; see the module doc): the cells its
    surface passes through (area samples, ~16 per cell face area) plus the cells whose nearest
    surface cell at or above them in their column faces up (mean sample normal z > ``up_cos``)."""
    R = yaw_rotation(yaw)
    V = np.asarray(mesh.vertices, np.float64)
    origin, shape = grid_box(V, R, cfg.cell, max(cfg.margin_cells, 1))
    tri = V[np.asarray(mesh.faces)]  # [F, 3, 3]
    area = np.asarray(mesh.area_faces, np.float64)
    n = int(min(max(16 * area.sum() / cfg.cell**2, 1000), 5_000_000))
    P, f = sample_triangles(tri, n, np.random.default_rng(seed), areas=area)
    P = np.concatenate([P, tri.reshape(-1, 3)])  # every vertex too: small faces are never missed
    nz = np.concatenate([np.asarray(mesh.face_normals)[f, 2], np.repeat(np.asarray(mesh.face_normals)[:, 2], 3)])
    ijk = np.clip(np.floor((P @ R - origin) / cfg.cell).astype(np.int64), 0, np.array(shape) - 1)
    flat = np.ravel_multi_index(ijk.T, shape)
    cnt = np.bincount(flat, minlength=int(np.prod(shape))).reshape(shape)
    mean_nz = (np.bincount(flat, weights=nz, minlength=int(np.prod(shape))).reshape(shape) / np.maximum(cnt, 1))
    surf = cnt > 0
    up = surf & (mean_nz > cfg.up_cos)
    Z = shape[2]
    key = np.where(surf, np.arange(Z)[None, None, :], Z)  # [X, Y, Z] z of a surface cell, else Z
    above = np.minimum.accumulate(key[:, :, ::-1], axis=2)[:, :, ::-1]  # nearest surface cell at or above
    has = above < Z
    up_above = np.take_along_axis(up, np.minimum(above, Z - 1), axis=2) & has
    return VoxelGrid(surf | up_above, origin, cfg.cell, R)


def as_carver(c):
    """A box ``Shape`` as its :class:`~drawer_lib.geometry.boxes.OrientedBox`; anything with
    ``bounds`` and ``contains`` (a :class:`~drawer_lib.complete.cut.Sweep`, an ``OrientedBox``)
    as it is."""
    if isinstance(c, Shape):
        if c.kind != "box":
            raise InputError("carve: only box shapes can be carved (got a mesh shape)")
        return c.box
    if not (hasattr(c, "bounds") and hasattr(c, "contains")):
        raise InputError(f"carve: a {type(c).__name__} is neither a box Shape nor a volume with bounds/contains")
    return c


def carve(grid: VoxelGrid, carvers: Sequence, inflate: float) -> tuple[VoxelGrid, int]:
    """Empty the occupied cells whose centre lies in any of ``carvers`` grown by ``inflate``
    (m): a part's :class:`~drawer_lib.complete.cut.Sweep`, an interior's cavity as an
    :class:`~drawer_lib.geometry.boxes.OrientedBox` or a box ``Shape``, or any object with
    ``bounds(inflate) -> (lo [3], hi [3])`` and ``contains(points [N, 3], inflate) -> [N]``.
    Returns (the carved grid, the number of cells emptied)."""
    occ = grid.occ.copy()
    idx = np.argwhere(occ)  # [N, 3]
    carvers = [as_carver(c) for c in carvers]
    if len(idx) == 0 or not carvers:
        return grid.with_occ(occ), 0
    P = grid.centers(idx)
    gone = np.zeros(len(P), bool)
    for c in carvers:  # loop over parts / cavities
        lo, hi = c.bounds(inflate)
        near = np.flatnonzero(np.all((P >= lo) & (P <= hi), axis=1) & ~gone)
        if len(near):
            gone[near[c.contains(P[near], inflate)]] = True
    occ[tuple(idx[gone].T)] = False
    return grid.with_occ(occ), int(gone.sum())


def near_surface(grid: VoxelGrid, mesh: trimesh.Trimesh, depth: float, seed: int = 0) -> tuple[VoxelGrid, int]:
    """Keep only the occupied cells whose centre lies within ``depth`` (m) of the visual
    ``mesh`` (distance to area samples spaced at most half a cell, plus the vertices; the
    error is below that spacing). An SDF is negative in space no camera saw (a neural field's
    inside-out initialisation, a TSDF's unknown); such phantom solid far from any visible
    surface is dropped, solid behind a visible surface is kept to ``depth``. Returns (the grid,
    the number of cells dropped)."""
    from scipy.spatial import cKDTree

    idx = np.argwhere(grid.occ)
    if len(idx) == 0:
        return grid, 0
    tri = np.asarray(mesh.vertices, np.float64)[np.asarray(mesh.faces)]
    area = np.asarray(mesh.area_faces, np.float64)
    spacing = grid.cell / 2
    n = int(min(max(2 * area.sum() / spacing**2, 1000), 3_000_000))
    P, _ = sample_triangles(tri, n, np.random.default_rng(seed), areas=area)
    tree = cKDTree(np.concatenate([P, np.asarray(mesh.vertices, np.float64)]))
    d, _ = tree.query(grid.centers(idx), k=1, distance_upper_bound=depth + spacing)
    far = ~(d <= depth)
    occ = grid.occ.copy()
    occ[tuple(idx[far].T)] = False
    return grid.with_occ(occ), int(far.sum())


def drop_islands(occ: Bool[np.ndarray, "X Y Z"], min_voxels: int) -> tuple[Bool[np.ndarray, "X Y Z"], int]:
    """Remove 6-connected islands of fewer than ``min_voxels`` cells (floaters). Returns (the
    occupancy, the number of cells removed)."""
    if min_voxels <= 1 or not occ.any():
        return occ, 0
    lab, n = ndimage.label(occ)
    size = np.bincount(lab.reshape(-1), minlength=n + 1)
    small = size < min_voxels
    small[0] = False
    drop = small[lab]
    return occ & ~drop, int(drop.sum())


# ----------------------------------------------------------------------------------- merging


def merge_boxes(occ: Bool[np.ndarray, "X Y Z"], overlap: bool = True, fill_tol: float = 0.0
                ) -> Int[np.ndarray, "B 2 3"]:
    """Greedy boxes covering the occupied cells of ``occ`` [X, Y, Z]: from the first uncovered
    cell (x fastest, then y, then z), grow along x as far as cells are occupied, then along y
    while the next x-run is, then along z while the next rectangle is. ``overlap``: growth may
    pass over cells an earlier box covers (fewer, larger boxes); else boxes are disjoint.
    ``fill_tol``: a y-run or z-layer is taken when at most this fraction of its cells is free
    (0: the boxes cover exactly the occupied cells; > 0 smooths a ragged surface into fewer
    boxes that also cover some free cells). Returns [B, 2, 3] int: (lo (i, j, k), hi exclusive)
    per box. The loop runs over boxes; each growth step is a numpy reduction."""
    if not 0.0 <= fill_tol < 1.0:
        raise ValueError(f"merge_boxes: fill_tol = {fill_tol} must be in [0, 1)")
    a = np.ascontiguousarray(np.transpose(np.asarray(occ, bool), (2, 1, 0)))  # [Z, Y, X]: x fastest
    free = a.copy()
    grow = a if overlap else free
    _, Yn, Xn = a.shape
    need = 1.0 - fill_tol - 1e-12

    def run(frac: np.ndarray) -> int:  # length of the leading run of layers full enough
        bad = frac < need
        return len(frac) if not bad.any() else int(np.argmax(bad))

    flat = free.reshape(-1)  # a view: covering cells updates it
    cand = np.flatnonzero(flat)
    out: list[tuple[int, int, int, int, int, int]] = []
    p = 0
    while p < len(cand):
        blk = flat[cand[p:p + 4096]]
        if not blk.any():
            p += len(blk)
            continue
        p += int(np.argmax(blk))
        s = int(cand[p])
        z, rem = divmod(s, Yn * Xn)
        y, x = divmod(rem, Xn)
        row = grow[z, y, x:]
        x1 = x + (len(row) if row.all() else int(np.argmin(row)))
        y1 = y + run(grow[z, y:, x:x1].mean(axis=1))
        z1 = z + run(grow[z:, y:y1, x:x1].mean(axis=(1, 2)))
        free[z:z1, y:y1, x:x1] = False
        out.append((x, y, z, x1, y1, z1))
    return np.array(out, np.int64).reshape(-1, 2, 3)


def boxes_to_shapes(boxes: Int[np.ndarray, "B 2 3"], grid: VoxelGrid) -> list[Shape]:
    """Box ``Shape``s (world frame, the grid's rotation) of cell boxes [B, 2, 3] (lo, hi excl.)."""
    lo = grid.origin + boxes[:, 0] * grid.cell  # [B, 3] grid coordinates
    hi = grid.origin + boxes[:, 1] * grid.cell
    centers = ((lo + hi) / 2) @ grid.rotation.T
    halves = (hi - lo) / 2
    return [box_shape(c, h, grid.rotation) for c, h in zip(centers, halves)]


def surface_skins(mesh: trimesh.Trimesh, rotation: Float[np.ndarray, "3 3"], carvers: Sequence, cell: float = 0.02,
                  thickness: float = 0.01, up_cos: float = 0.95, step: float = 0.01, min_points: int = 2,
                  clearance: float = 0.005, seed: int = 0) -> list[Shape]:
    """Thin boxes under the mesh's up-facing surfaces (a counter, a floor, a cabinet's top),
    outside every carver: the cells carving empties around a cavity or a swept volume take the
    counter above them with them (a counter is one 4 cm cell thick), so an object set on it
    would sink to the cavity's top. Points are sampled on the faces whose normal has z >=
    ``up_cos`` (~12 per ``cell``^2), binned in ``cell`` squares of the grid's frame
    (``rotation``: its columns are the frame's axes); a bin with ``min_points`` is a skin at its
    highest point's height, rounded to ``step``, when no corner or mid-point of its box (the
    cell, ``thickness`` deep) lies within ``clearance`` of a carver; bins of one height merge
    into rectangles (greedy)."""
    up = np.flatnonzero(np.asarray(mesh.face_normals)[:, 2] >= up_cos)
    if len(up) == 0:
        return []
    sub = mesh.submesh([up], append=True)
    n = int(min(3_000_000, max(100, 12 * sub.area / cell ** 2)))
    pts, _ = trimesh.sample.sample_surface(sub, n, seed=seed)
    local = pts @ rotation  # grid frame (rotation about z: heights unchanged)
    ij = np.floor(local[:, :2] / cell).astype(np.int64)
    lo = ij.min(0)
    ij -= lo
    key = ij[:, 0] * (ij[:, 1].max() + 1) + ij[:, 1]
    order = np.argsort(key, kind="stable")
    keys, start, counts = np.unique(key[order], return_index=True, return_counts=True)
    z = local[order, 2]
    top = np.maximum.reduceat(z, start)  # the highest surface in each bin: what an object rests on
    ok = counts >= min_points
    bi = ij[order][start]
    h = np.round(top / step) * step
    carvers = [as_carver(c) for c in carvers]
    centre = np.column_stack([(bi + lo + 0.5) * cell, h])  # [B, 3] grid frame
    for dx, dy, dz in itertools.product((-0.5, 0.0, 0.5), (-0.5, 0.0, 0.5), (0.0, -1.0)):  # the cell's box
        P = (centre + [dx * cell, dy * cell, dz * thickness]) @ rotation.T
        for c in carvers:
            blo, bhi = c.bounds(clearance)
            near = np.flatnonzero(np.all((P >= blo) & (P <= bhi), axis=1) & ok)
            if len(near):
                ok[near[c.contains(P[near], clearance)]] = False
    out: list[Shape] = []
    nx, ny = int(bi[:, 0].max()) + 1, int(bi[:, 1].max()) + 1
    for level in np.unique(h[ok]):  # loop over height levels
        occ = np.zeros((nx, ny, 1), bool)
        sel = ok & (h == level)
        occ[bi[sel, 0], bi[sel, 1], 0] = True
        for b in merge_boxes(occ, overlap=False):
            (x0, y0, _), (x1, y1, _) = b
            c = np.array([(x0 + x1) / 2 + lo[0], (y0 + y1) / 2 + lo[1], 0.0]) * cell
            c[2] = level - thickness / 2
            out.append(box_shape(c @ rotation.T, [(x1 - x0) * cell / 2, (y1 - y0) * cell / 2, thickness / 2], rotation))
    return out


# ------------------------------------------------------------------------------------ the step


@dataclass(eq=False)
class StaticCollision:
    """The static scene's collision ``shapes`` (boxes), the carved ``grid`` they cover exactly,
    ``boxes`` [B, 2, 3] cell boxes, ``yaw`` (rad) and counts / timings in ``stats``."""

    shapes: list[Shape]
    grid: VoxelGrid
    boxes: np.ndarray
    yaw: float
    stats: dict


def static_collision(mesh: trimesh.Trimesh, cfg: StaticCollisionConfig, field=None, carvers: Sequence = (),
                     exact_carvers: Sequence = ()) -> StaticCollision:
    """Boxes for the static scene. ``mesh``: the static visual mesh (world, m; its extent bounds
    the grid and its faces give the yaw); ``field``: a :class:`~drawer_lib.sdf.io.LoadedField`
    (``.sdf``, ``.lo``, ``.hi``), needed for ``source: field``; ``carvers``: swept volumes and
    cavities to empty (see :func:`carve`), grown by ``carve_inflate`` cells; ``exact_carvers``
    the same, not grown. Raises :class:`InputError` when ``source: field`` has
    no field (set ``complete.static.source: mesh`` for captures without one)."""
    t0 = time.perf_counter()
    if len(mesh.faces) == 0:
        raise InputError("static_collision: the static mesh has no faces")
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError("static_collision: the static mesh has non-finite vertices")
    yaw = dominant_yaw(mesh, cfg) if cfg.align else 0.0
    t1 = time.perf_counter()
    if cfg.source == "field":
        if field is None:
            raise InputError("static_collision: complete.static.source = field needs the sdf stage's field "
                             "(none given); use source: mesh for a capture without a field")
        grid = occupancy_from_field(field.sdf, np.asarray(field.lo), np.asarray(field.hi), mesh, cfg, yaw)
    else:
        grid = occupancy_from_mesh(mesh, cfg, yaw)
    t2 = time.perf_counter()
    n_occ = int(grid.occ.sum())
    n_far = 0
    if cfg.shell_depth > 0:
        grid, n_far = near_surface(grid, mesh, cfg.shell_depth)
    grid, n_carved = carve(grid, list(carvers), cfg.carve_inflate * cfg.cell)
    if exact_carvers:  # volumes emptied cell centre by cell centre, not grown (a rigid object above its support)
        grid, n_exact = carve(grid, list(exact_carvers), 0.0)
        n_carved += n_exact
    occ, n_islands = drop_islands(grid.occ, cfg.min_island_voxels)
    grid = grid.with_occ(occ)
    t3 = time.perf_counter()
    boxes = merge_boxes(grid.occ, cfg.overlap, cfg.fill_tol)
    shapes = boxes_to_shapes(boxes, grid)
    skins = surface_skins(mesh, grid.rotation, list(carvers) + list(exact_carvers), cfg.skin_cell,
                          cfg.skin_thickness, cfg.skin_up_cos) if cfg.skins else []
    shapes += skins
    t4 = time.perf_counter()
    stats = {"source": cfg.source, "yaw_deg": round(math.degrees(yaw), 3), "cell_m": cfg.cell,
             "grid_shape": list(grid.occ.shape), "n_occupied": n_occ, "n_far": n_far, "n_carved": n_carved,
             "n_island_cells": n_islands, "n_cells": int(grid.occ.sum()), "n_boxes": len(shapes) - len(skins),
             "n_skins": len(skins),
             "time_yaw_s": round(t1 - t0, 3), "time_occupancy_s": round(t2 - t1, 3),
             "time_carve_s": round(t3 - t2, 3), "time_merge_s": round(t4 - t3, 3),
             "wall_s": round(time.perf_counter() - t0, 3)}
    return StaticCollision(shapes, grid, boxes, yaw, stats)


# ------------------------------------------------------------------------------------ fidelity


def union_mesh(shapes: Sequence[Shape]) -> trimesh.Trimesh:
    """The boundary of the union of the shapes' solids (boxes; meshes as their convex hulls) as
    one closed mesh (manifold3d boolean union): shared and inner faces are gone. A solid that
    encloses no volume (the hull of points on one plane) joins as its surface, unmerged."""
    if not shapes:
        raise InputError("union_mesh: no shapes")
    solids = [trimesh.Trimesh(*s.solid(), process=False) for s in shapes]
    vol = [m for m in solids if m.is_volume]
    flat = [m for m in solids if not m.is_volume]
    if len(vol) > 1:
        vol = [trimesh.boolean.union(vol, engine="manifold")]
    parts = vol + flat
    return parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)


def collision_fidelity(shapes: Sequence[Shape], mesh: trimesh.Trimesh, n_points: int = 20_000, seed: int = 0,
                       free: Callable | None = None, probe: float = 0.01) -> dict:
    """How well collision ``shapes`` reproduce a visual ``mesh`` (world, m): Chamfer-L1 (mean of
    both directions, m) between ``n_points`` area samples on the surface of the shapes' union
    (faces shared between adjacent shapes excluded) and on the mesh, each measured to the other
    *surface* (exact point-to-triangle distance, as the geometry metrics); ``accuracy`` shapes -> mesh,
    ``completeness`` mesh -> shapes (m); F-scores at 1 and 2 cm; ``n_shapes``; ``wall_s``.

    ``free``: optional points [N, 3] -> bool [N], True in free space (e.g. where an SDF is positive);
    then the union samples whose point ``probe`` (m) outside along their normal is free are the
    *exposed* collision surface (what can be touched), the others its hidden back, and
    ``accuracy_exposed``, ``chamfer_l1_exposed`` and ``exposed_fraction`` are added."""
    from drawer_lib.metrics.geometry import SurfaceDistance, sample_surface

    t0 = time.perf_counter()
    if len(mesh.faces) == 0:
        raise InputError("collision_fidelity: the visual mesh has no faces")
    u = union_mesh(shapes)
    su = sample_surface(u, n_points, seed)
    pu = su.points  # [n, 3]
    pm = sample_surface(mesh, n_points, seed + 1).points  # [n, 3]
    d_acc, _ = SurfaceDistance(mesh)(pu)
    d_comp, _ = SurfaceDistance(u)(pm)
    out = {"chamfer_l1": float((d_acc.mean() + d_comp.mean()) / 2), "accuracy": float(d_acc.mean()),
           "completeness": float(d_comp.mean()), "n_shapes": len(shapes), "union_area_m2": float(u.area),
           "mesh_area_m2": float(mesh.area)}
    for key, tau in (("fscore_1cm", 0.01), ("fscore_2cm", 0.02)):
        p, r = float((d_acc < tau).mean()), float((d_comp < tau).mean())
        out[key] = 0.0 if p + r == 0 else 2 * p * r / (p + r)
    if free is not None:
        exposed = np.asarray(free(pu + probe * su.normals), bool)
        out["exposed_fraction"] = float(exposed.mean())
        if exposed.any():
            out["accuracy_exposed"] = float(d_acc[exposed].mean())
            out["chamfer_l1_exposed"] = float((d_acc[exposed].mean() + d_comp.mean()) / 2)
    out["wall_s"] = time.perf_counter() - t0
    return out
