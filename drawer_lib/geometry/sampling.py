"""Area-uniform sampling of triangle surfaces (numpy)."""

import numpy as np
from jaxtyping import Float, Int

from drawer_lib.errors import InputError


def triangle_areas(tri: Float[np.ndarray, "F 3 3"]) -> Float[np.ndarray, "F"]:
    """Areas (m^2) of triangles given by their corners; 0 for degenerate ones."""
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=-1)


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
