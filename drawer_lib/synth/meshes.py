"""Triangle meshes with texture coordinates for the procedural kitchens (numpy).

Every builder returns a closed surface with faces wound counter-clockwise seen from outside
(outward normals) and per-vertex texture coordinates **in metres** (a planar or cylindrical
unwrap at true scale); the model builder divides them by a material's texture size, so wood
grain and tiles have the same physical size on every piece.
"""

from dataclasses import dataclass

import numpy as np
from jaxtyping import Float, Int


@dataclass(frozen=True)
class UVMesh:
    verts: Float[np.ndarray, "V 3"]
    faces: Int[np.ndarray, "F 3"]
    uv: Float[np.ndarray, "V 2"]  # metres

    def transformed(self, R: Float[np.ndarray, "3 3"], t: Float[np.ndarray, "3"]) -> "UVMesh":
        return UVMesh(self.verts @ R.T + t, self.faces, self.uv)

    def translated(self, t) -> "UVMesh":
        return UVMesh(self.verts + np.asarray(t, np.float64), self.faces, self.uv)

    @property
    def bounds(self) -> np.ndarray:
        """[2, 3] axis-aligned min and max corners."""
        return np.stack([self.verts.min(0), self.verts.max(0)])

    def face_normals(self) -> np.ndarray:
        a, b, c = (self.verts[self.faces[:, k]] for k in range(3))
        n = np.cross(b - a, c - a)
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    def area(self) -> float:
        a, b, c = (self.verts[self.faces[:, k]] for k in range(3))
        return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())

    def volume(self) -> float:
        """Signed volume (positive for outward winding of a closed surface)."""
        a, b, c = (self.verts[self.faces[:, k]] for k in range(3))
        return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def concat(meshes: list[UVMesh]) -> UVMesh:
    if not meshes:
        return UVMesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 2)))
    offs = np.cumsum([0] + [len(m.verts) for m in meshes[:-1]])
    return UVMesh(
        np.concatenate([m.verts for m in meshes]),
        np.concatenate([m.faces + o for m, o in zip(meshes, offs)]).astype(np.int64),
        np.concatenate([m.uv for m in meshes]),
    )


# The six faces of a box: (normal axis, sign, in-plane axes (u, v)) with u x v = normal.
_BOX_FACES = [
    (0, 1, (1, 2)), (0, -1, (2, 1)),
    (1, 1, (2, 0)), (1, -1, (0, 2)),
    (2, 1, (0, 1)), (2, -1, (1, 0)),
]


def box(center, size, uv_offset=(0.0, 0.0)) -> UVMesh:
    """Axis-aligned box with full extents ``size``; each face is unwrapped by projection on
    the two world axes in its plane, so textures keep their metric size and stay continuous
    across neighbouring boxes."""
    c, h = np.asarray(center, np.float64), 0.5 * np.asarray(size, np.float64)
    if np.any(h <= 0):
        raise ValueError(f"box: non-positive size {size}")
    V, F, UV = [], [], []
    for ax, sgn, (a1, a2) in _BOX_FACES:
        base = len(V)
        for s1, s2 in [(-1, -1), (1, -1), (1, 1), (-1, 1)]:
            p = c.copy()
            p[ax] += sgn * h[ax]
            p[a1] += s1 * h[a1]
            p[a2] += s2 * h[a2]
            V.append(p)
            # horizontal faces map (x, y); vertical faces map (horizontal, z)
            if ax == 2:
                UV.append([p[0], p[1]])
            else:
                UV.append([p[1 - ax], p[2]])
        F += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    V, F = np.asarray(V), np.asarray(F, np.int64)
    # ensure outward winding (the in-plane axis order above fixes it; checked here cheaply)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    out = (V[F].mean(1) - c)
    flip = np.einsum("ij,ij->i", n, out) < 0
    F[flip] = F[flip][:, ::-1]
    return UVMesh(V, F, np.asarray(UV) + np.asarray(uv_offset))


def box_between(lo, hi, uv_offset=(0.0, 0.0)) -> UVMesh:
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return box((lo + hi) / 2, hi - lo, uv_offset)


