"""A capture written as a phone app leaves it: ``ns-process-data polycam --use-depth`` (what the
``dir`` source imports). From a rendered capture: a camera per frame (odd frames seen through a
slightly wider lens), JPEG frames with gaps in their numbering (frames dropped as blurry),
LiDAR depth at 1 / ``factor`` of the RGB's size in millimetres, Polycam's 0 / 127 / 255
confidence maps, no train / test lists; the ground truth copied under the new frame names so the
twin can be scored. Simulated input: the renderer's depth, sampled as a time-of-flight sensor
samples it."""

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
from PIL import Image

from drawer_lib.geometry.distortion import remap, undistortion_map
from drawer_lib.io.capture import load_capture
from drawer_lib.io.images import read_u16, write_u16
from drawer_lib.paths import capture_name


def lidar(depth: np.ndarray, factor: int = 4) -> np.ndarray:
    """The sensor's map of a depth [H, W] (H, W multiples of ``factor`` >= 2): one sample per
    cell of ``factor`` x ``factor`` pixels, the mean of its central 2 x 2 pixels (a sample
    straddling a depth edge mixes the two, as real time-of-flight pixels do)."""
    c = factor // 2
    return (depth[c - 1::factor, c - 1::factor] + depth[c - 1::factor, c::factor]
            + depth[c::factor, c - 1::factor] + depth[c::factor, c::factor]) / 4


def write_polycam(src: Path, out: Path, factor: int = 4, drift: float = 0.996, drop_every: int = 7,
                  confidence: bool = True, progress=lambda it, **kw: it) -> None:
    """The capture at ``src`` written into ``out`` as ns-process-data writes a Polycam capture
    (module doc): frame k is named ``frame_<k + 1:05d>``, frames with k % ``drop_every`` == 3 are
    left out, odd frames' focal length is ``drift`` x the capture's."""
    cap = load_capture(src)
    it = cap.intrinsics
    if it.width % factor or it.height % factor:
        raise ValueError(f"{src}: {it.width}x{it.height} is not a multiple of the LiDAR factor {factor}")
    for d in ("images", "depth", "confidence"):
        (out / d).mkdir(parents=True, exist_ok=True)
    gt_src = src / capture_name("gt")
    if gt_src.is_dir():
        shutil.copytree(gt_src, out / "gt", ignore=shutil.ignore_patterns("instances"))
        (out / capture_name("gt_instances")).mkdir(parents=True, exist_ok=True)
    frames = []
    for k in progress(range(len(cap.frames)), desc="phone capture", total=len(cap.frames)):
        fr = cap.frames[k]
        if k % drop_every == 3:
            continue
        n = f"frame_{k + 1:05d}"
        img, dep = cap.image(k), cap.depth(k)
        inst_p = src / capture_name("gt_instances") / f"{fr.stem}.png"
        inst = read_u16(inst_p) if inst_p.is_file() else None
        if k % 2:  # seen through the frame's own camera (a slightly wider view)
            own = dataclasses.replace(it, fx=it.fx * drift, fy=it.fy * drift)
            rows, cols = undistortion_map(it, own)
            img, dep = remap(img, rows, cols), remap(dep, rows, cols, nearest=True)
            if inst is not None:
                inst = remap(inst, rows, cols, nearest=True)
        Image.fromarray(img).save(out / f"images/{n}.jpg", quality=95)
        if inst is not None:
            write_u16(out / capture_name("gt_instances") / f"{n}.png", inst)
        z = lidar(dep, factor)
        Image.fromarray(np.round(z * 1000).astype(np.uint16)).save(out / f"depth/{n}.png")
        f = {"fl_x": it.fx * (drift if k % 2 else 1.0), "fl_y": it.fy * (drift if k % 2 else 1.0),
             "cx": it.cx, "cy": it.cy, "w": it.width, "h": it.height,
             "file_path": f"./images/{n}.jpg", "depth_file_path": f"./depth/{n}.png",
             "transform_matrix": np.asarray(fr.c2w_gl).tolist()}
        if confidence:
            # low where the depth jumps within a cell's neighbourhood (ARKit's low-confidence edges), medium on a stripe
            jump = np.zeros(z.shape, bool)
            jump[:, 1:] |= np.abs(np.diff(z, axis=1)) > 0.1
            jump[1:, :] |= np.abs(np.diff(z, axis=0)) > 0.1
            c = np.where(jump, 0, 255).astype(np.uint8)
            c[:, 0] = np.where(jump[:, 0], 0, 127)
            Image.fromarray(c).save(out / f"confidence/{n}.png")
            f["confidence_file_path"] = f"./confidence/{n}.png"
        frames.append(f)
    (out / capture_name("transforms")).write_text(json.dumps({"camera_model": "OPENCV", "orientation_override": "none",
                                                     "frames": frames}, indent=2))
