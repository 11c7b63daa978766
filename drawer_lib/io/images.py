"""Image and array files of the capture format: RGB PNG, 16-bit depth PNG, 16-bit label PNG, npy.

Every reader raises :class:`CaptureError` naming the file when it is missing, unreadable or of the
wrong kind, so that callers never see a half-decoded array.
"""

import json
import math
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from drawer_lib.errors import CaptureError
from drawer_lib.io.atomic import atomic_write_text


def _open(path: Path) -> Image.Image:
    path = Path(path)
    if not path.is_file():
        raise CaptureError(f"{path}: file is missing")
    try:
        img = Image.open(path)
        img.load()
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as e:
        raise CaptureError(f"{path}: unreadable image ({e})") from e
    return img


def image_size(path: Path) -> tuple[int, int]:
    """(width, height) of an image file, decoding it fully to catch truncated files."""
    return _open(path).size


def read_rgb(path: Path) -> np.ndarray:
    """uint8 [H, W, 3]; grey or RGBA images are converted to RGB."""
    img = _open(path)
    if img.mode != "RGB":
        img = img.convert("RGB")
    return np.asarray(img, dtype=np.uint8).copy()


def write_rgb(path: Path, rgb: np.ndarray) -> None:
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"write_rgb: expected uint8 [H, W, 3], got {rgb.dtype} {rgb.shape}")
    Image.fromarray(rgb).save(path, compress_level=6)


def read_u16(path: Path) -> np.ndarray:
    """uint16 [H, W] from a 16-bit single-channel PNG (error for any other kind of image)."""
    img = _open(path)
    if img.mode not in ("I;16", "I;16B", "I;16L", "I"):
        raise CaptureError(f"{path}: expected a 16-bit single-channel PNG, got mode {img.mode!r}")
    a = np.asarray(img)
    if a.dtype != np.uint16:
        if a.min() < 0 or a.max() > 65535:
            raise CaptureError(f"{path}: values outside the 16-bit range")
        a = a.astype(np.uint16)
    return a.copy()


def read_u8(path: Path) -> np.ndarray:
    """uint8 [H, W] from an 8-bit single-channel image (error for any other kind of image)."""
    img = _open(path)
    if img.mode != "L":
        raise CaptureError(f"{path}: expected an 8-bit single-channel image, got mode {img.mode!r}")
    return np.asarray(img, dtype=np.uint8).copy()


def write_u16(path: Path, a: np.ndarray) -> None:
    if a.dtype != np.uint16 or a.ndim != 2:
        raise ValueError(f"write_u16: expected uint16 [H, W], got {a.dtype} {a.shape}")
    Image.fromarray(a).save(path, compress_level=6)


def read_depth(path: Path, unit_scale: float) -> np.ndarray:
    """Metric z-depth float32 [H, W] in metres; 0 marks invalid pixels (never NaN)."""
    return read_u16(path).astype(np.float32) * np.float32(unit_scale)


def write_depth(path: Path, depth_m: np.ndarray, unit_scale: float) -> None:
    """Store metric depth as uint16 multiples of ``unit_scale``; non-finite, <= 0 or out of
    range values become 0 (invalid)."""
    d = np.asarray(depth_m, np.float64) / unit_scale
    ok = np.isfinite(d) & (d > 0) & (d < 65535.5)
    q = np.zeros(d.shape, np.uint16)
    q[ok] = np.round(d[ok]).astype(np.uint16)
    write_u16(path, q)


def read_npy(path: Path, dtype: type, shape: tuple[int, ...]) -> np.ndarray:
    """Load an .npy file and check dtype and shape (``-1`` in ``shape`` matches any size)."""
    path = Path(path)
    if not path.is_file():
        raise CaptureError(f"{path}: file is missing")
    try:
        a = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as e:
        raise CaptureError(f"{path}: unreadable array ({e})") from e
    if a.dtype != dtype:
        raise CaptureError(f"{path}: dtype {a.dtype}, expected {np.dtype(dtype)}")
    if len(a.shape) != len(shape) or any(s not in (-1, t) for s, t in zip(shape, a.shape)):
        raise CaptureError(f"{path}: shape {a.shape}, expected {shape}")
    if not np.all(np.isfinite(a)):
        raise CaptureError(f"{path}: contains non-finite values")
    return a


def read_json(path: Path):
    path = Path(path)
    if not path.is_file():
        raise CaptureError(f"{path}: file is missing")
    try:
        return json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CaptureError(f"{path}: not valid JSON ({e})") from e


# Every float written to JSON is rounded to this many decimal places (1e-10: far below any
# precision a capture, a mesh or a metric has). Float64 results can differ in their last bits
# between machines and thread counts (SIMD paths, summation order); rounded, the files are
# byte-identical, so DVC's hashes and a shared cache mean what they should.
FLOAT_DECIMALS = 10


def round_floats(obj, decimals: int = FLOAT_DECIMALS):
    """``obj`` with every float rounded to ``decimals`` places (-0.0 written as 0.0); tuples
    become lists, dicts and lists are copied, numpy scalars (``np.bool_``, ``np.float32``, ...)
    become Python ones; NaN and inf are left for the writer to refuse.

    >>> round_floats({"a": [0.1 + 0.2, -1e-17], "b": (1, 2.5), "c": np.float64(1) > 0})
    {'a': [0.3, 0.0], 'b': [1, 2.5], 'c': True}
    """
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        return round(obj, decimals) + 0.0 if math.isfinite(obj) else obj
    if isinstance(obj, dict):
        return {k: round_floats(v, decimals) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [round_floats(v, decimals) for v in obj]
    return obj


def write_json(path: Path, obj, indent: int | None = 2) -> None:
    """Write JSON with floats rounded to :data:`FLOAT_DECIMALS` places (so the same values give
    the same bytes on every machine). NaN and inf are refused: they are not JSON and must not
    travel downstream. Written whole or not at all (:func:`drawer_lib.io.atomic.atomic_write_text`)."""
    atomic_write_text(path, json.dumps(round_floats(obj), indent=indent, allow_nan=False) + "\n")
