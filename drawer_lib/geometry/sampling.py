"""Area-uniform sampling of triangle surfaces (numpy)."""

import numpy as np
from jaxtyping import Float, Int

from drawer_lib.errors import InputError


def triangle_areas(tri: Float[np.ndarray, "F 3 3"]) -> Float[np.ndarray, "F"]:
    """Areas (m^2) of triangles given by their corners; 0 for degenerate ones."""
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=-1)


R2_STEP = (0.7548776662466927, 0.5698402909980532)  # 1/g, 1/g^2, g the plastic number (Roberts' R2 sequence)


def local_triangle_points(tri: Float[np.ndarray, "F 3 3"], density: float,
                          areas: Float[np.ndarray, "F"] | None = None
                          ) -> tuple[Float[np.ndarray, "n 3"], Int[np.ndarray, "n"]]:
    """Points on each triangle that depend on that triangle alone: round(area x ``density``)
    points (per m^2) at the first terms of Roberts' R2 low-discrepancy sequence (u_j, v_j) =
    frac(0.5 + j (1/g, 1/g^2)), j = 1, 2, ..., folded into the triangle (u + v > 1 -> 1 - u,
    1 - v). Unlike :func:`sample_triangles`, changing one triangle of a mesh (another
    simplification of the same surface) changes that triangle's points only, not every
    point's draw. Returns (points [n, 3], index of each point's triangle [n]).

    >>> tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 0, 1], [0, 1, 1]]], float)
    >>> p, f = local_triangle_points(tri, 6.0)
    >>> f.tolist(), bool(np.all(p[:, 0] + p[:, 1] <= 1))
    ([0, 0, 0, 1, 1, 1], True)
    """
    if not (np.isfinite(density) and density >= 0):
        raise ValueError(f"local_triangle_points: density = {density} must be finite and >= 0")
    tri = np.asarray(tri, np.float64)
    area = triangle_areas(tri) if areas is None else np.asarray(areas, np.float64)
    n = np.floor(np.where(np.isfinite(area), area, 0.0) * density + 0.5).astype(np.int64)
    k = np.repeat(np.arange(len(tri)), n)
    if not len(k):
        return np.zeros((0, 3)), k
    j = np.arange(len(k)) - np.repeat(np.cumsum(n) - n, n) + 1  # 1.. n_f within each triangle
    u, v = (0.5 + j * R2_STEP[0]) % 1.0, (0.5 + j * R2_STEP[1]) % 1.0
    fold = u + v > 1
    u, v = np.where(fold, 1 - u, u), np.where(fold, 1 - v, v)
    t = tri[k]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0]), k


def sample_triangles(tri: Float[np.ndarray, "F 3 3"], n: int, rng: np.random.Generator,
                     areas: Float[np.ndarray, "F"] | None = None
                     ) -> tuple[Float[np.ndarray, "n 3"], Int[np.ndarray, "n"]]:
    """``n`` points uniform over the union of the triangles (a triangle is drawn with
    probability proportional to its area, zero-area ones never; the point is uniform inside it:
    barycentrics (1 - sqrt r1, sqrt r1 (1 - r2), sqrt r1 r2), Osada et al. 2002). Returns
    (points [n, 3], index of each point's triangle [n]). ``areas`` [F] saves recomputing them.

    >>> tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)
    >>> p, f = sample_triangles(tri, 4, np.random.default_rng(0))
    >>> bool(np.all(p[:, 0] + p[:, 1] <= 1)), f.tolist()
    (True, [0, 0, 0, 0])
    """
    area = triangle_areas(tri) if areas is None else np.asarray(areas, np.float64)
    total = float(area.sum())
    if len(tri) == 0 or not np.isfinite(total) or total <= 0:
        raise InputError(f"sample_triangles: the {len(tri)} triangles have no area to sample")
    k = rng.choice(len(tri), n, p=area / total)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    b = np.stack([1 - s, s * (1 - r2), s * r2], -1)
    return (b[:, :, None] * tri[k]).sum(1), k