def lathe(profile: Float[np.ndarray, "P 2"], n: int = 32) -> UVMesh:
    """Surface of revolution about +z from a profile of (radius, z) points.

    The profile runs from the bottom to the top; a first/last point with radius 0 closes the
    surface at that pole with a fan (no zero-area triangles). UV: (arc length around at the
    largest radius, arc length along the profile).
    """
    prof = np.asarray(profile, np.float64)
    if prof.ndim != 2 or prof.shape[1] != 2 or len(prof) < 2:
        raise ValueError("lathe: profile must be [P, 2] with P >= 2")
    r_max = prof[:, 0].max()
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(prof, axis=0), axis=1))])
    theta = np.linspace(0.0, 2 * np.pi, n + 1)  # last column duplicates the seam for UVs
    V, UV, F = [], [], []
    ring_start = []
    for k, (r, z) in enumerate(prof):
        ring_start.append(len(V))
        for t in theta:
            V.append([r * np.cos(t), r * np.sin(t), z])
            UV.append([t * r_max, s[k]])
    P = len(prof)
    for k in range(P - 1):
        a0, b0 = ring_start[k], ring_start[k + 1]
        for j in range(n):
            a, a1, b, b1 = a0 + j, a0 + j + 1, b0 + j, b0 + j + 1
            if prof[k, 0] == 0.0:  # bottom pole: fan
                F.append([a, b1, b])
            elif prof[k + 1, 0] == 0.0:  # top pole: fan
                F.append([a, a1, b])
            else:
                F += [[a, a1, b1], [a, b1, b]]
    mesh = UVMesh(np.asarray(V), np.asarray(F, np.int64), np.asarray(UV))
    # orient outward: the profile may run either way round
    if mesh.volume() < 0:
        mesh = UVMesh(mesh.verts, mesh.faces[:, ::-1].copy(), mesh.uv)
    return _drop_unused(mesh)


def cylinder(p0, p1, radius: float, n: int = 20) -> UVMesh:
    """Closed cylinder between points ``p0`` and ``p1``."""
    p0, p1 = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
    L = np.linalg.norm(p1 - p0)
    if L <= 0 or radius <= 0:
        raise ValueError("cylinder: zero length or radius")
    m = lathe(np.array([[0, 0], [radius, 0], [radius, L], [0, L]]), n)
    return m.transformed(frame_z(p1 - p0), p0)


def torus_arc(R: float, r: float, arc: float = np.pi, n_major: int = 16, n_minor: int = 10) -> UVMesh:
    """Tube of radius ``r`` along a circular arc of radius ``R`` in the xz-plane (from +x at
    angle -arc/2 to +arc/2 around the y axis), closed with flat caps; for mug handles."""
    phis = np.linspace(-arc / 2, arc / 2, n_major + 1)
    ths = np.linspace(0, 2 * np.pi, n_minor + 1)
    V, UV, F = [], [], []
    for i, ph in enumerate(phis):
        c = np.array([R * np.cos(ph), 0.0, R * np.sin(ph)])
        radial = np.array([np.cos(ph), 0.0, np.sin(ph)])
        for j, th in enumerate(ths):
            V.append(c + r * (np.cos(th) * radial + np.sin(th) * np.array([0, 1.0, 0])))
            UV.append([ph * R, th * r])
    w = n_minor + 1
    for i in range(n_major):
        for j in range(n_minor):
            a, b = i * w + j, (i + 1) * w + j
            F += [[a, b, b + 1], [a, b + 1, a + 1]]
    for i, sgn in ((0, -1), (n_major, 1)):  # caps
        ph = phis[i]
        ci = len(V)
        V.append([R * np.cos(ph), 0.0, R * np.sin(ph)])
        UV.append([0.0, 0.0])
        for j in range(n_minor):
            a, b = i * w + j, i * w + j + 1
            F.append([ci, b, a] if sgn > 0 else [ci, a, b])
    mesh = UVMesh(np.asarray(V), np.asarray(F, np.int64), np.asarray(UV))
    if mesh.volume() < 0:
        mesh = UVMesh(mesh.verts, mesh.faces[:, ::-1].copy(), mesh.uv)
    return mesh


def frame_z(direction) -> np.ndarray:
    """A rotation whose third column is the unit ``direction`` (ValueError if zero)."""
    z = np.asarray(direction, np.float64)
    n = np.linalg.norm(z)
    if n < 1e-12:
        raise ValueError("frame_z: zero direction")
    z = z / n
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def _drop_unused(m: UVMesh) -> UVMesh:
    used = np.unique(m.faces)
    if len(used) == len(m.verts):
        return m
    remap = -np.ones(len(m.verts), np.int64)
    remap[used] = np.arange(len(used))
    return UVMesh(m.verts[used], remap[m.faces], m.uv[used])
