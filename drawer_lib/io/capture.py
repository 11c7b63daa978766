"""The capture format (docs/formats.md#capture): read, validate and write ``transforms.json`` and its files.

This module is the only place that converts the stored OpenGL camera-to-world matrices to the
library's OpenCV world-to-camera convention (:mod:`drawer_lib.geometry`).
"""

import math
from dataclasses import dataclass, field, replace
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
    read_u8,
    read_u16,
    write_json,
)
from drawer_lib.io.rgbd import confidence_levels, upsample_depth
from drawer_lib.paths import capture_name

CAMERA_MODELS = ("PINHOLE", "OPENCV")
FRAME_FILE_KEYS = ("depth_file_path", "mono_depth_file_path", "mono_normal_file_path", "detections_path",
                   "confidence_file_path")
PINHOLE_KEYS = ("fl_x", "fl_y", "cx", "cy", "w", "h")


@dataclass(frozen=True)
class Frame:
    """One posed frame. Paths are relative to the capture root, as stored."""

    file_path: str
    c2w_gl: np.ndarray  # [4, 4] OpenGL camera-to-world, as in transforms.json
    depth_file_path: str | None = None
    mono_depth_file_path: str | None = None
    mono_normal_file_path: str | None = None
    detections_path: str | None = None
    confidence_file_path: str | None = None  # the depth's confidence (8-bit, at the depth's size)
    intrinsics: Intrinsics | None = None  # the frame's own camera when the file gives one per frame

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
        if self.intrinsics is not None:
            it = self.intrinsics
            d.update({"fl_x": it.fx, "fl_y": it.fy, "cx": it.cx, "cy": it.cy, "w": it.width, "h": it.height})
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
    overlays: list[dict] = field(default_factory=list)  # stage outputs read in place of optional files (io/overlay.py)

    # -- per-frame data ---------------------------------------------------------------------
    def image(self, i: int) -> np.ndarray:
        """uint8 [H, W, 3]."""
        return read_rgb(self.root / self.frames[i].file_path)

    def depth(self, i: int) -> np.ndarray:
        """float32 [H, W] metric z-depth in metres, 0 = invalid; a depth map smaller than the
        image (a phone's LiDAR) is brought to the image's size by nearest neighbour (the
        capture stage's import does it once, edge-aware: :mod:`drawer_lib.io.rgbd`)."""
        d = self.depth_raw(i)
        it = self.frame_intrinsics(i)
        if d.shape != (it.height, it.width):
            d = upsample_depth(d, (it.height, it.width), method="nearest")
        return d

    def depth_raw(self, i: int) -> np.ndarray:
        """float32 [h, w] metric z-depth in metres as stored (0 = invalid), at its own size."""
        return read_depth(self._path(i, "depth_file_path"), self.depth_unit_scale_factor)

    def confidence(self, i: int) -> np.ndarray:
        """uint8 [h, w] confidence levels of frame ``i``'s depth, at the depth's size: 0 low,
        1 medium, 2 high (Polycam's 0 / 127 / 255 read as such)."""
        p = self._path(i, "confidence_file_path")
        return confidence_levels(read_u8(p), str(p))

    def frame_intrinsics(self, i: int) -> Intrinsics:
        """Frame ``i``'s camera: its own when the file gives one per frame, else the capture's."""
        return self.frames[i].intrinsics or self.intrinsics

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

    @property
    def per_frame_cameras(self) -> bool:
        """True when some frame's camera differs from the capture's (:attr:`intrinsics`)."""
        return any(f.intrinsics is not None and f.intrinsics != self.intrinsics for f in self.frames)

    def camera(self, i: int) -> Camera:
        """The posed camera of frame ``i``."""
        return Camera(self.frame_intrinsics(i), self.frames[i].w2c)

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


MAX_UNCOVERED = 0.01  # a frame's own camera may leave this fraction of the capture camera's width / height unseen


