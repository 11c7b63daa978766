"""Area-uniform sampling of triangle surfaces (numpy)."""

import numpy as np
from jaxtyping import Float, Int

from drawer_lib.errors import InputError


def triangle_areas(tri: Float[np.ndarray, "F 3 3"]) -> Float[np.ndarray, "F"]:
    """Areas (m^2) of triangles given by their corners; 0 for degenerate ones."""
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=-1)


R2_STEP = (0.7548776662466927, 0.5698402909980532)  # 1/g, 1/g^2, g the plastic number (Roberts' R2 sequence)
# three directions for a face's own phases (the fractional parts of sqrt of primes: irrational,
# so the phases of faces on any lattice spread evenly over [0, 1) -- Weyl's equidistribution)
_PHASE_DIRS = np.sqrt(np.array([[2.0, 3, 5], [7, 11, 13], [17, 19, 23]])) % 1.0
PHASE_M = 0.01  # length (m) over which a face's phases run through [0, 1) once along each direction


def face_phases(centroids: Float[np.ndarray, "F 3"]) -> Float[np.ndarray, "F 3"]:
    """Three numbers in [0, 1) per face, continuous in its centroid (m): frac(c . a_k / ``PHASE_M``)
    for three fixed irrational directions a_k. Moving a face by 1e-7 m moves them by about
    1e-5; faces a centimetre apart get unrelated ones."""
    return (np.asarray(centroids, np.float64) @ _PHASE_DIRS.T / PHASE_M) % 1.0


def local_triangle_points(tri: Float[np.ndarray, "F 3 3"], density: float,
                          areas: Float[np.ndarray, "F"] | None = None
                          ) -> tuple[Float[np.ndarray, "n 3"], Int[np.ndarray, "n"]]:
    """Points on each triangle that depend on that triangle alone, ``density`` per m^2 in
    expectation. A triangle's three phases (:func:`face_phases` of its centroid) (d, pu, pv)
    set its count, floor(area x ``density`` + d) (a randomised rounding: over many faces each
    keeps its share of the points, a face of a fifth of a point gets one a fifth of the time),
    and where they lie: the terms (u_j, v_j) = frac((pu, pv) + j (1/g, 1/g^2)), j = 0, 1, ...
    of Roberts' R2 low-discrepancy sequence, folded into the triangle (u + v > 1 -> 1 - u,
    1 - v). Unlike :func:`sample_triangles`, changing one triangle of a mesh (another
    simplification of the same surface) changes that triangle's points only, not every point's
    draw, and a triangle moved by float round-off keeps its count (but within ~1e-5 of a step)
    and moves its points by as little. Returns (points [n, 3], index of each point's triangle [n]).

    >>> tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 0, 1], [0, 1, 1]]], float)
    >>> p, f = local_triangle_points(tri, 6.0)
    >>> f.tolist(), bool(np.all(p[:, 0] + p[:, 1] <= 1))
    ([0, 0, 0, 1, 1, 1], True)
    """
    if not (np.isfinite(density) and density >= 0):
        raise ValueError(f"local_triangle_points: density = {density} must be finite and >= 0")
    tri = np.asarray(tri, np.float64)
    area = triangle_areas(tri) if areas is None else np.asarray(areas, np.float64)
    cen = tri.mean(1)
    ok = np.isfinite(area) & np.all(np.isfinite(cen), axis=1) & (area > 0)
    ph = face_phases(np.where(ok[:, None], cen, 0.0))
    n = np.floor(np.where(ok, area, 0.0) * density + ph[:, 0]).astype(np.int64)  # a bad face's phase is 0: none
    k = np.repeat(np.arange(len(tri)), n)
    if not len(k):
        return np.zeros((0, 3)), k
    j = np.arange(len(k)) - np.repeat(np.cumsum(n) - n, n)  # 0.. n_f - 1 within each triangle
    u, v = (ph[k, 1] + j * R2_STEP[0]) % 1.0, (ph[k, 2] + j * R2_STEP[1]) % 1.0
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
