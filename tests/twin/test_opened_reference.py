"""The opened-state reference: the scene's own model re-rendered from its synth config."""

import numpy as np
import torch

from drawer_lib.io.capture import load_capture
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.opened import SynthReference
from drawer_lib.paths import capture_name
from drawer_lib.twin.renders import opened_q, region_psnr


def test_reference_at_q0_is_the_capture_and_opening_moves_only_the_part(exact_capture, tiny_scene):
    root = exact_capture[0]
    cap = load_capture(root, check_files=False)
    cams = cap.cameras(cap.test)[:2]
    ref = SynthReference(tiny_scene.synth, cams)
    try:
        gt = read_parts(root / capture_name("gt_parts"))
        # the drawer these views see most of, so that there is a part region to check
        drawers = [p for p in gt.parts if p.kind == "prismatic"]
        seen = {p.id: sum(int(m.sum()) for _, m in ref.views(p.id, 0.0)) for p in drawers}
        part = max(drawers, key=lambda p: seen[p.id])
        assert seen[part.id] > 50, seen  # a drawer in view: the checks below check something
        closed = ref.views(part.id, 0.0)
        for (rgb, mask), i in zip(closed, cap.test[:2]):
            img = cap.image(i).astype(np.float32) / 255.0
            assert np.abs(rgb.numpy() - img).max() < 1.5 / 255  # the capture's own test image
        opened = ref.views(part.id, opened_q(part))
        for (c_rgb, c_mask), (o_rgb, o_mask) in zip(closed, opened):
            changed = (c_rgb - o_rgb).abs().amax(-1) > 0.02
            region = c_mask | o_mask
            assert region.any() and changed.any()  # the part is in view and opening it shows
            # changes stay in the part's columns (its pixels, the cavity it uncovers, its
            # shadow below it on the fronts and the floor), grown by its width either side
            jj = np.nonzero(region)[1]
            mj = jj.max() - jj.min() + 1
            near = np.zeros_like(region)
            near[:, max(jj.min() - mj, 0):jj.max() + mj + 1] = True
            assert changed.numpy()[~near].mean() < 0.005
            assert region_psnr(o_rgb, c_rgb, region) < region_psnr(o_rgb, c_rgb, ~region)
        again = ref.views(part.id, 0.0)  # the joint was put back
        torch.testing.assert_close(again[0][0], closed[0][0])
    finally:
        ref.close()


def test_region_psnr_of_an_empty_mask_is_none():
    x = torch.zeros(4, 4, 3)
    assert region_psnr(x, x + 0.1, np.zeros((4, 4), bool)) is None
    assert abs(region_psnr(x, x + 0.1, np.ones((4, 4), bool)) - 20.0) < 1e-4
