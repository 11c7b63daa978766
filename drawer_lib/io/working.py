"""A capture read at a stage's working resolution.

A phone writes 1920 x 1440 images; the SDF's rays, the perception's rendered views and the
Gaussians' training images do not need all of them. Each such stage has a ``max_side`` (pixels
of the longer image side; ``null`` keeps the capture's size) and reads the capture through
:func:`at_working_size`, which divides the images by the smallest integer factor ``f`` that
brings the longer side to at most ``max_side``. Every frame is read from disk and reduced on its
own, so no full-size image is held longer than its reduction takes.

How each modality is reduced, per block of ``f`` x ``f`` pixels:

- colour: the box mean (rounded to uint8);
- metric and relative depth: the lower median of the block's valid (> 0, finite) values, 0
  where fewer than a quarter are valid. A median is one of the samples, so a block across a
  depth edge keeps one side's depth instead of a flying point between the two;
- normals: the box mean, renormalised;
- instance maps: the block's centre pixel (ids are labels, not numbers); detections whose ids
  no longer appear are dropped from the frame's list.

The camera is exact for the pixel convention of :class:`~drawer_lib.geometry.camera.Intrinsics`
(the image plane's corner at (0, 0)): focal lengths and principal point divide by ``f``; the
right and bottom remainders (``W % f``, ``H % f`` pixels) are cropped.
"""

from dataclasses import dataclass, replace

import numpy as np

from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Intrinsics
from drawer_lib.io.capture import Capture


def check_max_side(key: str, max_side: int | None) -> None:
    """A config's ``max_side`` is null or at least 8 px (``key`` names it in the error)."""
    if max_side is not None and max_side < 8:
        raise ConfigError(f"{key} = {max_side} must be >= 8 px or null (a working image needs 8 px on its longer side)")


