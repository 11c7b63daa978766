"""The ``dir`` source: validate an existing capture folder (docs/formats.md#capture, e.g. nerfstudio's
``ns-process-data`` output) and write it in the standard layout, undistorted.

A capture with lens distortion (``camera_model: OPENCV`` with k1, k2, p1, p2, as COLMAP and
``ns-process-data`` write it) is undistorted here, once: every raster is resampled to the
pinhole camera of the same size whose every pixel the distorted image covers
(:func:`~drawer_lib.geometry.distortion.undistorted_intrinsics`): RGB bilinearly, depth,
monocular priors, detections and instance maps by nearest neighbour (no values mixed across
edges). The manifest records the source camera. Images are written as PNG whatever their
source format (JPEG frames included); other files keep their content.
"""

import shutil
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from drawer_lib.capture.config import DirSource
from drawer_lib.errors import CaptureError
from drawer_lib.geometry.distortion import remap, undistorted_intrinsics, undistortion_map
from drawer_lib.io.capture import Capture, Frame, load_capture, write_transforms
from drawer_lib.io.images import read_npy, read_rgb, read_u16, write_rgb, write_u16
from drawer_lib.io.manifest import Manifest
from drawer_lib.io.parts import read_parts
from drawer_lib.paths import capture_name


def resolve_input(root: Path, p: str, what: str) -> Path:
    """An input path of a scene config, relative to the project root ``root``."""
    if not p:
        raise CaptureError(f"{what}: no path given")
    path = Path(p)
    path = path if path.is_absolute() else root / path
    if not path.exists():
        raise CaptureError(f"{what}: {path} does not exist")
    return path


class _Resampler:
    """Copies the rasters of a frame, undistorted when the source camera has distortion."""

    def __init__(self, cap: Capture):
        self.src = cap.intrinsics
        self.distorted = cap.intrinsics.has_distortion
        self.dst = undistorted_intrinsics(self.src) if self.distorted else self.src
        self.maps = undistortion_map(self.src, self.dst) if self.distorted else None

    def _map(self, a: np.ndarray, nearest: bool) -> np.ndarray:
        return a if self.maps is None else remap(a, *self.maps, nearest=nearest)

    def rgb(self, src: Path, dst: Path) -> None:
        write_rgb(dst, self._map(read_rgb(src), nearest=False))

    def u16(self, src: Path, dst: Path) -> None:
        if self.maps is None:
            shutil.copy2(src, dst)
        else:
            write_u16(dst, self._map(read_u16(src), nearest=True))

    def npy(self, src: Path, dst: Path, dtype: type, channels: int | None) -> None:
        if self.maps is None:
            shutil.copy2(src, dst)
            return
        H, W = self.src.height, self.src.width
        a = read_npy(src, dtype, (H, W) if channels is None else (H, W, channels))
        np.save(dst, self._map(a, nearest=True))


