"""Marching cubes of an SDF over a box, restricted to where train cameras saw.

The SDF is evaluated on a coarse grid first and only near its zero level set on the fine grid
(elsewhere the upsampled coarse values keep the right sign), so extraction costs scale with the
surface, not the volume.
"""

from collections.abc import Callable

import numpy as np
import torch
import torch.nn.functional as F
import trimesh
from skimage.measure import marching_cubes

from drawer_lib.errors import InputError, NonFiniteError
from drawer_lib.geometry.camera import Intrinsics

SdfFn = Callable[[torch.Tensor], torch.Tensor]  # [N, 3] -> [N], no gradient


def grid_shape(lo: np.ndarray, hi: np.ndarray, cell: float) -> tuple[int, int, int]:
    return tuple(int(n) for n in np.ceil((np.asarray(hi) - np.asarray(lo)) / cell).astype(int) + 1)


def grid_points(lo: np.ndarray, shape: tuple[int, int, int], cell: float) -> torch.Tensor:
    axes = [torch.tensor(lo[a] + cell * np.arange(shape[a]), dtype=torch.float32) for a in range(3)]
    return torch.stack(torch.meshgrid(*axes, indexing="ij"), -1)


@torch.no_grad()
def evaluate(sdf_fn: SdfFn, pts: torch.Tensor, chunk: int = 1 << 16) -> torch.Tensor:
    flat = pts.reshape(-1, 3)
    out = torch.cat([sdf_fn(c) for c in flat.split(chunk)]) if len(flat) else torch.zeros(0)
    if not torch.all(torch.isfinite(out)):
        raise NonFiniteError("SDF evaluation produced non-finite values")
    return out.reshape(pts.shape[:-1])


def refine_levels(coarse_factor: int) -> list[int]:
    """Cell multiples of the coarse-to-fine levels of :func:`sdf_grid`: ``coarse_factor`` halved
    while it stays even, then 1 (4 -> [4, 2, 1], 8 -> [8, 4, 2, 1], 6 -> [6, 3, 1], 5 -> [5, 1])."""
    f, levels = int(coarse_factor), [int(coarse_factor)]
    while f > 1:
        f = f // 2 if f % 2 == 0 else 1
        levels.append(f)
    return levels


def _upsample(values: torch.Tensor, factor: int, shape: tuple[int, int, int]) -> torch.Tensor:
    """Trilinear values at the vertices of a grid ``factor`` times finer than ``values``' and
    aligned at its first vertex (fine vertex k sits at coarse coordinate k / factor), cropped or
    edge-padded to ``shape``."""
    up = F.interpolate(values[None, None], size=tuple((np.array(values.shape) - 1) * factor + 1), mode="trilinear",
                       align_corners=True)[0, 0]
    up = up[: shape[0], : shape[1], : shape[2]]
    pad = [max(shape[a] - up.shape[a], 0) for a in range(3)]
    if any(pad):
        up = F.pad(up[None, None], (0, pad[2], 0, pad[1], 0, pad[0]), mode="replicate")[0, 0]
    return up


@torch.no_grad()
def sdf_grid(sdf_fn: SdfFn, lo: np.ndarray, hi: np.ndarray, cell: float, coarse_factor: int = 4) -> np.ndarray:
    """SDF values [X, Y, Z] on the grid of cell ``cell`` from ``lo`` (covering ``hi``).

    Coarse to fine: the SDF is evaluated everywhere on a grid of cell ``coarse_factor * cell``,
    then level by level (cell halved, :func:`refine_levels`) the previous level's values are
    upsampled trilinearly and evaluated exactly where they lie within two of the previous
    level's cells of the zero level set. So the result is exact within two cells of the zero
    level set (and within 2 * 2^k cells where k levels up were exact), and upsampled values of a
    coarser level elsewhere, which keep the sign of the field away from the surface. The
    evaluations scale with the surface area, not the volume of the box."""
    shape = grid_shape(lo, hi, cell)
    levels = refine_levels(coarse_factor)
    c0 = cell * levels[0]
    vals = evaluate(sdf_fn, grid_points(lo, grid_shape(lo, hi, c0), c0))
    for prev, f in zip(levels, levels[1:]):
        lshape = shape if f == 1 else grid_shape(lo, hi, cell * f)
        up = _upsample(vals, prev // f, lshape)
        near = up.abs() < 2.0 * cell * prev
        idx = near.nonzero()  # only these vertices are evaluated; no full grid of points is built
        pts = torch.tensor(lo, dtype=torch.float32) + (cell * f) * idx.to(torch.float32)
        vals = up
        vals[near] = evaluate(sdf_fn, pts)
    return vals.numpy()


def frustum_mask(lo: np.ndarray, shape: tuple[int, int, int], cell: float, intr: Intrinsics, w2c: np.ndarray,
                 near: float = 0.05, chunk: int = 1 << 20, where: np.ndarray | None = None) -> np.ndarray:
    """Vertices inside the view frustum (in front of the camera, within the image) of at least one
    of the cameras ``w2c`` [C, 4, 4]; with ``where`` (bool ``shape``) only those vertices are
    tested (the others are False). Computed in float32 chunks of vertices (memory stays
    bounded for large grids)."""
    axes = [torch.tensor(lo[a] + cell * np.arange(shape[a]), dtype=torch.float32) for a in range(3)]
    T = torch.tensor(np.asarray(w2c), dtype=torch.float32)  # [C, 4, 4]
    seen = torch.zeros(shape, dtype=torch.bool)
    flat = seen.view(-1)
    todo = (torch.arange(int(np.prod(shape))) if where is None
            else torch.from_numpy(np.flatnonzero(np.asarray(where, bool).reshape(-1))))
    YZ = shape[1] * shape[2]
    for s0 in range(0, len(todo), chunk):
        k = todo[s0 : s0 + chunk]
        p = torch.stack([axes[0][k // YZ], axes[1][(k // shape[2]) % shape[1]], axes[2][k % shape[2]]], -1)
        ok = torch.zeros(len(k), dtype=torch.bool)
        for Tc in T:
            pc = p @ Tc[:3, :3].T + Tc[:3, 3]
            z = pc[:, 2]
            zs = torch.where(z > near, z, torch.ones_like(z))
            u = intr.fx * pc[:, 0] / zs + intr.cx
            v = intr.fy * pc[:, 1] / zs + intr.cy
            ok |= (z > near) & (u >= 0) & (u <= intr.width) & (v >= 0) & (v <= intr.height)
        flat[k] = ok
    return seen.numpy()


def seen_crossing_mask(values: np.ndarray, lo: np.ndarray, cell: float, intr: Intrinsics, w2c: np.ndarray,
                       level: float = 0.0, near: float = 0.05) -> np.ndarray:
    """Marching-cubes mask of the cubes of ``values`` that straddle ``level`` and whose highest
    corner lies in a camera's frustum: the same mesh as the plain frustum mask, with the frustum
    tested only at crossing cubes (a full grid holds ~10^7 vertices, each tested against every
    camera otherwise). All False when nothing crosses or nothing crossing is seen."""
    crossing = crossing_cubes(values, level)
    if not crossing.any():
        return crossing
    return frustum_mask(lo, crossing.shape, cell, intr, w2c, near, where=crossing)


def marching_cubes_mesh(values: np.ndarray, lo: np.ndarray, cell: float, level: float = 0.0,
                        mask: np.ndarray | None = None) -> trimesh.Trimesh:
    """Zero-level-set (``level``) mesh of an SDF grid, outward normals (towards positive SDF).
    An empty mesh when the level set does not cross the (masked) grid."""
    v = np.asarray(values, np.float32)
    if not np.all(np.isfinite(v)):
        raise NonFiniteError("marching_cubes_mesh: non-finite SDF values")
    if mask is not None and not mask.any():
        return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), process=False)
    if not (v.min() < level < v.max()):
        return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), process=False)
    try:
        verts, faces, _, _ = marching_cubes(v, level, spacing=(cell, cell, cell), mask=mask, allow_degenerate=False)
    except RuntimeError as e:  # the level set crosses the grid, but no masked cube
        if "No surface found" not in str(e):
            raise
        return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), process=False)
    # skimage's winding already makes face normals point towards increasing values (s > 0)
    return trimesh.Trimesh(verts + np.asarray(lo), faces, process=False)


