"""Frames from a video file or an image folder; sharpness scoring and blur-aware selection."""

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

from drawer_lib.errors import CaptureError
from drawer_lib.io.images import read_rgb

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True)
class VideoFrame:
    index: int  # position in the source (video frame number or sorted image index)
    rgb: np.ndarray  # uint8 [H, W, 3]


def sharpness(rgb: np.ndarray) -> float:
    """Variance of the Laplacian of the grey image (higher = sharper)."""
    g = rgb.astype(np.float64).mean(-1)
    return float(ndimage.laplace(g).var())


def _resize(rgb: np.ndarray, max_size: int) -> np.ndarray:
    h, w = rgb.shape[:2]
    s = max_size / max(h, w)
    if s >= 1:
        return rgb
    size = (max(int(round(w * s)), 1), max(int(round(h * s)), 1))
    return np.asarray(Image.fromarray(rgb).resize(size, Image.LANCZOS))


def _pick(n: int, step: int, max_frames: int) -> list[int]:
    idx = list(range(0, n, step))
    if len(idx) > max_frames:
        idx = [idx[int(round(k))] for k in np.linspace(0, len(idx) - 1, max_frames)]
    return idx


def read_frames(path: Path, step: int = 1, max_frames: int = 10**9, max_size: int = 10**9) -> list[VideoFrame]:
    """Every ``step``-th frame (at most ``max_frames``, evenly spread) of a video file or of a
    folder of images (sorted by name), resized so the longer side is at most ``max_size``.

    Raises CaptureError naming the file when it cannot be decoded or has too few frames.
    """
    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise CaptureError(f"{path}: no images ({', '.join(IMAGE_SUFFIXES)})")
        out, size = [], None
        for k in _pick(len(files), step, max_frames):
            rgb = read_rgb(files[k])
            if size is not None and rgb.shape != size:
                raise CaptureError(f"{files[k]}: size {rgb.shape[1]}x{rgb.shape[0]} differs from the first image's")
            size = rgb.shape
            out.append(VideoFrame(k, _resize(rgb, max_size)))
        return out

    import imageio_ffmpeg

    if not path.is_file():
        raise CaptureError(f"{path}: video file is missing")
    try:
        n, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
        keep = set(_pick(n, step, max_frames))
        gen = imageio_ffmpeg.read_frames(str(path), pix_fmt="rgb24")
        meta = next(gen)
        w, h = meta["size"]
        out = []
        for k, buf in enumerate(gen):
            if k in keep:
                rgb = np.frombuffer(buf, np.uint8).reshape(h, w, 3)
                out.append(VideoFrame(k, _resize(rgb, max_size)))
        gen.close()
    except (OSError, RuntimeError, ValueError, StopIteration, KeyError) as e:
        raise CaptureError(f"{path}: cannot decode video ({type(e).__name__}: {e})") from e
    if not out:
        raise CaptureError(f"{path}: video has no frames")
    return out


def drop_blurriest(frames: list[VideoFrame], fraction: float) -> tuple[list[VideoFrame], list[int]]:
    """Drop the blurriest frame of every window of round(1 / fraction) consecutive frames,
    which removes ~``fraction`` of the frames while keeping the coverage even in time.
    Returns (kept frames, dropped source indices)."""
    if fraction <= 0 or len(frames) < 3:
        return list(frames), []
    win = max(int(round(1.0 / fraction)), 2)
    sharp = np.array([sharpness(f.rgb) for f in frames])
    drop = set()
    for start in range(0, len(frames), win):
        block = range(start, min(start + win, len(frames)))
        if len(block) == win:
            drop.add(min(block, key=lambda i: sharp[i]))
    return [f for i, f in enumerate(frames) if i not in drop], sorted(frames[i].index for i in drop)


def write_video(path: Path, frames: list[np.ndarray], fps: float = 10.0, quality: float = 8.0) -> None:
    """Encode uint8 [H, W, 3] frames as H.264 (even sizes; e.g. to test the video source)."""
    import imageio_ffmpeg

    h, w = frames[0].shape[:2]
    writer = imageio_ffmpeg.write_frames(str(path), (w, h), fps=fps, quality=quality, macro_block_size=2,
                                         pix_fmt_in="rgb24", pix_fmt_out="yuv420p", ffmpeg_log_level="error")
    writer.send(None)
    for f in frames:
        if f.shape[:2] != (h, w):
            raise ValueError("write_video: frames differ in size")
        writer.send(np.ascontiguousarray(f))
    writer.close()
