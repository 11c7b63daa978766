"""Rigid motion of a part about its joint (pure numpy).

A revolute joint rotates by q (rad) about the line through ``origin`` along the unit
``direction`` (right-hand rule); a prismatic joint translates by q (m) along ``direction``.
Directions are oriented so that positive q opens a part (as in ``drawer.parts/1``).
"""

import numpy as np
from jaxtyping import Float

from drawer_lib.geometry.rotations import axis_angle_to_matrix


def joint_transform(kind: str, origin: Float[np.ndarray, "3"], direction: Float[np.ndarray, "3"],
                    q: float) -> Float[np.ndarray, "4 4"]:
    """4x4 world transform that moves a part from its closed pose to joint value ``q``.

    >>> import numpy as np
    >>> T = joint_transform("prismatic", np.zeros(3), np.array([0, -1.0, 0]), 0.3)
    >>> T[:3, 3].round(3).tolist()
    [0.0, -0.3, 0.0]
    """
    d = np.asarray(direction, np.float64)
    n = np.linalg.norm(d)
    if n < 1e-12:
        raise ValueError("joint_transform: zero-length axis direction")
    d = d / n
    T = np.eye(4)
    if kind == "prismatic":
        T[:3, 3] = q * d
    elif kind == "revolute":
        R = axis_angle_to_matrix(d, q)
        o = np.asarray(origin, np.float64)
        T[:3, :3] = R
        T[:3, 3] = o - R @ o
    else:
        raise ValueError(f"joint_transform: kind {kind!r} is not revolute or prismatic")
    return T


def apply_transform(T: Float[np.ndarray, "4 4"], points: Float[np.ndarray, "N 3"]) -> Float[np.ndarray, "N 3"]:
    return points @ T[:3, :3].T + T[:3, 3]
