"""Ray casting of triangle meshes from pinhole cameras (Open3D's Embree-backed RaycastingScene).

Pixel centres follow the library convention (centre of pixel (i, j) at (j + 0.5, i + 0.5)).
"""

import numpy as np
from jaxtyping import Float, Int

from drawer_lib.geometry.camera import Camera, Intrinsics


class Raycaster:
    """Casts camera rays against a fixed triangle mesh."""

    def __init__(self, verts: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]):
        import open3d as o3d

        self._o3d = o3d
        self.scene = o3d.t.geometry.RaycastingScene()
        mesh = o3d.t.geometry.TriangleMesh()
        mesh.vertex.positions = o3d.core.Tensor(np.ascontiguousarray(verts, np.float32))
        mesh.triangle.indices = o3d.core.Tensor(np.ascontiguousarray(faces, np.int32))
        self.scene.add_triangles(mesh)

    def cast(self, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t [...], unit face normals [..., 3], face id [...] with -1 = miss); t = inf on a miss."""
        shape = origins.shape[:-1]
        rays = np.concatenate([origins.reshape(-1, 3), dirs.reshape(-1, 3)], -1).astype(np.float32)
        ans = self.scene.cast_rays(self._o3d.core.Tensor(rays))
        t = ans["t_hit"].numpy().reshape(shape)
        n = ans["primitive_normals"].numpy().reshape(shape + (3,))
        fid = ans["primitive_ids"].numpy().astype(np.int64).reshape(shape)
        fid[~np.isfinite(t)] = -1
        return t, n, fid

    def depth_normals(self, intr: Intrinsics, w2c: Float[np.ndarray, "4 4"]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """z-depth [H, W] (0 on a miss), camera-facing unit normals in the OpenCV camera frame
        [H, W, 3] (0 on a miss) and face ids [H, W] (-1 on a miss)."""
        o, d = Camera(intr, w2c).rays()
        t, n_world, fid = self.cast(o, d)
        hit = fid >= 0
        z = np.where(hit, t, 0.0).astype(np.float32)
        n_cam = n_world @ w2c[:3, :3].T
        d_cam = d @ w2c[:3, :3].T
        flip = np.einsum("hwc,hwc->hw", n_cam, d_cam) > 0
        n_cam[flip] *= -1
        n_cam[~hit] = 0
        return z, n_cam.astype(np.float32), fid
