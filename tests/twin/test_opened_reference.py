"""The opened-state reference: the scene's own model re-rendered from its synth config."""

import numpy as np
import pytest
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


def test_opened_scores_are_computed_part_by_part(exact_capture, tiny_scene, tmp_path):
    """The twin stage scores each part's opened views as they are rendered and keeps none: here
    the 'twin' renders are the reference's own, darkened by 10 %, so every score is known."""
    from types import SimpleNamespace

    from drawer_lib.metrics.image import psnr
    from drawer_lib.runner import StageRun
    from drawer_lib.twin.config import RendersConfig
    from drawer_lib.twin.pipeline import _OpenedScores

    root = exact_capture[0]
    cap = load_capture(root, check_files=False)
    cams = cap.cameras(cap.test)[:1]
    gt = read_parts(root / capture_name("gt_parts"))
    moving = [p for p in gt.parts if p.articulated]
    rc = RendersConfig(max_views=1, lpips=False)
    run = StageRun("twin", tmp_path, tmp_path, 0)
    scores = _OpenedScores(cap, cams, gt, tiny_scene.synth, rc, None, run)
    ref = SynthReference(tiny_scene.synth, cams)
    want = []
    try:
        for p in moving:
            q = opened_q(p, rc.open_fraction)
            gv = ref.views(p.id, q)
            views = [SimpleNamespace(rgb=0.9 * rgb, part_alpha=torch.from_numpy(m.astype(np.float32))) for rgb, m in gv]
            want.append(float(psnr(views[0].rgb.permute(2, 0, 1)[None], gv[0][0].permute(2, 0, 1)[None])[0]))
            scores.add(p.id, q, views)
    finally:
        scores.close()
        ref.close()
    m: dict = {}
    scores.finish(m)
    assert m["n_parts_scored_open"] == len(moving) > 0
    assert m["open_psnr"] == pytest.approx(np.mean(want), rel=1e-6)
    assert run.out("render_scores").is_file() and run.out("contact_sheet").is_file()
    none = _OpenedScores(cap, cams, gt, None, rc, None, run)  # not a procedural scene
    none.finish(m2 := {})
    assert "open_psnr" not in m2
