"""A contact sheet of a capture: one row per frame with every modality it has, side by side
(RGB | metric depth | monocular depth | monocular normals | detections | GT instances)."""

from pathlib import Path

import numpy as np

from drawer_lib.io.capture import Capture
from drawer_lib.io.images import read_u16
from drawer_lib.paths import capture_name


def colorize_depth(d: np.ndarray, lo: float | None = None, hi: float | None = None) -> np.ndarray:
    """[H, W] -> uint8 [H, W, 3] (near = bright); 0 or non-finite (invalid) pixels are black."""
    ok = np.isfinite(d) & (d > 0)
    if not ok.any():
        return np.zeros(d.shape + (3,), np.uint8)
    lo = float(np.percentile(d[ok], 1)) if lo is None else lo
    hi = float(np.percentile(d[ok], 99)) if hi is None else hi
    t = np.clip((hi - np.where(ok, d, hi)) / max(hi - lo, 1e-9), 0, 1)
    rgb = np.stack([0.25 + 0.75 * t, 0.15 + 0.85 * t**1.5, 0.45 * (1 - t) + 0.3 * t], -1)
    rgb[~ok] = 0
    return (rgb * 255).astype(np.uint8)


def colorize_labels(lab: np.ndarray, seed: int = 7) -> np.ndarray:
    """Integer label map -> uint8 colours (0 stays black)."""
    rng = np.random.default_rng(seed)
    pal = rng.integers(50, 256, size=(int(lab.max()) + 1, 3)).astype(np.uint8)
    pal[0] = 0
    return pal[lab.astype(np.int64)]


def contact_sheet(cap: Capture, frames: list[int]) -> np.ndarray:
    """uint8 [rows * H, cols * W, 3]; columns are the modalities present in the capture."""
    rows = []
    for i in frames:
        f = cap.frames[i]
        tiles = [cap.image(i)]
        if f.depth_file_path:
            tiles.append(colorize_depth(cap.depth(i)))
        if f.mono_depth_file_path:
            m = cap.mono_depth(i)
            tiles.append(colorize_depth(1.0 + m, 1.0, 2.0))
        if f.mono_normal_file_path:
            tiles.append(((cap.mono_normal(i) * 0.5 + 0.5) * 255).clip(0, 255).astype(np.uint8))
        if f.detections_path:
            tiles.append(colorize_labels(cap.detections(i)[0]))
        inst = cap.root / capture_name("gt_instances") / f"{f.stem}.png"
        if inst.is_file():
            tiles.append(colorize_labels(read_u16(inst), seed=3))
        rows.append(np.concatenate(tiles, 1))
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0))) for r in rows]
    return np.concatenate(rows, 0)


def save_contact_sheet(cap: Capture, frames: list[int], path: Path) -> None:
    from PIL import Image

    Image.fromarray(contact_sheet(cap, frames)).save(path)
