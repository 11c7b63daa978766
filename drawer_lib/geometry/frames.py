"""World up and in-plane frames of planes (numpy)."""

import numpy as np
from jaxtyping import Float

UP = np.array([0.0, 0.0, 1.0])  # world up (+z; docs/formats.md#conventions)


def plane_axes(n: Float[np.ndarray, "3"]) -> tuple[Float[np.ndarray, "3"], Float[np.ndarray, "3"]]:
    """In-plane unit axes (u, v) of a plane with unit normal ``n``: u horizontal (UP x n; world
    x-ish for a horizontal plane), v = n x u (up the plane).

    >>> u, v = plane_axes(np.array([0.0, -1.0, 0.0]))
    >>> (u + 0.0).tolist(), (v + 0.0).tolist()
    ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    """
    u = np.cross(UP, n)
    if np.linalg.norm(u) < 1e-6:  # a horizontal plane: u along world x
        u = np.cross(np.array([0.0, 1.0, 0.0]), n)
    u = u / np.linalg.norm(u)
    return u, np.cross(n, u)
