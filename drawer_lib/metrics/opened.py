"""The opened-state reference of a synthetic scene (docs/formats.md#opened-state-nvs): the scene's own
model, rebuilt from its ``synth`` config, rendered with one GT part's joint at ``q`` in the
capture's test views, and the part's pixels from the renderer's segmentation. Evaluation only:
the twin never sees this."""

import numpy as np
import torch

from drawer_lib.geometry.camera import Camera, opencv_to_opengl
from drawer_lib.synth.config import RenderConfig, SynthConfig
from drawer_lib.synth.layout import sample_layout
from drawer_lib.synth.model import KitchenRenderer, build_model


class SynthReference:
    """Renders of a procedural scene with one part posed; ``close()`` frees the GL context."""

    def __init__(self, synth: SynthConfig, cams: list[Camera], render: RenderConfig | None = None):
        if not cams:
            raise ValueError("SynthReference: no views")
        self.layout = sample_layout(synth)
        self.km = build_model(self.layout, cams[0].intrinsics, render)
        self.renderer = KitchenRenderer(self.km, cams[0].intrinsics)
        self.cams = cams
        self.entity_index = {e.name: i for i, e in enumerate(self.layout.entities)}

    def views(self, gt_id: str, q: float) -> list[tuple[torch.Tensor, np.ndarray]]:
        """Per view (rgb [H, W, 3] float in [0, 1], bool mask [H, W] of the part's pixels) with
        GT part ``gt_id`` at joint value ``q``; the part is put back at 0 afterwards."""
        if gt_id not in self.entity_index:
            raise KeyError(f"SynthReference: no entity {gt_id!r} in the scene")
        r = self.renderer
        out = []
        r.set_joint(gt_id, q)
        try:
            for cam in self.cams:
                r.set_camera(opencv_to_opengl(cam.c2w))
                rgb, _, ent, _ = r.render()
                out.append((torch.from_numpy(rgb.astype(np.float32) / 255.0), ent == self.entity_index[gt_id]))
        finally:
            r.set_joint(gt_id, 0.0)
        return out

    def close(self) -> None:
        self.renderer.close()
