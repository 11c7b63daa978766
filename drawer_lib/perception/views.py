"""The mesh as the cameras see it: per-frame face-id maps (ray cast), face adjacency, normals."""

from dataclasses import dataclass

import numpy as np
import trimesh
from jaxtyping import Float, Int

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import pixel_of
from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.io.capture import Capture


def perception_mesh(mesh: trimesh.Trimesh, max_faces: int, max_edge: float, cap: Capture | None = None,
                    frames: list[int] | None = None, snap: float = 0.0) -> trimesh.Trimesh:
    """``mesh`` simplified (quadric, PyMeshLab) to at most ``max_faces`` faces, then split so that
    no edge exceeds ``max_edge`` (m; simplification leaves large triangles on flat fronts, and a
    mask needs several faces under it), degenerate faces removed. ``snap`` > 0: the vertices are
    first rounded to that grid (m; :func:`~drawer_lib.mesh.clean.snap_vertices`). Raises
    :class:`InputError` for a mesh without faces."""
    if len(mesh.faces) == 0:
        raise InputError("decompose: the mesh has no faces")
    from drawer_lib.mesh.clean import snap_vertices

    m = mesh = snap_vertices(mesh, snap)
    if len(mesh.faces) > max_faces:
        from drawer_lib.mesh.clean import CleanConfig, clean_mesh

        # PyMeshLab's collapse, as when perception's thresholds were fitted (decision fits and the
        # held-out split); the mesh stage's faster default has not been benchmarked for perception
        m, _ = clean_mesh(mesh, CleanConfig(min_component_diag=0.0, target_faces=max_faces, decimator="pymeshlab"))
    frames = frames if frames is not None else (list(cap.train) if cap is not None else [])
    if cap is not None:
        m = seen_submesh(m, cap, frames)
    # split in steps of at most 4x, cutting back to the seen part after each (a huge floor
    # triangle that a camera sees must not turn into millions of unseen faces)
    while max_edge > 0 and len(m.edges_unique) and m.edges_unique_length.max() > max_edge * (1 + 1e-9):
        step = max(max_edge, float(m.edges_unique_length.max()) / 4)
        v, f = trimesh.remesh.subdivide_to_size(np.asarray(m.vertices), np.asarray(m.faces), step, max_iter=12)
        m = trimesh.Trimesh(v, f, process=False)
        m.merge_vertices()
        if cap is not None:
            m = seen_submesh(m, cap, frames)
    keep = m.area_faces > 1e-12
    if not keep.all():
        m = trimesh.Trimesh(m.vertices, m.faces[keep], process=False)
        m.remove_unreferenced_vertices()
    return m


@dataclass
class MeshViews:
    """Face ids per pixel of the frames used (``frames`` are capture indices)."""

    mesh: trimesh.Trimesh
    frames: list[int]
    face_maps: Int[np.ndarray, "T H W"]  # -1 = no face
    depth_maps: Float[np.ndarray, "T H W"]  # z-depth (m), 0 = no face
    face_px: Int[np.ndarray, "T F"]  # flat pixel index of each face's centroid where it is visible, else -1

    @property
    def n_faces(self) -> int:
        return len(self.mesh.faces)

    def silhouette(self, t: int, member: np.ndarray) -> np.ndarray:
        """[H, W] pixels of view ``t`` whose face is in the boolean face set ``member`` [F]."""
        fm = self.face_maps[t]
        return (fm >= 0) & member[np.maximum(fm, 0)]

    def face_frames(self) -> np.ndarray:
        """[F] number of views in which each face's centroid is visible."""
        return (self.face_px >= 0).sum(0)

    def faces_under(self, t: int, mask: np.ndarray) -> np.ndarray:
        """Face ids whose centroid is visible in view ``t`` inside the bool ``mask`` [H, W]
        (independent of how face and pixel sizes compare)."""
        px = self.face_px[t]
        vis = np.nonzero(px >= 0)[0]
        return vis[mask.ravel()[px[vis]]]


