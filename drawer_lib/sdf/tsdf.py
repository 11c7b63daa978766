"""The TSDF baseline: Open3D's tensor ``VoxelBlockGrid`` fusion of a capture's metric depth.

Two Open3D facts shape this file (checked on open3d 0.20.0): the legacy ``ScalableTSDFVolume``
returns empty meshes in that wheel, so the tensor ``VoxelBlockGrid`` is used; and its projection
puts pixel centres at integer + 0.5 like this library (cx = W/2 for a centred principal point),
so the capture's intrinsics are passed unchanged. (The legacy ``UniformTSDFVolume`` uses the
other convention, cx = W/2 - 0.5; mixing them up moves the surface by ~1 cm at 3 m.)

The fused volume is exported as a dense :class:`GridSDF` (metres; NaN where the accumulated
weight is below ``weight_threshold``), which the mesh stage meshes like a neural field.
"""

from collections.abc import Callable

import numpy as np

from drawer_lib.errors import InputError
from drawer_lib.io.capture import Capture
from drawer_lib.sdf.config import TsdfConfig
from drawer_lib.sdf.io import GridSDF

BLOCK_RES = 16


def fuse_tsdf(cap: Capture, frames: list[int], cfg: TsdfConfig,
              progress: Callable = lambda it, **kw: it) -> GridSDF:
    """Integrate the metric depth of ``frames`` into a TSDF; returns the observed voxels as a
    dense grid (vertex k at ``lo + k * voxel``) of signed distances in metres."""
    import open3d as o3d
    import open3d.core as o3c

    it = cap.intrinsics
    if it.has_distortion:
        raise InputError(f"{cap.root}: TSDF fusion needs undistorted (PINHOLE) depth; distortion {it.dist}")
    dev = o3c.Device("CPU:0")
    vbg = o3d.t.geometry.VoxelBlockGrid(attr_names=("tsdf", "weight"), attr_dtypes=(o3c.float32, o3c.float32),
                                        attr_channels=((1), (1)), voxel_size=cfg.voxel, block_resolution=BLOCK_RES,
                                        block_count=cfg.block_count, device=dev)
    K = o3c.Tensor(np.array([[it.fx, 0, it.cx], [0, it.fy, it.cy], [0, 0, 1]]), o3c.float64)
    n_valid = 0
    for i in progress(frames, desc="tsdf", total=len(frames)):
        z = np.ascontiguousarray(cap.depth(i), dtype=np.float32)  # metres, 0 = invalid
        if not np.all(np.isfinite(z)):
            raise InputError(f"{cap._path(i, 'depth_file_path')}: depth has non-finite values")
        valid = int(((z > 0) & (z <= cfg.depth_max)).sum())
        if valid == 0:  # Open3D aborts on a frame that touches no block
            continue
        n_valid += valid
        dimg = o3d.t.geometry.Image(o3c.Tensor(z))
        ext = o3c.Tensor(np.ascontiguousarray(cap.frames[i].w2c), o3c.float64)
        coords = vbg.compute_unique_block_coordinates(dimg, K, ext, 1.0, float(cfg.depth_max),
                                                      trunc_voxel_multiplier=float(cfg.trunc_voxels))
        vbg.integrate(coords, dimg, K, ext, 1.0, float(cfg.depth_max), trunc_voxel_multiplier=float(cfg.trunc_voxels))
    if n_valid == 0:
        raise InputError(f"{cap.root}: no valid depth pixel (0 < z <= depth_max = {cfg.depth_max} m) in the "
                         f"{len(frames)} train frames")
    xyz, idx = vbg.voxel_coordinates_and_flattened_indices()
    xyz = xyz.numpy().astype(np.float64)
    idx = idx.numpy()
    tsdf = vbg.attribute("tsdf").reshape((-1,)).numpy()[idx]
    weight = vbg.attribute("weight").reshape((-1,)).numpy()[idx]
    keep = weight >= cfg.weight_threshold
    if not keep.any():
        raise InputError(f"{cap.root}: TSDF fusion observed no voxel with weight >= {cfg.weight_threshold}")
    xyz, tsdf = xyz[keep], tsdf[keep]
    lo = xyz.min(0)
    ijk = np.rint((xyz - lo) / cfg.voxel).astype(np.int64)
    values = np.full(tuple(ijk.max(0) + 1), np.nan, np.float32)
    values[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = tsdf * (cfg.trunc_voxels * cfg.voxel)
    return GridSDF(lo, cfg.voxel, values)
