"""Colours of mesh faces from posed images, and rendering of a face-coloured mesh (the
``textured_mesh`` baseline and the Gaussians' initial colours)."""

import numpy as np
import torch
import trimesh

from drawer_lib.geometry.camera import Intrinsics, pixel_of
from drawer_lib.geometry.raycast import Raycaster


def mesh_depths(rc: Raycaster, intr: Intrinsics, w2cs: np.ndarray) -> np.ndarray:
    """z-depth [C, H, W] of the mesh from each camera (0 where the ray misses)."""
    return np.stack([rc.depth_normals(intr, T)[0] for T in w2cs])


def face_colors(points: np.ndarray, images: np.ndarray, intr: Intrinsics, w2cs: np.ndarray, depths: np.ndarray,
                rel_tol: float = 0.01, abs_tol: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """Mean colour [F, 3] in [0, 1] of surface points [F, 3] (e.g. face centroids) over the views
    where they are visible (their depth matches the view's mesh depth within
    ``abs_tol + rel_tol z``), and the number of such views [F]; unseen points get 0.5 grey."""
    F = len(points)
    acc = np.zeros((F, 3))
    cnt = np.zeros(F)
    for img, T, D in zip(images, w2cs, depths):
        ii, jj, z, ok = pixel_of(points, T, intr, near=1e-6)
        d = D[ii, jj]
        ok &= (d > 0) & (np.abs(d - z) <= abs_tol + rel_tol * z)
        acc[ok] += img[ii[ok], jj[ok]]
        cnt[ok] += 1
    col = np.where(cnt[:, None] > 0, acc / np.maximum(cnt, 1)[:, None], 0.5)
    return col, cnt


def render_face_colored(rc: Raycaster, colors: np.ndarray, intr: Intrinsics, w2c: np.ndarray,
                        background: np.ndarray) -> np.ndarray:
    """[H, W, 3] image of the mesh with flat per-face ``colors`` (background where rays miss)."""
    _, _, fid = rc.depth_normals(intr, w2c)
    out = np.where((fid >= 0)[..., None], colors[np.maximum(fid, 0)], background)
    return out.astype(np.float32)


def colored_mesh_at_resolution(mesh: trimesh.Trimesh, cell: float) -> trimesh.Trimesh:
    """The mesh split until every face's area is at most cell^2 / 2 (one colour per face then
    means a texture of about ``cell`` metres per texel)."""
    from drawer_lib.splat.anchored import subdivide_to_area

    V, F, _ = subdivide_to_area(np.asarray(mesh.vertices), np.asarray(mesh.faces), 0.5 * cell * cell, max_rounds=12)
    return trimesh.Trimesh(V, F, process=False)


def to_tensor_images(images: np.ndarray) -> torch.Tensor:
    """uint8 [C, H, W, 3] -> float32 [C, H, W, 3] in [0, 1]."""
    return torch.from_numpy(images.astype(np.float32) / 255.0)