def _face_pixels(mesh: trimesh.Trimesh, cap: Capture, i: int, depth: np.ndarray, tol: float = 0.01) -> np.ndarray:
    """[F] flat pixel index of each face centroid in frame i where the centroid is visible (its
    z agrees with the ray-cast depth there within ``tol`` + 1 % of z), else -1."""
    it = cap.intrinsics
    y, x, z, ok = pixel_of(np.asarray(mesh.triangles_center), cap.frames[i].w2c, it, near=1e-3)
    idx = np.where(ok, y * it.width + x, 0)
    d = depth.ravel()[idx]
    ok &= (d > 0) & (np.abs(d - z) < tol + 0.01 * z)
    return np.where(ok, idx, -1)


def render_views(mesh: trimesh.Trimesh, cap: Capture, frames: list[int]) -> MeshViews:
    rc = Raycaster(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    fms, dms, fps = [], [], []
    for i in frames:
        d, _, f = rc.depth_normals(cap.intrinsics, cap.frames[i].w2c)
        fms.append(f.astype(np.int64))
        dms.append(d.astype(np.float32))
        fps.append(_face_pixels(mesh, cap, i, d))
    return MeshViews(mesh, list(frames), np.stack(fms), np.stack(dms), np.stack(fps))


def seen_submesh(mesh: trimesh.Trimesh, cap: Capture, frames: list[int], rings: int = 1) -> trimesh.Trimesh:
    """The faces some frame's pixel ray hits, grown by ``rings`` edge-neighbour rings."""
    rc = Raycaster(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    seen = np.zeros(len(mesh.faces), bool)
    for i in frames:
        f = rc.depth_normals(cap.intrinsics, cap.frames[i].w2c)[2]
        seen[f[f >= 0]] = True
    adj = np.asarray(mesh.face_adjacency).reshape(-1, 2)
    for _ in range(rings):
        grow = seen.copy()
        grow[adj[seen[adj[:, 0]], 1]] = True
        grow[adj[seen[adj[:, 1]], 0]] = True
        seen = grow
    if not seen.any():
        raise InputError("decompose: no train camera sees the mesh")
    m = trimesh.Trimesh(mesh.vertices, np.asarray(mesh.faces)[seen], process=False)
    m.remove_unreferenced_vertices()
    return m


def adjacency_edges(mesh: trimesh.Trimesh) -> tuple[Int[np.ndarray, "E 2"], Float[np.ndarray, "E"]]:
    """Pairs of faces sharing an edge and their dihedral angles (deg, 0 = coplanar)."""
    pairs = np.asarray(mesh.face_adjacency, np.int64).reshape(-1, 2)
    if len(pairs) == 0:
        return pairs, np.zeros(0)
    n = np.asarray(mesh.face_normals)
    cos = np.clip((n[pairs[:, 0]] * n[pairs[:, 1]]).sum(-1), -1, 1)
    return pairs, np.degrees(np.arccos(cos))


def connected_components(n: int, edges: np.ndarray, members: np.ndarray | None = None) -> np.ndarray:
    """Component label [n] of the graph (nodes outside ``members`` get -1)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as cc

    if members is None:
        members = np.ones(n, bool)
    e = edges[members[edges[:, 0]] & members[edges[:, 1]]] if len(edges) else edges
    A = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)) if len(e) else coo_matrix((n, n))
    _, lab = cc(A, directed=False)
    return np.where(members, lab, -1)


def largest_component(faces: np.ndarray, n: int, edges: np.ndarray) -> np.ndarray:
    """The face ids of the largest edge-connected component of the face set ``faces``."""
    if len(faces) == 0:
        return faces
    m = np.zeros(n, bool)
    m[faces] = True
    lab = connected_components(n, edges, m)
    sub = lab[faces]
    best = np.bincount(sub).argmax()
    return faces[sub == best]
