"""The built-in detector's views: renders of a procedural kitchen with their per-pixel classes
(:data:`drawer_lib.detect.builtin.CLASSES`) and their true front instances, read off the
renderer's segmentation. Only the synthetic generator is read here; no stage's output is."""

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from drawer_lib.detect.builtin import BG, EDGE, FRONT, HANDLE, OBJECT
from drawer_lib.geometry.camera import Intrinsics, opencv_to_opengl
from drawer_lib.synth.camera_path import camera_path
from drawer_lib.synth.config import RenderConfig, SynthConfig
from drawer_lib.synth.layout import sample_layout
from drawer_lib.synth.model import KitchenRenderer, build_model


@dataclass(frozen=True)
class View:
    rgb: np.ndarray  # uint8 [H, W, 3]
    classes: np.ndarray  # uint8 [H, W], CLASSES indices
    fronts: np.ndarray  # int32 [H, W]: the front entity's index + 1 per pixel (handles included), 0 elsewhere


def view_classes(ent: np.ndarray, handle: np.ndarray, kind_of: np.ndarray, edge_px: int) -> np.ndarray:
    """uint8 [H, W] classes of a render: ``ent`` [H, W] entity index (-1 none), ``handle`` [H, W]
    bool, ``kind_of`` [E] 0 static / 1 front / 2 object. A front pixel within ``edge_px`` of a
    pixel of another entity is 'edge'; a handle pixel is 'handle' whatever it sits on.

    >>> ent = np.array([[0, 1, 1, 2, 2]]); kinds = np.array([0, 1, 1])
    >>> view_classes(ent, np.zeros_like(ent, bool), kinds, 1).tolist()
    [[0, 2, 2, 2, 1]]
    """
    k = np.where(ent >= 0, kind_of[np.maximum(ent, 0)], 0)
    out = np.full(ent.shape, BG, np.uint8)
    out[k == 2] = OBJECT
    front = k == 1
    size = 2 * edge_px + 1
    border = ndimage.maximum_filter(ent, size=size, mode="nearest") != ndimage.minimum_filter(ent, size=size, mode="nearest")
    out[front] = FRONT
    out[front & border] = EDGE
    out[handle & (k > 0)] = HANDLE
    return out


def render_views(synth: SynthConfig, render: RenderConfig, frames: list[int], edge_px: int) -> Iterator[View]:
    """The kitchen ``synth`` seen from frames ``frames`` of its camera path."""
    layout = sample_layout(synth)
    cc = synth.camera
    intr = Intrinsics.from_fovy(np.deg2rad(cc.fovy_deg), cc.width, cc.height)
    km = build_model(layout, intr, render)
    poses = camera_path(layout, cc, np.random.default_rng([synth.seed, 2]))
    kind_of = np.array([0 if e.family == "static" else 2 if e.family == "object" else 1 for e in layout.entities])
    renderer = KitchenRenderer(km, intr)
    try:
        for k in frames:
            if not 0 <= k < len(poses):
                continue
            renderer.set_camera(opencv_to_opengl(poses[k]))
            rgb, _, ent, handle = renderer.render()
            cls = view_classes(ent, handle, kind_of, edge_px)
            fronts = np.where((ent >= 0) & (kind_of[np.maximum(ent, 0)] == 1), ent + 1, 0).astype(np.int32)
            yield View(rgb, cls, fronts)
    finally:
        renderer.close()