def reference_camera(cams: list[Intrinsics], top: Intrinsics | None, src: str, names: list[str]) -> Intrinsics:
    """The capture's one camera, given each frame's: theirs when they agree; else the top-level
    camera when the file has one, or the camera of the frames' common size with the median
    principal point and the largest focal lengths (the narrowest view, which every frame
    covers), to which the ``dir`` import resamples each frame. A frame whose own camera leaves
    more than ``MAX_UNCOVERED`` of that view unseen, or frames of different sizes, are errors
    naming them."""
    if all(c == cams[0] for c in cams):
        return cams[0]
    sizes = {(c.width, c.height) for c in cams}
    if len(sizes) > 1:
        bad = [n for n, c in zip(names, cams) if (c.width, c.height) != (cams[0].width, cams[0].height)]
        raise CaptureError(f"{src}: frames differ in image size {sorted(sizes)} ({bad[0]} and others); one "
                           "size for all frames is supported")
    if top is not None:
        ref = top
    else:
        med = lambda a: float(np.median([getattr(c, a) for c in cams]))  # noqa: E731
        ref = Intrinsics(max(c.fx for c in cams), max(c.fy for c in cams), med("cx"), med("cy"), cams[0].width,
                         cams[0].height, cams[0].dist)
    for n, c in zip(names, cams):
        # the reference image's border, seen through the frame's camera (pixels, continuous)
        xs = (np.array([0.0, ref.width]) - ref.cx) / ref.fx * c.fx + c.cx
        ys = (np.array([0.0, ref.height]) - ref.cy) / ref.fy * c.fy + c.cy
        out_x = max(0.0, -xs[0]) + max(0.0, xs[1] - c.width)
        out_y = max(0.0, -ys[0]) + max(0.0, ys[1] - c.height)
        if out_x > MAX_UNCOVERED * ref.width or out_y > MAX_UNCOVERED * ref.height:
            raise CaptureError(f"{src}: frame {n}'s camera (fl_x {c.fx:g}, fl_y {c.fy:g}, cx {c.cx:g}, cy {c.cy:g}) "
                               f"leaves {out_x:.1f} x {out_y:.1f} px of the capture's camera (fl_x {ref.fx:g}, "
                               f"fl_y {ref.fy:g}, cx {ref.cx:g}, cy {ref.cy:g}) unseen (at most {MAX_UNCOVERED:.0%}); "
                               "drop or crop that frame")
    return ref


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
    dist = tuple(_num(d, k, src) if k in d else 0.0 for k in ("k1", "k2", "p1", "p2"))
    for k in ("k3", "k4", "k5", "k6"):
        if k in d and _num(d, k, src) != 0.0:
            raise CaptureError(f"{src}: {k} = {d[k]}: only the OPENCV model (k1, k2, p1, p2) is supported")
    if model == "PINHOLE" and any(dist):
        raise CaptureError(f"{src}: camera_model PINHOLE with distortion {dist}; use OPENCV")
    scale = _num(d, "depth_unit_scale_factor", src, True) if "depth_unit_scale_factor" in d else 0.001
    top_cam = all(k in d for k in PINHOLE_KEYS)  # else every frame carries its own (Polycam, ARKit)

    def pinhole(obj: dict, where: str) -> Intrinsics:
        fx, fy = _num(obj, "fl_x", where, True), _num(obj, "fl_y", where, True)
        cx, cy = _num(obj, "cx", where), _num(obj, "cy", where)
        w, h = _num(obj, "w", where, True), _num(obj, "h", where, True)
        if w != int(w) or h != int(h):
            raise CaptureError(f"{where}: image size w={w}, h={h} is not integral")
        return Intrinsics(fx, fy, cx, cy, int(w), int(h), dist)  # type: ignore[arg-type]

    top = pinhole(d, src) if top_cam else None

    raw_frames = d.get("frames")
    if not isinstance(raw_frames, list) or not raw_frames:
        raise CaptureError(f"{src}: no frames")
    frames, seen = [], {}
    lens = {"camera_model": model, **{k: d.get(k, 0.0) for k in ("k1", "k2", "k3", "k4", "p1", "p2")}}
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
        own_lens = {k: fr[k] for k in lens if k in fr and fr[k] != lens[k]}
        if own_lens:
            raise CaptureError(f"{src}: frame {fp} has its own lens model {own_lens}; one lens model (camera_model, "
                               "distortion) for all frames is supported")
        if top is None:
            missing = [k for k in PINHOLE_KEYS if k not in fr]
            if missing:
                raise CaptureError(f"{src}: missing {missing[0]!r} (neither at the top level nor in frame {fp})")
            cam = pinhole(fr, f"{src}: frame {fp}")
        else:
            cam = pinhole({**{k: d[k] for k in PINHOLE_KEYS}, **{k: fr[k] for k in PINHOLE_KEYS if k in fr}},
                          f"{src}: frame {fp}")
        frames.append(Frame(fp, T, *(fr.get(key) for key in FRAME_FILE_KEYS), intrinsics=cam))
    intr = reference_camera([f.intrinsics for f in frames], top, src, [f.file_path for f in frames])
    frames = [f if f.intrinsics != intr else replace(f, intrinsics=None) for f in frames]

    extra = {k: v for k, v in d.items() if k not in (
        "camera_model", "fl_x", "fl_y", "cx", "cy", "w", "h", "k1", "k2", "k3", "k4", "p1", "p2",
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
    for i, fr in enumerate(tqdm(cap.frames, desc="validate capture", disable=not progress, leave=False)):
        it = cap.frame_intrinsics(i)
        W, H = it.width, it.height
        size = image_size(cap.root / fr.file_path)
        if size != (W, H):
            raise CaptureError(f"{cap.root / fr.file_path}: size {size[0]}x{size[1]}, {capture_name('transforms')} says {W}x{H}")
        if fr.depth_file_path is not None:
            h, w = cap.depth_raw(i).shape
            if (h, w) != (H, W) and (h > H or w > W or abs(w * H - h * W) > 0.01 * W * H):
                raise CaptureError(f"{cap.root / fr.depth_file_path}: size {w}x{h}; a depth map must have the image's "
                                   f"size {W}x{H} or be smaller with its aspect (a phone's LiDAR: 256x192 beside 1024x768)")
            if fr.confidence_file_path is not None:
                c = cap.confidence(i)
                if c.shape != (h, w):
                    raise CaptureError(f"{cap.root / fr.confidence_file_path}: size {c.shape[1]}x{c.shape[0]}, expected "
                                       f"the depth's {w}x{h}")
        elif fr.confidence_file_path is not None:
            raise CaptureError(f"{cap.root / capture_name('transforms')}: frame {fr.file_path} has a "
                               "confidence_file_path but no depth_file_path")
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