# scikit-image's Lewiner marching cubes reads its ``mask`` at a cube's *highest* corner: the cube
# spanning vertices [i, i+1] x [j, j+1] x [k, k+1] is computed when mask[i+1, j+1, k+1] (checked
# in tests/mesh against single-cube volumes). Cube masks below use that indexing.


def _cube_corners(v: np.ndarray):
    """The 8 corner views [X-1, Y-1, Z-1] of the cubes of a vertex grid [X, Y, Z]."""
    X, Y, Z = (n - 1 for n in v.shape)
    return [v[dx : dx + X, dy : dy + Y, dz : dz + Z] for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)]


def crossing_cubes(values: np.ndarray, level: float = 0.0) -> np.ndarray:
    """Marching-cubes mask (bool, shape of ``values``; a cube at its highest corner) of the cubes
    whose 8 corner values straddle ``level`` (min <= level <= max): the only cubes that can
    produce a triangle, so restricting any other mask to them leaves the mesh unchanged."""
    v = np.asarray(values, np.float32)
    out = np.zeros(v.shape, bool)
    if min(v.shape) < 2:
        return out
    first, *rest = _cube_corners(v)
    lo, hi = first.copy(), first.copy()
    for c in rest:
        np.minimum(lo, c, out=lo)
        np.maximum(hi, c, out=hi)
    out[1:, 1:, 1:] = (lo <= level) & (hi >= level)
    return out


def cube_mask(vertex_ok: np.ndarray) -> np.ndarray:
    """Marching-cubes mask (a cube at its highest corner) that keeps the cubes whose 8 corners
    are all ``vertex_ok`` [X, Y, Z]."""
    ok = np.asarray(vertex_ok, bool)
    out = np.zeros_like(ok)
    if min(ok.shape) < 2:
        return out
    first, *rest = _cube_corners(ok)
    c = first.copy()
    for r in rest:
        c &= r
    out[1:, 1:, 1:] = c
    return out


def grid_field_mesh(grid, intr: Intrinsics, w2c: np.ndarray, level: float = 0.0, near: float = 0.05) -> trimesh.Trimesh:
    """Mesh of a :class:`~drawer_lib.sdf.io.GridSDF` on its own voxel grid: only cubes whose 8
    corners were observed and that lie in a train frustum (an unobserved corner would otherwise
    put a false surface at the back of the truncation band). Raises ValueError when no cube is
    both observed and seen."""
    obs = grid.observed()
    values = np.where(obs, grid.values, grid.unknown)
    # all three masks index a cube by its highest corner; the frustum is tested only where an
    # observed cube straddles the level (the only cubes with triangles): the same mesh for far
    # fewer projections
    cubes = cube_mask(obs) & crossing_cubes(values, level)
    mask = cubes & frustum_mask(grid.lo, obs.shape, grid.cell, intr, w2c, near, where=cubes)
    if not mask.any():
        raise InputError("grid_field_mesh: no observed cube that the level set crosses lies in a train camera's view")
    return marching_cubes_mesh(values, grid.lo, grid.cell, level, mask)
