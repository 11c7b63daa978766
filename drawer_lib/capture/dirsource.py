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
from drawer_lib.io.rgbd import upsample_depth
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
    """Copies the rasters of the frames to the capture's one pinhole camera ``dst``: undistorted
    when the source camera has distortion, resampled when a frame has its own camera; a depth
    map smaller than its image is first brought to the image's size (:mod:`~drawer_lib.io.rgbd`)
    after its low-confidence pixels are dropped."""

    def __init__(self, cap: Capture, src: DirSource):
        self.cap, self.cfg = cap, src
        self.distorted = cap.intrinsics.has_distortion
        self.dst = undistorted_intrinsics(cap.intrinsics) if self.distorted else cap.intrinsics
        self._maps: dict = {}
        self.depth_stats = {"source_size": None, "upsampled": 0, "low_confidence_dropped": 0, "pixels": 0}

    @property
    def resampled(self) -> bool:
        return self.distorted or self.cap.per_frame_cameras

    def maps(self, i: int):
        """(rows, cols) of frame ``i``'s source pixels for each pixel of ``dst``, or None (a copy)."""
        it = self.cap.frame_intrinsics(i)
        if it == self.dst:
            return None
        if it not in self._maps:
            self._maps[it] = undistortion_map(it, self.dst)
        return self._maps[it]

    def _map(self, i: int, a: np.ndarray, nearest: bool) -> np.ndarray:
        m = self.maps(i)
        return a if m is None else remap(a, *m, nearest=nearest)

    def rgb(self, i: int, src: Path, dst: Path) -> None:
        write_rgb(dst, self._map(i, read_rgb(src), nearest=False))

    def u16(self, i: int, src: Path, dst: Path) -> None:
        if self.maps(i) is None:
            if src.resolve() != dst.resolve():  # (instance maps are resampled in place)
                shutil.copy2(src, dst)
        else:
            write_u16(dst, self._map(i, read_u16(src), nearest=True))

    def depth(self, i: int, dst: Path) -> None:
        """Frame ``i``'s depth: low-confidence pixels dropped, brought to the image's size, then
        to ``dst``'s camera; the values stay the source's units (no depths mixed)."""
        fr, cap, cfg = self.cap.frames[i], self.cap, self.cfg
        it = cap.frame_intrinsics(i)
        raw = read_u16(cap.root / fr.depth_file_path)
        st = self.depth_stats
        st["source_size"] = st["source_size"] or [raw.shape[1], raw.shape[0]]
        st["pixels"] += raw.size
        changed = False
        if fr.confidence_file_path is not None and cfg.min_confidence > 0:
            low = (cap.confidence(i) < cfg.min_confidence) & (raw > 0)
            st["low_confidence_dropped"] += int(low.sum())
            raw = np.where(low, 0, raw).astype(np.uint16)
            changed = True
        if raw.shape != (it.height, it.width):
            guide = read_rgb(cap.root / fr.file_path) if cfg.depth_upsample == "edge_aware" else None
            up = upsample_depth(raw.astype(np.float32), (it.height, it.width), guide, cfg.depth_upsample,
                                sigma_color=cfg.upsample_sigma_color, same_surface=cfg.upsample_same_surface)
            raw = np.round(up).astype(np.uint16)  # in the source's depth units
            st["upsampled"] += 1
            changed = True
        if not changed and self.maps(i) is None:
            shutil.copy2(cap.root / fr.depth_file_path, dst)
        else:
            write_u16(dst, self._map(i, raw, nearest=True))

    def npy(self, i: int, src: Path, dst: Path, dtype: type, channels: int | None) -> None:
        if self.maps(i) is None:
            shutil.copy2(src, dst)
            return
        H, W = self.dst.height, self.dst.width
        a = read_npy(src, dtype, (H, W) if channels is None else (H, W, channels))
        np.save(dst, self._map(i, a, nearest=True))


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
    rs = _Resampler(cap, src)
    D = {k: capture_name(k) for k in ("images", "depth", "mono_depth", "mono_normal", "detections", "gt",
                                      "gt_instances", "sparse_points")}

    new_frames = []
    desc = "undistort frames" if rs.distorted else "resample frames" if rs.resampled else "copy frames"
    for i, fr in enumerate(progress(cap.frames, desc=desc, total=len(cap.frames))):
        s = fr.stem
        rel = {"file_path": f"{D['images']}/{s}.png"}
        rs.rgb(i, path / fr.file_path, out / rel["file_path"])
        if fr.depth_file_path is not None:
            rel["depth_file_path"] = f"{D['depth']}/{s}.png"
            rs.depth(i, out / rel["depth_file_path"])
        if fr.mono_depth_file_path is not None:
            rel["mono_depth_file_path"] = f"{D['mono_depth']}/{s}.npy"
            rs.npy(i, path / fr.mono_depth_file_path, out / rel["mono_depth_file_path"], np.float32, None)
        if fr.mono_normal_file_path is not None:
            rel["mono_normal_file_path"] = f"{D['mono_normal']}/{s}.npy"
            rs.npy(i, path / fr.mono_normal_file_path, out / rel["mono_normal_file_path"], np.float16, 3)
        if fr.detections_path is not None:
            rel["detections_path"] = f"{D['detections']}/{s}.png"
            rs.u16(i, path / fr.detections_path, out / rel["detections_path"])
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
        if rs.resampled and (out / D["gt_instances"]).is_dir():  # instance maps are rasters of the frames
            index = {fr.stem: i for i, fr in enumerate(cap.frames)}
            for p in sorted((out / D["gt_instances"]).glob("*.png")):
                if p.stem not in index:
                    raise CaptureError(f"{p}: no frame of {tf} has the stem {p.stem!r}")
                rs.u16(index[p.stem], p, p)
    has_gt = gt_kinds is not None

    new = replace(cap, root=out, intrinsics=rs.dst, frames=new_frames, extra=extra)
    write_transforms(new)

    def every(key: str) -> bool:
        return new.has(key)

    for k in ("depth_file_path", "mono_depth_file_path", "mono_normal_file_path", "detections_path",
              "confidence_file_path"):
        if any(getattr(f, k) is not None for f in cap.frames) and not cap.has(k):
            raise CaptureError(f"{tf}: some frames have {k} and some do not")
    it = cap.intrinsics
    camera = {"camera_model": "OPENCV" if rs.distorted else "PINHOLE", "fl_x": it.fx, "fl_y": it.fy, "cx": it.cx,
              "cy": it.cy, "w": it.width, "h": it.height, "distortion": list(it.dist), "undistorted": rs.distorted}
    if rs.distorted:
        camera["how"] = ("resampled to the pinhole camera of the same size whose every pixel the distorted image "
                         "covers: RGB bilinear, other rasters nearest")
    if cap.per_frame_cameras:
        own = [cap.frame_intrinsics(i) for i in range(len(cap.frames))]
        camera["per_frame"] = {"n_frames_own_camera": sum(f.intrinsics is not None for f in cap.frames),
                               "fl_x_range": [min(c.fx for c in own), max(c.fx for c in own)],
                               "cx_range": [min(c.cx for c in own), max(c.cx for c in own)],
                               "how": "each frame resampled to this camera (narrowest view, median principal point): "
                                      "RGB bilinear, other rasters nearest"}
    depth = None
    if rs.depth_stats["pixels"]:
        st = rs.depth_stats
        depth = {"source_size": st["source_size"], "frames_upsampled": st["upsampled"],
                 "upsample": src.depth_upsample if st["upsampled"] else None,
                 "min_confidence": src.min_confidence if cap.has("confidence_file_path") else None,
                 "low_confidence_fraction": round(st["low_confidence_dropped"] / st["pixels"], 6)}
    manifest = Manifest(
        scene=scene, source="dir", n_frames=len(new.frames), n_train=len(new.train), n_test=len(new.test),
        width=new.intrinsics.width, height=new.intrinsics.height,
        has={"rgb": True, "depth": every("depth_file_path"), "mono_depth": every("mono_depth_file_path"),
             "mono_normal": every("mono_normal_file_path"), "detections": every("detections_path"),
             "sparse_points": has_sparse, "gt": has_gt},
        lacks={k: f"{path} has no {k}" for k in ("depth", "mono_depth", "mono_normal", "detections", "sparse_points")}
        | {"gt": f"{path} has no {capture_name('gt_parts')}"},
        details={"poses": {"kind": "given", "source": str(path)}, "intrinsics": camera}
        | ({"depth": depth} if depth is not None else {}),
        world_frame={"metric_scale": src.metric_scale, "gravity": src.gravity,
                     "how": f"as given by {path}; metric scale and gravity as stated in the scene config"},
        gt_part_kinds=gt_kinds,
    )
    metrics = {"n_frames": len(new.frames), "n_train": len(new.train), "n_test": len(new.test),
               "undistorted": rs.distorted, "resampled": rs.resampled}
    if depth is not None:
        metrics |= {"depth_frames_upsampled": depth["frames_upsampled"],
                    "depth_low_confidence_fraction": depth["low_confidence_fraction"]}
    return manifest, metrics