def working_factor(width: int, height: int, max_side: int | None) -> int:
    """The smallest integer ``f >= 1`` with ``max(width, height) / f <= max_side`` (1 for None).

    >>> working_factor(1920, 1440, 640), working_factor(200, 150, 640), working_factor(1281, 960, 640)
    (3, 1, 3)
    """
    check_max_side("max_side", max_side)
    if max_side is None:
        return 1
    return max(1, -(-max(width, height) // int(max_side)))


def scale_intrinsics(it: Intrinsics, f: int) -> Intrinsics:
    """The camera of an image reduced by ``f`` x ``f`` blocks, remainders cropped (exact).

    >>> scale_intrinsics(Intrinsics(100.0, 100.0, 64.0, 48.0, 129, 96), 2)
    Intrinsics(fx=50.0, fy=50.0, cx=32.0, cy=24.0, width=64, height=48, dist=(0.0, 0.0, 0.0, 0.0))
    """
    if f == 1:
        return it
    return Intrinsics(it.fx / f, it.fy / f, it.cx / f, it.cy / f, it.width // f, it.height // f, it.dist)


def _block_grid(a: np.ndarray, f: int) -> tuple[int, int]:
    """(H // f, W // f) of ``a`` [H, W, ...]; an error when a side would be empty."""
    h, w = a.shape[0] // f, a.shape[1] // f
    if h == 0 or w == 0:
        raise ConfigError(f"a working factor of {f} leaves nothing of a {a.shape[1]} x {a.shape[0]} image")
    return h, w


def _blocks(a: np.ndarray, f: int) -> np.ndarray:
    """[H, W, ...] -> [H // f, W // f, f * f, ...] (remainders cropped)."""
    h, w = _block_grid(a, f)
    b = a[: h * f, : w * f].reshape(h, f, w, f, *a.shape[2:])
    b = np.moveaxis(b, 2, 1)  # [h, w, f, f, ...]
    return b.reshape(h, w, f * f, *a.shape[2:])


def box_mean(a: np.ndarray, f: int) -> np.ndarray:
    """float32 [H // f, W // f, ...]: the mean of each ``f`` x ``f`` block of ``a`` [H, W, ...]."""
    return _blocks(a.astype(np.float32, copy=False), f).mean(2, dtype=np.float64).astype(np.float32)


def block_median(a: np.ndarray, f: int, min_valid: float = 0.25) -> np.ndarray:
    """float32 [H // f, W // f]: the lower median of each block's valid (> 0, finite) values of
    ``a`` [H, W], 0 where fewer than ``min_valid`` of the block's pixels are valid."""
    b = _blocks(a.astype(np.float32, copy=False), f)
    ok = np.isfinite(b) & (b > 0)
    n = ok.sum(-1)
    s = np.sort(np.where(ok, b, np.inf), axis=-1)
    k = np.maximum(n - 1, 0) // 2
    out = np.take_along_axis(s, k[..., None], -1)[..., 0]
    return np.where(n >= max(1, int(np.ceil(min_valid * f * f))), out, 0.0).astype(np.float32)


def block_centre(a: np.ndarray, f: int) -> np.ndarray:
    """[H // f, W // f, ...]: each block's pixel at (f // 2, f // 2) (labels: nearest, no mixing)."""
    h, w = _block_grid(a, f)
    return np.ascontiguousarray(a[f // 2: h * f: f, f // 2: w * f: f])


@dataclass
class WorkingCapture(Capture):
    """A :class:`Capture` whose per-frame data and cameras are at ``1 / factor`` of ``full``'s.

    Frame files, splits and overlays are ``full``'s; everything a method reads through
    ``image``, ``depth``, ``mono_depth``, ``mono_normal``, ``detections``, ``intrinsics`` and
    ``camera`` is at the working size. ``depth_raw`` and ``confidence`` stay at the depth's
    own size, as stored.
    """

    full: Capture | None = None
    factor: int = 1

    def image(self, i: int) -> np.ndarray:
        return np.clip(np.rint(box_mean(self.full.image(i), self.factor)), 0, 255).astype(np.uint8)

    def depth(self, i: int) -> np.ndarray:
        return block_median(self.full.depth(i), self.factor)

    def mono_depth(self, i: int) -> np.ndarray:
        return block_median(self.full.mono_depth(i), self.factor)

    def mono_normal(self, i: int) -> np.ndarray:
        n = box_mean(self.full.mono_normal(i), self.factor)
        norm = np.linalg.norm(n, axis=-1, keepdims=True)
        return np.where(norm > 1e-6, n / np.maximum(norm, 1e-6), np.array([0, 0, -1], np.float32)).astype(np.float32)

    def detections(self, i: int) -> tuple[np.ndarray, list[dict]]:
        labels, rows = self.full.detections(i)
        labels = block_centre(labels, self.factor)
        present = set(np.unique(labels).tolist())
        return labels, [r for r in rows if int(r["id"]) in present]


def at_working_size(cap: Capture, max_side: int | None) -> Capture:
    """``cap`` read at the working size for ``max_side`` (``cap`` itself when it already fits)."""
    if isinstance(cap, WorkingCapture):
        cap = cap.full
    f = working_factor(cap.intrinsics.width, cap.intrinsics.height, max_side)
    if f == 1:
        return cap
    frames = [fr if fr.intrinsics is None else replace(fr, intrinsics=scale_intrinsics(fr.intrinsics, f))
              for fr in cap.frames]
    return WorkingCapture(root=cap.root, intrinsics=scale_intrinsics(cap.intrinsics, f), frames=frames,
                          train=list(cap.train), test=list(cap.test),
                          depth_unit_scale_factor=cap.depth_unit_scale_factor, extra=dict(cap.extra),
                          overlays=list(cap.overlays), full=cap, factor=f)


def working_size_metrics(cap: Capture) -> dict:
    """What a stage records of the size it worked at: ``working_size`` [W, H] and ``working_factor``."""
    return {"working_size": [cap.intrinsics.width, cap.intrinsics.height],
            "working_factor": cap.factor if isinstance(cap, WorkingCapture) else 1}
