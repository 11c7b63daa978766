"""The capture format (docs/formats.md#capture): read, validate and write ``transforms.json`` and its files.

This module is the only place that converts the stored OpenGL camera-to-world matrices to the
library's OpenCV world-to-camera convention (:mod:`drawer_lib.geometry`).
"""

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from drawer_lib.errors import CaptureError
from drawer_lib.geometry.camera import Camera, Intrinsics, check_rigid, invert_rigid, opengl_to_opencv
from drawer_lib.io.images import (
    image_size,
    read_depth,
    read_json,
    read_npy,
    read_rgb,
    read_u16,
    write_json,
)
from drawer_lib.paths import capture_name

CAMERA_MODELS = ("PINHOLE", "OPENCV")
FRAME_FILE_KEYS = ("depth_file_path", "mono_depth_file_path", "mono_normal_file_path", "detections_path")
PER_FRAME_CAMERA_KEYS = ("camera_model", "fl_x", "fl_y", "cx", "cy", "w", "h", "k1", "k2", "k3", "k4", "p1", "p2")


@dataclass(frozen=True)
class Frame:
    """One posed frame. Paths are relative to the capture root, as stored."""

    file_path: str
    c2w_gl: np.ndarray  # [4, 4] OpenGL camera-to-world, as in transforms.json
    depth_file_path: str | None = None
    mono_depth_file_path: str | None = None
    mono_normal_file_path: str | None = None
    detections_path: str | None = None

    @property
    def stem(self) -> str:
        return Path(self.file_path).stem

    @property
    def c2w(self) -> np.ndarray:
        """[4, 4] OpenCV camera-to-world."""
        return opengl_to_opencv(self.c2w_gl)

    @property
    def w2c(self) -> np.ndarray:
        """[4, 4] OpenCV world-to-camera (what projections take)."""
        return invert_rigid(self.c2w)

    def to_json(self) -> dict:
        d = {"file_path": self.file_path, "transform_matrix": np.asarray(self.c2w_gl).tolist()}
        for k in FRAME_FILE_KEYS:
            v = getattr(self, k)
            if v is not None:
                d[k] = v
        return d


@dataclass
class Capture:
    """A validated capture folder. Indices in ``train``/``test`` refer to ``frames``."""

    root: Path
    intrinsics: Intrinsics
    frames: list[Frame]
    train: list[int]
    test: list[int]
    depth_unit_scale_factor: float = 0.001
    extra: dict = field(default_factory=dict)  # other top-level keys, kept on write

    # -- per-frame data ---------------------------------------------------------------------
    def image(self, i: int) -> np.ndarray:
        """uint8 [H, W, 3]."""
        return read_rgb(self.root / self.frames[i].file_path)

    def depth(self, i: int) -> np.ndarray:
        """float32 [H, W] metric z-depth in metres, 0 = invalid."""
        p = self._path(i, "depth_file_path")
        return read_depth(p, self.depth_unit_scale_factor)

    def mono_depth(self, i: int) -> np.ndarray:
        """float32 [H, W] relative depth (unknown per-frame scale and shift)."""
        H, W = self.intrinsics.height, self.intrinsics.width
        return read_npy(self._path(i, "mono_depth_file_path"), np.float32, (H, W))

    def mono_normal(self, i: int) -> np.ndarray:
        """float32 [H, W, 3] unit normals in the OpenCV camera frame."""
        H, W = self.intrinsics.height, self.intrinsics.width
        return read_npy(self._path(i, "mono_normal_file_path"), np.float16, (H, W, 3)).astype(np.float32)

    def detections(self, i: int) -> tuple[np.ndarray, list[dict]]:
        """(uint16 [H, W] instance ids local to the frame, [{"id", "label", "score"}])."""
        p = self._path(i, "detections_path")
        return read_u16(p), read_json(p.with_suffix(".json"))

    def _path(self, i: int, key: str) -> Path:
        rel = getattr(self.frames[i], key)
        if rel is None:
            raise CaptureError(f"{self.root / capture_name('transforms')}: frame {self.frames[i].file_path} has no {key}")
        return self.root / rel

    # -- whole-capture views ------------------------------------------------------------------
    def has(self, key: str) -> bool:
        """True when every frame has ``key`` (one of FRAME_FILE_KEYS)."""
        return len(self.frames) > 0 and all(getattr(f, key) is not None for f in self.frames)

    def camera(self, i: int) -> Camera:
        """The posed camera of frame ``i``."""
        return Camera(self.intrinsics, self.frames[i].w2c)

    def cameras(self, frames: list[int]) -> list[Camera]:
        return [self.camera(i) for i in frames]

    def w2c_all(self) -> np.ndarray:
        """[C, 4, 4] OpenCV world-to-camera of all frames."""
        return np.stack([f.w2c for f in self.frames])

    def to_json(self) -> dict:
        it = self.intrinsics
        d = {
            "camera_model": "OPENCV" if it.has_distortion else "PINHOLE",
            "fl_x": it.fx, "fl_y": it.fy, "cx": it.cx, "cy": it.cy, "w": it.width, "h": it.height,
        }
        if it.has_distortion:
            d.update(dict(zip(("k1", "k2", "p1", "p2"), it.dist)))
        d["depth_unit_scale_factor"] = self.depth_unit_scale_factor
        d.update(self.extra)
        d["frames"] = [f.to_json() for f in self.frames]
        d["train_filenames"] = [self.frames[i].file_path for i in self.train]
        d["test_filenames"] = [self.frames[i].file_path for i in self.test]
        return d


