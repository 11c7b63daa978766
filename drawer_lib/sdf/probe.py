"""Quick accuracy probes of an SDF during training (the ``sdf`` stage's error-against-time curve).

A probe extracts a quick mesh (marching cubes at ``cell``, only where the train cameras look)
and scores it against ``gt/mesh.ply`` (the metrics of docs/formats.md#geometry, fewer sample points than the mesh
stage), and measures the rendered depth of the test views against the GT depth ray cast from
``gt/mesh.ply``. Probes run outside the training clock.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import trimesh

from drawer_lib.geometry.camera import pixel_dirs
from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.io.capture import Capture
from drawer_lib.io.mesh import load_mesh
from drawer_lib.geometry.isosurface import grid_field_mesh, marching_cubes_mesh, sdf_grid, seen_crossing_mask
from drawer_lib.metrics.geometry import MeshEvaluator
from drawer_lib.paths import capture_name
from drawer_lib.sdf.io import GridSDF

DepthFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]  # (origins, dirs [R, 3]) -> z-depth [R]


@dataclass
class TestDepth:
    origins: torch.Tensor  # [R, 3]
    dirs: torch.Tensor  # [R, 3] with camera z component 1
    z: torch.Tensor  # [R] exact z-depth


class GeometryProbe:
    """Scores SDFs of one capture against its ground truth (``gt/mesh.ply`` must exist)."""

    def __init__(self, cap: Capture, cell: float = 0.02, n_points: int = 100_000, pixel_stride: int = 2,
                 max_test_rays: int = 200_000):
        """Test depth is scored on every ``pixel_stride``-th pixel of the test views, or on a
        coarser stride when that would exceed ``max_test_rays`` (a phone's hundreds of frames)."""
        self.cap, self.cell = cap, cell
        self.gt = load_mesh(cap.root / capture_name("gt_mesh"))
        self.w2c = np.stack([cap.frames[i].w2c for i in cap.train])
        self.evaluator = MeshEvaluator(self.gt, cap.intrinsics, self.w2c, n_points=n_points)
        n_px = len(cap.test) * cap.intrinsics.width * cap.intrinsics.height
        self.test = self._test_depth(max(pixel_stride, int(np.ceil(np.sqrt(n_px / max_test_rays)))))

    def _test_depth(self, stride: int) -> TestDepth | None:
        if not self.cap.test:
            return None
        it = self.cap.intrinsics
        rc = Raycaster(np.asarray(self.gt.vertices), np.asarray(self.gt.faces))
        sel = np.zeros((it.height, it.width), bool)
        sel[::stride, ::stride] = True
        sel = sel.reshape(-1)
        d_cam = pixel_dirs(it).reshape(-1, 3)[sel]
        os_, ds, zs = [], [], []
        for i in self.cap.test:
            z = rc.depth_normals(it, self.cap.frames[i].w2c)[0].reshape(-1)[sel]
            ok = z > 0
            c2w = self.cap.frames[i].c2w
            os_.append(np.broadcast_to(c2w[:3, 3], (int(ok.sum()), 3)))
            ds.append(d_cam[ok] @ c2w[:3, :3].T)
            zs.append(z[ok])
        f = lambda a: torch.tensor(np.concatenate(a), dtype=torch.float32)  # noqa: E731
        return TestDepth(f(os_), f(ds), f(zs))

    def quick_mesh(self, sdf_fn: Callable, lo: np.ndarray, hi: np.ndarray, grid: GridSDF | None = None) -> trimesh.Trimesh:
        if grid is not None:  # a fused grid is meshed on its own voxels, observed cubes only
            try:
                return grid_field_mesh(grid, self.cap.intrinsics, self.w2c)
            except ValueError:  # nothing observed in view: no quick mesh (an empty curve cell)
                return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), process=False)
        v = sdf_grid(sdf_fn, lo, hi, self.cell, 4)
        mask = seen_crossing_mask(v, lo, self.cell, self.cap.intrinsics, self.w2c)
        return marching_cubes_mesh(v, lo, self.cell, 0.0, mask)

    def __call__(self, sdf_fn: Callable, lo: np.ndarray, hi: np.ndarray, depth_fn: DepthFn | None,
                 grid: GridSDF | None = None) -> dict[str, float]:
        """``chamfer_l1`` (m), ``fscore_1cm``, ``fscore_2cm`` of the quick mesh (NaN when it is
        empty) and ``test_depth_l1`` (m, mean over test pixels where GT has depth)."""
        out = {"chamfer_l1": float("nan"), "fscore_1cm": float("nan"), "fscore_2cm": float("nan"),
               "test_depth_l1": float("nan")}
        mesh = self.quick_mesh(sdf_fn, lo, hi, grid)
        if len(mesh.faces):
            r = self.evaluator(mesh)
            out.update({k: r[k] for k in ("chamfer_l1", "fscore_1cm", "fscore_2cm")})
        if depth_fn is not None and self.test is not None and len(self.test.z):
            z = depth_fn(self.test.origins, self.test.dirs)
            out["test_depth_l1"] = float((z - self.test.z).abs().mean())
        return out