def import_dir_capture(scene: str, src: DirSource, test_every: int, out: Path, root: Path,
                       progress: Callable = lambda it, **kw: it) -> tuple[Manifest, dict]:
    """Validate the capture at ``src.path`` and write it to ``out`` with standard folder names
    (images/, depth/, mono_depth/, mono_normal/, detections/, gt/, sparse/), undistorted to a
    pinhole camera when it has distortion. Without train/test lists in its transforms.json,
    every ``test_every``-th frame is a test frame."""
    path = resolve_input(root, src.path, f"scene {scene}: dir.path")
    tf = path / capture_name("transforms")
    cap = load_capture(path, check_files=True, default_test_every=test_every, progress=True)
    stems: dict[str, str] = {}
    for fr in cap.frames:
        if fr.stem in stems:
            raise CaptureError(f"{tf}: frames {stems[fr.stem]} and {fr.file_path} share the stem {fr.stem!r}")
        stems[fr.stem] = fr.file_path
    rs = _Resampler(cap)
    D = {k: capture_name(k) for k in ("images", "depth", "mono_depth", "mono_normal", "detections", "gt",
                                      "gt_instances", "sparse_points")}

    new_frames = []
    for fr in progress(cap.frames, desc="undistort frames" if rs.distorted else "copy frames", total=len(cap.frames)):
        s = fr.stem
        rel = {"file_path": f"{D['images']}/{s}.png"}
        rs.rgb(path / fr.file_path, out / rel["file_path"])
        if fr.depth_file_path is not None:
            rel["depth_file_path"] = f"{D['depth']}/{s}.png"
            rs.u16(path / fr.depth_file_path, out / rel["depth_file_path"])
        if fr.mono_depth_file_path is not None:
            rel["mono_depth_file_path"] = f"{D['mono_depth']}/{s}.npy"
            rs.npy(path / fr.mono_depth_file_path, out / rel["mono_depth_file_path"], np.float32, None)
        if fr.mono_normal_file_path is not None:
            rel["mono_normal_file_path"] = f"{D['mono_normal']}/{s}.npy"
            rs.npy(path / fr.mono_normal_file_path, out / rel["mono_normal_file_path"], np.float16, 3)
        if fr.detections_path is not None:
            rel["detections_path"] = f"{D['detections']}/{s}.png"
            rs.u16(path / fr.detections_path, out / rel["detections_path"])
            shutil.copy2((path / fr.detections_path).with_suffix(".json"), (out / rel["detections_path"]).with_suffix(".json"))
        new_frames.append(Frame(rel["file_path"], fr.c2w_gl, rel.get("depth_file_path"), rel.get("mono_depth_file_path"),
                                rel.get("mono_normal_file_path"), rel.get("detections_path")))

    extra = dict(cap.extra)
    has_sparse = False
    if "ply_file_path" in extra:
        ply = path / extra["ply_file_path"]
        if not ply.is_file():
            raise CaptureError(f"{tf}: ply_file_path {extra['ply_file_path']!r} is missing")
        shutil.copy2(ply, out / D["sparse_points"])
        extra["ply_file_path"] = D["sparse_points"]
        has_sparse = True

    gt_kinds = None
    if (path / D["gt"]).is_dir():
        if (path / capture_name("gt_parts")).is_file():
            gt_kinds = read_parts(path / capture_name("gt_parts")).kinds()
        shutil.copytree(path / D["gt"], out / D["gt"], dirs_exist_ok=True)
        if rs.distorted and (out / D["gt_instances"]).is_dir():  # instance maps are rasters of the frames
            for p in sorted((out / D["gt_instances"]).glob("*.png")):
                rs.u16(p, p)
    has_gt = gt_kinds is not None

    new = replace(cap, root=out, intrinsics=rs.dst, frames=new_frames, extra=extra)
    write_transforms(new)

    def every(key: str) -> bool:
        return new.has(key)

    some = {k: any(getattr(f, k) is not None for f in new.frames) for k in
            ("depth_file_path", "mono_depth_file_path", "mono_normal_file_path", "detections_path")}
    for k, v in some.items():
        if v and not every(k):
            raise CaptureError(f"{tf}: some frames have {k} and some do not")
    it = cap.intrinsics
    camera = {"camera_model": "OPENCV" if rs.distorted else "PINHOLE", "fl_x": it.fx, "fl_y": it.fy, "cx": it.cx,
              "cy": it.cy, "w": it.width, "h": it.height, "distortion": list(it.dist), "undistorted": rs.distorted}
    if rs.distorted:
        camera["how"] = ("resampled to the pinhole camera of the same size whose every pixel the distorted image "
                         "covers: RGB bilinear, other rasters nearest")
    manifest = Manifest(
        scene=scene, source="dir", n_frames=len(new.frames), n_train=len(new.train), n_test=len(new.test),
        width=new.intrinsics.width, height=new.intrinsics.height,
        has={"rgb": True, "depth": every("depth_file_path"), "mono_depth": every("mono_depth_file_path"),
             "mono_normal": every("mono_normal_file_path"), "detections": every("detections_path"),
             "sparse_points": has_sparse, "gt": has_gt},
        lacks={k: f"{path} has no {k}" for k in ("depth", "mono_depth", "mono_normal", "detections", "sparse_points")}
        | {"gt": f"{path} has no {capture_name('gt_parts')}"},
        details={"poses": {"kind": "given", "source": str(path)}, "intrinsics": camera},
        world_frame={"metric_scale": src.metric_scale, "gravity": src.gravity,
                     "how": f"as given by {path}; metric scale and gravity as stated in the scene config"},
        gt_part_kinds=gt_kinds,
    )
    metrics = {"n_frames": len(new.frames), "n_train": len(new.train), "n_test": len(new.test),
               "undistorted": rs.distorted}
    return manifest, metrics