def write_transforms(capture: Capture) -> None:
    write_json(capture.root / capture_name("transforms"), capture.to_json())


def _num(d: dict, key: str, src: str, positive: bool = False) -> float:
    if key not in d:
        raise CaptureError(f"{src}: missing {key!r}")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise CaptureError(f"{src}: {key} = {v!r} is not a finite number")
    if positive and v <= 0:
        raise CaptureError(f"{src}: {key} = {v!r} must be positive")
    return float(v)


def split_every(n: int, test_every: int) -> tuple[list[int], list[int]]:
    """Every ``test_every``-th frame (starting at index test_every // 2) is a test frame."""
    if test_every < 2:
        raise ValueError(f"test_every must be >= 2, got {test_every}")
    test = [i for i in range(n) if i % test_every == test_every // 2]
    train = [i for i in range(n) if i % test_every != test_every // 2]
    return train, test


def load_capture(root: Path, check_files: bool = True, default_test_every: int | None = None,
                 progress: bool = False) -> Capture:
    """Read and validate a capture folder.

    Checks the camera model and intrinsics, that every transform is a finite rigid motion, that
    file paths are unique and present, that train and test splits are non-empty and name known
    frames and, with ``check_files``, that every image decodes with the stated size and every
    depth / mono / detection file has the right kind and shape. Without split keys in the file,
    ``default_test_every`` builds one (else it is an error).

    Raises CaptureError naming the file or frame at fault.
    """
    root = Path(root)
    tf = root / capture_name("transforms")
    d = read_json(tf)
    src = str(tf)
    if not isinstance(d, dict):
        raise CaptureError(f"{src}: expected a JSON object")
    model = d.get("camera_model", "PINHOLE")
    if model not in CAMERA_MODELS:
        raise CaptureError(f"{src}: camera_model {model!r} is not one of {CAMERA_MODELS}")
    fx, fy = _num(d, "fl_x", src, True), _num(d, "fl_y", src, True)
    cx, cy = _num(d, "cx", src), _num(d, "cy", src)
    w, h = _num(d, "w", src, True), _num(d, "h", src, True)
    if w != int(w) or h != int(h):
        raise CaptureError(f"{src}: image size w={w}, h={h} is not integral")
    dist = tuple(_num(d, k, src) if k in d else 0.0 for k in ("k1", "k2", "p1", "p2"))
    for k in ("k3", "k4", "k5", "k6"):
        if k in d and _num(d, k, src) != 0.0:
            raise CaptureError(f"{src}: {k} = {d[k]}: only the OPENCV model (k1, k2, p1, p2) is supported")
    if model == "PINHOLE" and any(dist):
        raise CaptureError(f"{src}: camera_model PINHOLE with distortion {dist}; use OPENCV")
    intr = Intrinsics(fx, fy, cx, cy, int(w), int(h), dist)  # type: ignore[arg-type]
    scale = _num(d, "depth_unit_scale_factor", src, True) if "depth_unit_scale_factor" in d else 0.001

    raw_frames = d.get("frames")
    if not isinstance(raw_frames, list) or not raw_frames:
        raise CaptureError(f"{src}: no frames")
    frames, seen = [], {}
    for k, fr in enumerate(raw_frames):
        fp = fr.get("file_path") if isinstance(fr, dict) else None
        if not isinstance(fp, str) or not fp:
            raise CaptureError(f"{src}: frames[{k}] has no file_path")
        if fp in seen:
            raise CaptureError(f"{src}: frames[{k}] repeats file_path {fp!r}")
        seen[fp] = k
        try:
            T = np.asarray(fr["transform_matrix"], dtype=np.float64)
        except (KeyError, ValueError, TypeError) as e:
            raise CaptureError(f"{src}: frame {fp}: missing or malformed transform_matrix") from e
        why = check_rigid(T)
        if why:
            raise CaptureError(f"{src}: frame {fp}: transform_matrix {why}")
        top = {"camera_model": model, **{k: d.get(k, 0.0) for k in ("k1", "k2", "k3", "k4", "p1", "p2")}}
        own = {k: fr[k] for k in PER_FRAME_CAMERA_KEYS if k in fr and fr[k] != top.get(k, d.get(k))}
        if own:
            raise CaptureError(f"{src}: frame {fp} has its own camera {own}; one camera for all frames is supported")
        frames.append(Frame(fp, T, *(fr.get(key) for key in FRAME_FILE_KEYS)))

    extra = {k: v for k, v in d.items() if k not in (
        "camera_model", "fl_x", "fl_y", "cx", "cy", "w", "h", "k1", "k2", "p1", "p2",
        "depth_unit_scale_factor", "frames", "train_filenames", "test_filenames")}

    if "train_filenames" in d or "test_filenames" in d:
        splits = []
        for key in ("train_filenames", "test_filenames"):
            names = d.get(key)
            if not isinstance(names, list) or not names:
                raise CaptureError(f"{src}: {key} is empty or missing")
            idx = []
            for n in names:
                if n not in seen:
                    raise CaptureError(f"{src}: {key} names {n!r}, which is not a frame")
                idx.append(seen[n])
            splits.append(idx)
        train, test = splits
    elif default_test_every is not None:
        train, test = split_every(len(frames), default_test_every)
        if not train or not test:
            raise CaptureError(f"{src}: {len(frames)} frames are too few for a train/test split")
    else:
        raise CaptureError(f"{src}: no train_filenames/test_filenames")

    cap = Capture(root, intr, frames, train, test, scale, extra)
    if check_files:
        validate_files(cap, progress=progress)
    return cap


def validate_files(cap: Capture, progress: bool = False) -> None:
    """Decode every file a frame names and check kinds and sizes (CaptureError on the first fault)."""
    W, H = cap.intrinsics.width, cap.intrinsics.height
    for i, fr in enumerate(tqdm(cap.frames, desc="validate capture", disable=not progress, leave=False)):
        size = image_size(cap.root / fr.file_path)
        if size != (W, H):
            raise CaptureError(f"{cap.root / fr.file_path}: size {size[0]}x{size[1]}, {capture_name('transforms')} says {W}x{H}")
        if fr.depth_file_path is not None:
            dep = cap.depth(i)
            if dep.shape != (H, W):
                raise CaptureError(f"{cap.root / fr.depth_file_path}: size {dep.shape[1]}x{dep.shape[0]}, expected {W}x{H}")
        if fr.mono_depth_file_path is not None:
            cap.mono_depth(i)
        if fr.mono_normal_file_path is not None:
            n = cap.mono_normal(i)
            norms = np.linalg.norm(n, axis=-1)
            if np.abs(norms - 1).max() > 0.05:
                raise CaptureError(f"{cap.root / fr.mono_normal_file_path}: normals are not unit length")
        if fr.detections_path is not None:
            lab, dets = cap.detections(i)
            p = cap.root / fr.detections_path
            if lab.shape != (H, W):
                raise CaptureError(f"{p}: size {lab.shape[1]}x{lab.shape[0]}, expected {W}x{H}")
            if not isinstance(dets, list) or not all(isinstance(x, dict) and {"id", "label", "score"} <= x.keys() for x in dets):
                raise CaptureError(f"{p.with_suffix('.json')}: expected a list of {{id, label, score}}")
            listed = {int(x["id"]) for x in dets}
            unknown = set(np.unique(lab).tolist()) - listed - {0}
            if unknown:
                raise CaptureError(f"{p}: ids {sorted(unknown)} are not listed in {p.with_suffix('.json').name}")
