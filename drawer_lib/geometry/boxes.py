"""Oriented boxes: the one box type of the pipeline (a part's solid, an interior's walls and
cavity, a static collision box, a piece of a swept volume), the tests on them, and the frame of
a front that the boxes behind it are laid out in.

A box is ``center`` [3] (m), ``rotation`` [3, 3] (columns = the box axes in the world, a proper
rotation) and ``half`` [3] (half extents along those axes, m). A front's frame has the columns
(u, v = normal x u, normal): u along the front, v up it, the normal out of it.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from jaxtyping import Bool, Float, Int
from scipy.spatial import ConvexHull, QhullError

_CHUNK = 2_000_000  # point-box tests per vectorised block
# unit box [-1, 1]^3: corners (bit 0 -> x, bit 1 -> y, bit 2 -> z) and 12 outward triangles
_CORNERS = np.array([[(i & 1) * 2 - 1, (i >> 1 & 1) * 2 - 1, (i >> 2 & 1) * 2 - 1] for i in range(8)], np.float64)
_TRIANGLES = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                       [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], np.int64)
_TRIPLES = np.array([(i, j, k) for i in range(12) for j in range(i + 1, 12) for k in range(j + 1, 12)])


def _frozen(a, shape: tuple[int, ...], name: str) -> np.ndarray:
    out = np.array(a, dtype=np.float64)
    if out.shape != shape:
        raise ValueError(f"OrientedBox.{name}: shape {out.shape}, expected {shape}")
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class OrientedBox:
    """A box (see the module doc); the arrays are stored as read-only float64 copies. Values are
    not checked here (a zero half extent is a flat box); :meth:`drawer_lib.bodies.TwinModel.validate`
    checks collision boxes and names their body."""

    center: Float[np.ndarray, "3"]
    rotation: Float[np.ndarray, "3 3"]
    half: Float[np.ndarray, "3"]

    def __post_init__(self):
        for name, shape in (("center", (3,)), ("rotation", (3, 3)), ("half", (3,))):
            object.__setattr__(self, name, _frozen(getattr(self, name), shape, name))

    def __repr__(self) -> str:
        return f"OrientedBox(center={np.round(self.center, 4).tolist()}, half={np.round(self.half, 4).tolist()})"

    @property
    def volume(self) -> float:
        """m^3."""
        return float(8.0 * np.prod(self.half))

    def corners(self) -> Float[np.ndarray, "8 3"]:
        """The 8 corners [8, 3] (m), corner i at the signs (bit 0: x, bit 1: y, bit 2: z)."""
        return self.center + (_CORNERS * self.half) @ self.rotation.T

    def triangles(self) -> tuple[Float[np.ndarray, "8 3"], Int[np.ndarray, "12 3"]]:
        """The surface as 12 outward triangles: (vertices [8, 3] = :meth:`corners`, faces [12, 3])."""
        return _CORNERS * self.half @ self.rotation.T + self.center, _TRIANGLES

    def bounds(self, inflate: float = 0.0) -> tuple[Float[np.ndarray, "3"], Float[np.ndarray, "3"]]:
        """World axis-aligned bounds (lo [3], hi [3]) of the box grown by ``inflate`` (m)."""
        ext = np.abs(self.rotation) @ (self.half + inflate)
        return self.center - ext, self.center + ext

    def contains(self, points: Float[np.ndarray, "N 3"], inflate: float = 0.0) -> Bool[np.ndarray, "N"]:
        """Whether each point [N, 3] lies in the box grown by ``inflate`` (m) on every side
        (boundary included)."""
        local = (np.asarray(points, np.float64) - self.center) @ self.rotation  # [N, 3]
        return np.all(np.abs(local) <= self.half + inflate, axis=1)

    def halfspaces(self) -> tuple[Float[np.ndarray, "6 3"], Float[np.ndarray, "6"]]:
        """(A, b) with the box = {x : A x <= b}."""
        A = np.concatenate([self.rotation.T, -self.rotation.T])
        c = self.rotation.T @ self.center
        return A, np.concatenate([c + self.half, -c + self.half])

    def faces(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """The 6 faces as (centre [3], outward normal [3], in-plane axes [2, 3], in-plane half
        extents [2])."""
        R, h = self.rotation, self.half
        out = []
        for ax in range(3):
            a, b = [k for k in range(3) if k != ax]
            for s in (1.0, -1.0):
                n = s * R[:, ax]
                out.append((self.center + n * h[ax], n, np.stack([R[:, a], R[:, b]]), h[[a, b]]))
        return out

    def translated_hull(self, direction: Float[np.ndarray, "3"] | Sequence[float], lo: float, hi: float
                        ) -> "OrientedBox":
        """The box that holds this one translated by q * ``direction`` for every q in [lo, hi]
        (m): exactly the swept volume's hull, grown by |R^T d| (hi - lo) / 2 about its
        mid-travel centre."""
        d = np.asarray(direction, np.float64) / np.linalg.norm(direction)
        R = self.rotation
        return OrientedBox(self.center + d * (lo + hi) / 2, R, self.half + np.abs(R.T @ d) * (hi - lo) / 2)

    def to_json(self) -> dict:
        return {"center": self.center.tolist(), "rotation": self.rotation.tolist(), "half": self.half.tolist()}


def boxes_contain(points: Float[np.ndarray, "N 3"], centers: Float[np.ndarray, "K 3"],
                  rotations: Float[np.ndarray, "K 3 3"], half: Float[np.ndarray, "3"] | Float[np.ndarray, "K 3"]
                  ) -> Bool[np.ndarray, "N"]:
    """Whether each point [N, 3] lies in at least one of K oriented boxes (``centers`` [K, 3],
    ``rotations`` [K, 3, 3] columns = axes, half extents ``half`` [3] shared or [K, 3]).
    Vectorised over points and boxes in blocks; a point found inside is not tested again."""
    P = np.asarray(points, np.float64)
    out = np.zeros(len(P), bool)
    K = len(centers)
    if len(P) == 0 or K == 0:
        return out
    H = np.broadcast_to(np.asarray(half, np.float64), (K, 3))
    ext = np.einsum("kij,kj->ki", np.abs(rotations), H)  # [K, 3] world half extents of each box
    lo, hi = (centers - ext).min(0), (centers + ext).max(0)
    idx = np.flatnonzero(np.all((P >= lo) & (P <= hi), axis=1))  # candidates in the union's bounds
    off = np.einsum("kj,kjl->kl", centers, rotations)  # [K, 3] box centres in box coordinates
    k0 = 0
    while k0 < K and len(idx):
        step = max(1, _CHUNK // max(len(idx), 1))
        sl = slice(k0, min(K, k0 + step))
        local = np.einsum("nj,kjl->knl", P[idx], rotations[sl]) - off[sl, None, :]  # [k, n, 3]
        hit = np.all(np.abs(local) <= H[sl, None, :], axis=2).any(0)  # [n]
        out[idx[hit]] = True
        idx = idx[~hit]  # points found inside need no further test
        k0 = sl.stop
    return out


def separated(a: OrientedBox, b: OrientedBox) -> bool:
    """Separating-axis test of two boxes (15 axes): True when a plane separates them (touching
    boxes are separated)."""
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


def overlap_volume(a: OrientedBox, b: OrientedBox) -> float:
    """Volume (m^3) of the intersection of two oriented boxes: the vertices of the intersection
    polytope (every feasible intersection point of three of the 12 face planes) and their convex
    hull. 0 for disjoint, touching or flat intersections.

    >>> I = np.eye(3)
    >>> round(overlap_volume(OrientedBox(np.zeros(3), I, np.ones(3)), OrientedBox(np.array([1.0, 0, 0]), I, np.ones(3))), 6)
    4.0
    """
    if separated(a, b):
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


def front_frame(normal: Float[np.ndarray, "3"] | Sequence[float], u: Float[np.ndarray, "3"] | Sequence[float]
                ) -> Float[np.ndarray, "3 3"]:
    """[3, 3] rotation whose columns are a front's (u, v = normal x u, normal) axes, from its
    outward unit ``normal`` and in-plane unit ``u`` (:class:`drawer_lib.io.parts.Front`).

    >>> (front_frame([0.0, -1.0, 0.0], [1.0, 0.0, 0.0]) + 0.0).tolist()
    [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]
    """
    n, u = np.asarray(normal, np.float64), np.asarray(u, np.float64)
    return np.stack([u, np.cross(n, u), n], axis=1)
