"""The built-in detector: instance decoding and painting against hand-made probability maps,
the network's shapes, its weights file, its fit on a tiny analytic dataset, the 2D matching,
and the detector and detect stages end to end (a few steps on one train kitchen)."""

import copy
import dataclasses
import json
import os
import shutil
import signal

import numpy as np
import pytest
import torch
from helpers import run_stage, scene_paths

from drawer_lib.bench.scenes import kitchen_scene
from drawer_lib.detect.builtin import (
    CLASSES,
    DECODE_BAND,
    EDGE,
    FRONT,
    HANDLE,
    OBJECT,
    DetectorEnsemble,
    TinyUNet,
    class_probs,
    decode_instances,
    float32_error,
    handles_per_region,
    merge_weak_boundaries,
    jitter_logits,
    normalise,
    load_detector,
    resize_mask,
    save_detector,
)
from drawer_lib.detect.config import BuiltinDetectConfig, DetectorTrainConfig
from drawer_lib.detect.masks import Detection, paint_detections
from drawer_lib.detect.train import Sample, _crop_batch, fit_views, average_fit, average_state_path, check_layouts, class_weights, drop_fit_state, fit_detector, pixel_accuracy
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.capture import load_capture
from drawer_lib.io.overlay import apply_overlay
from drawer_lib.metrics.detections import match_fronts
from drawer_lib.runner import StageRun
from drawer_lib.synth.config import RenderConfig


def _probs(cls: np.ndarray) -> np.ndarray:
    p = np.full((len(CLASSES), *cls.shape), 0.02, np.float32)
    for c in range(len(CLASSES)):
        p[c][cls == c] = 0.92
    return p


def test_two_fronts_apart_by_an_edge_a_handle_and_an_object():
    cls = np.zeros((40, 60), np.int64)
    cls[5:35, 5:29] = FRONT
    cls[5:35, 31:55] = FRONT
    cls[5:35, 29:31] = EDGE  # the gap between them
    cls[5:35, [4, 55]] = EDGE
    cls[18:22, 40:48] = HANDLE
    cls[37:40, 0:20] = OBJECT
    cls[1:3, 1:3] = FRONT  # too small
    dets = decode_instances(_probs(cls), BuiltinDetectConfig(min_area_px=20, min_score=0.5, erode_px=1, min_seed_px=5))
    fronts = sorted((d for d in dets if d.label == "front"), key=lambda d: d.mask.nonzero()[1].min())
    assert len(fronts) == 2
    assert fronts[0].mask[5:35, 4:29].all() and not fronts[0].mask[:, 31:].any()  # flooded over its own edge
    assert not fronts[1].mask[18:22, 40:48].any()  # its handle is a detection of its own
    assert [d.label for d in dets if d.label != "front"] == ["handle", "object"]
    assert all(0.5 < d.score <= 1 for d in dets)
    assert decode_instances(_probs(np.zeros((8, 8), np.int64)), BuiltinDetectConfig()) == []  # empty image


def test_a_bar_handle_across_a_small_front_does_not_cut_it_in_two():
    cls = np.zeros((30, 60), np.int64)
    cls[5:25, 5:29] = FRONT
    cls[5:25, 31:55] = FRONT
    cls[5:25, 29:31] = EDGE  # a double door's gap, each door's bar beside it
    cls[8:22, 24:27] = HANDLE
    cls[8:22, 33:36] = HANDLE
    cls[13:17, 5:29] = HANDLE  # a bar across the left door, edge to edge
    cfg = dict(min_area_px=20, min_score=0.5, erode_px=1, min_seed_px=5, merge_edge=0.0)
    fronts = lambda d: [x for x in d if x.label == "front"]
    assert len(fronts(decode_instances(_probs(cls), BuiltinDetectConfig(core_handle=False, **cfg)))) == 3
    two = sorted(fronts(decode_instances(_probs(cls), BuiltinDetectConfig(core_handle=True, **cfg))),
                 key=lambda d: d.mask.nonzero()[1].min())
    assert len(two) == 2 and two[0].mask[5:13, 5:24].all() and two[0].mask[17:25, 5:24].all()
    assert not two[0].mask[:, 31:].any() and not two[0].mask[13:17, 5:29].any()  # its handle stays out


def test_regions_without_an_edge_between_them_merge():
    lab = np.zeros((6, 9), np.int64)
    lab[:, 0:3], lab[:, 3:6], lab[:, 6:9] = 1, 2, 3
    pe = np.zeros((6, 9))
    pe[:, 5:7] = 0.9  # a seen edge between 2 and 3, none between 1 and 2
    out = merge_weak_boundaries(lab, pe, 0.5)
    assert (out[:, 0:6] == 1).all() and (out[:, 6:] == 3).all()
    assert (merge_weak_boundaries(lab, pe, 0.95) == 1).all()  # transitively, through 2
    assert np.array_equal(merge_weak_boundaries(lab, pe, 0.0), lab)
    lab[:, 3:6] = 0  # apart: background between them
    assert np.array_equal(merge_weak_boundaries(lab, np.zeros_like(pe), 0.5), lab)
    assert np.array_equal(merge_weak_boundaries(np.zeros((3, 3), np.int64), np.zeros((3, 3)), 0.5), np.zeros((3, 3)))
    with pytest.raises(ConfigError, match="merge_edge"):
        BuiltinDetectConfig(merge_edge=1.5)


def test_a_weak_boundary_merges_only_while_the_pair_carries_one_handle():
    lab = np.zeros((6, 12), np.int64)
    lab[:, 0:3], lab[:, 3:6], lab[:, 6:9], lab[:, 9:12] = 1, 2, 3, 4
    pe = np.zeros((6, 12))
    pe[:, 2:4] = 0.6   # 1|2: weak-ish
    pe[:, 5:7] = 0.55  # 2|3: weaker, taken first
    pe[:, 8:10] = 0.3  # 3|4: below merge_edge, always merges
    handles = np.array([0, 1, 0, 1, 0])  # per label; regions 1 and 3 carry a handle each
    out = merge_weak_boundaries(lab, pe, 0.5, band_max=0.7, carried=handles)
    # 3|4 merge (sure); 2|3 merge (2 has none, {3, 4} one); 1|{2, 3, 4} would gather two: kept apart
    assert (out[:, 0:3] == 1).all() and (out[:, 3:12] == 2).all()
    # without handles counted, 0.7 merges everything, as the plain threshold does
    assert (merge_weak_boundaries(lab, pe, 0.7) == 1).all()
    assert (merge_weak_boundaries(lab, pe, 0.5, band_max=0.7, carried=np.zeros(5, np.int64)) == 1).all()
    # the conditional band off: the plain threshold
    assert np.array_equal(merge_weak_boundaries(lab, pe, 0.5, band_max=0.5, carried=handles),
                          merge_weak_boundaries(lab, pe, 0.5))
    # a chain of handle-less regions between two handled ones never joins both
    out = merge_weak_boundaries(lab, np.full_like(pe, 0.6), 0.5, band_max=0.7, carried=np.array([0, 1, 0, 0, 1]))
    assert len(np.unique(out)) == 2 and out[0, 0] != out[0, -1]
    # regions counted, limit 2: the weakest pair first (3|4 is sure; 2|3 would make three), then 1|2
    out = merge_weak_boundaries(lab, pe, 0.5, band_max=0.7, carried=np.ones(5, np.int64), limit=2)
    assert (out[:, 0:6] == 1).all() and (out[:, 6:12] == 3).all()
    with pytest.raises(ValueError, match="carried has 3"):
        merge_weak_boundaries(lab, pe, 0.5, band_max=0.7, carried=np.zeros(3, np.int64))
    with pytest.raises(ConfigError, match="merge_band_limit"):
        BuiltinDetectConfig(merge_band_limit="three")


def test_decisions_near_their_thresholds_are_listed_with_their_signed_margin():
    """A boundary whose mean P(edge) lies within DECODE_BAND of ``merge_edge`` (either side) and
    a region whose score lies that close to ``min_score`` are listed, with value - threshold;
    a clear margin is not; no list, nothing recorded and the same decoding."""
    lab = np.zeros((6, 9), np.int64)
    lab[:, 0:3], lab[:, 3:6], lab[:, 6:9] = 1, 2, 3
    pe = np.zeros((6, 9))
    pe[:, 2:4] = 0.5 + 0.4 * DECODE_BAND  # 1|2: merged (below 0.5 + ...), by less than the band ...
    pe[:, 5:7] = 0.5 - 0.4 * DECODE_BAND  # 2|3: ... and one kept apart (0.5 - ... is below): listed both
    near: list[dict] = []
    out = merge_weak_boundaries(lab, pe, 0.5 + 0.1 * DECODE_BAND, near=near)  # the threshold between them
    assert len(np.unique(out)) == 2 and out[0, 0] != out[0, -1]  # 2|3 merged, 1|2 not
    assert sorted(round(r["margin"] / DECODE_BAND, 3) for r in near) == [-0.5, 0.3]
    assert {r["step"] for r in near} == {"merge"}
    assert np.array_equal(out, merge_weak_boundaries(lab, pe, 0.5 + 0.1 * DECODE_BAND))
    clear: list[dict] = []
    merge_weak_boundaries(lab, pe, 0.5 + 3 * DECODE_BAND, near=clear)
    assert clear == []
    band: list[dict] = []  # with the handle-counting band: its upper threshold too
    merge_weak_boundaries(lab, pe, 0.3, band_max=0.5 + 0.1 * DECODE_BAND, carried=np.zeros(4, np.int64), near=band)
    assert [r["step"] for r in band] == ["merge_band", "merge_band"]
    # a front's score: P(front) + P(edge) averages to min_score + 0.2 band
    cls = np.zeros((30, 30), np.int64)
    cls[5:25, 5:25] = FRONT
    p = _probs(cls)
    cfg = BuiltinDetectConfig(min_area_px=20, min_score=0.5, erode_px=1, min_seed_px=5, merge_edge=0.0)
    front = [d for d in decode_instances(p, cfg) if d.label == "front"][0]
    at = float(front.score)
    for shift, listed in ((0.2, True), (-0.2, True), (3.0, False)):
        near = []
        dets = decode_instances(p, dataclasses.replace(cfg, min_score=at - shift * DECODE_BAND), near)
        assert bool(near) == listed and len([d for d in dets if d.label == "front"]) == (shift > 0)
        if listed:
            assert near == [{"step": "score", "margin": pytest.approx(shift * DECODE_BAND, abs=1e-6), "label": "front"}]


def test_logit_jitter_moves_probabilities_by_about_its_sigma_and_is_seeded():
    rng = np.random.default_rng(0)
    p = rng.dirichlet(np.ones(len(CLASSES)), (20, 30)).transpose(2, 0, 1).astype(np.float32)
    for sigma in (1e-5, 1e-3):
        q = jitter_logits(p, sigma, seed=3)
        assert q.dtype == p.dtype and q.shape == p.shape
        np.testing.assert_allclose(q.sum(0), 1.0, atol=1e-6)
        d = q - p  # dp_c = p_c (dz_c - sum_k p_k dz_k): below sigma / 2 in standard deviation
        assert 0 < np.abs(d).max() < 2 * sigma and 0.05 * sigma < d.std() < 0.5 * sigma
        assert np.array_equal(q, jitter_logits(p, sigma, seed=3)) and not np.array_equal(q, jitter_logits(p, sigma, 4))
    assert np.abs(jitter_logits(p, 0.0, 0) - p).max() < 1e-6
    with pytest.raises(ConfigError, match="logit_jitter"):
        BuiltinDetectConfig(logit_jitter=-1e-3)
    with pytest.raises(ConfigError, match="logit_jitter"):
        BuiltinDetectConfig(logit_jitter=float("nan"))


def test_float32_error_is_float32_rounding_and_leaves_the_model_as_it_was():
    torch.manual_seed(0)
    model = TinyUNet(4).eval()
    before = {k: v.clone() for k, v in model.state_dict().items()}
    rgb = np.random.default_rng(0).integers(0, 256, (30, 41, 3), dtype=np.uint8)
    e = float32_error(model, rgb, 41)
    assert 0 < e["logp_sd"] <= e["logp_max"] < 1e-4 and 0 < e["p_max"] < 1e-5
    assert all(v.dtype == torch.float32 and torch.equal(v, before[k]) for k, v in model.state_dict().items())


def test_handles_are_counted_in_the_region_holding_most_of_their_pixels():
    lab = np.zeros((4, 10), np.int64)
    lab[:, 0:5], lab[:, 5:10] = 1, 2
    h = np.zeros((4, 10), bool)
    h[1:3, 3:6] = True   # 4 px in 1, 2 px in 2: region 1's
    h[0, 8] = True       # one pixel: below min_px, not a handle
    h[3, 7:10] = True    # region 2's
    assert handles_per_region(lab, h, 2).tolist() == [0, 1, 1]
    assert handles_per_region(lab, np.zeros_like(h), 2).tolist() == [0, 0, 0]
    lab[:, 0:5] = 0      # a handle over the background counts for nobody
    assert handles_per_region(lab, h, 2).tolist() == [0, 0, 1]


def test_decoding_keeps_two_handled_doors_apart_and_joins_a_cut_front():
    """Two doors side by side (a handle each; P(edge) 0.6 between them), then a clear edge
    (0.9), then one wide front the network cut down its middle (one handle; 0.6 along the cut):
    the plain threshold 0.7 joins both faint boundaries, the handle-counting band only the cut."""
    cls = np.zeros((30, 100), np.int64)
    cls[5:25, 2:98] = FRONT
    for c in (30, 50, 75):
        cls[5:25, c:c + 2] = EDGE
    cls[8:22, 26:28] = HANDLE   # left door's
    cls[8:22, 33:35] = HANDLE   # second door's
    cls[8:22, 90:92] = HANDLE   # the wide front's (cut at 75), one handle
    prob = _probs(cls)
    for c in (30, 75):
        prob[FRONT, 5:25, c:c + 2], prob[EDGE, 5:25, c:c + 2] = 0.4, 0.6  # a seen but faint edge
    base = dict(min_area_px=20, min_score=0.5, erode_px=1, min_seed_px=5)
    n_fronts = lambda cfg: sum(d.label == "front" for d in decode_instances(prob, BuiltinDetectConfig(**base, **cfg)))
    assert n_fronts(dict(merge_edge=0.5)) == 4
    assert n_fronts(dict(merge_edge=0.7)) == 2
    assert n_fronts(dict(merge_edge=0.5, merge_edge_band=0.7)) == 3  # the cut at 75 joins; the doors stay apart
    assert n_fronts(dict(merge_edge=0.5, merge_edge_band=0.7, merge_band_limit="two_regions")) == 2  # pairs only
    prob[EDGE, 5:25, 50:52], prob[FRONT, 5:25, 50:52] = 0.6, 0.4  # the clear edge faint too: a run of four
    assert n_fronts(dict(merge_edge=0.7)) == 1
    assert n_fronts(dict(merge_edge=0.5, merge_edge_band=0.7, merge_band_limit="two_regions")) == 2


def test_painting_keeps_handles_on_top_and_ids_local():
    big = np.zeros((10, 10), bool)
    big[1:9, 1:9] = True
    small = np.zeros_like(big)
    small[4:6, 4:6] = True
    hidden = np.zeros_like(big)
    hidden[2:4, 2:4] = True  # wholly under nothing: painted before big? no, smaller: on top
    lab, rows = paint_detections([Detection(small, "handle", 0.9), Detection(big, "front", 0.8)], big.shape)
    assert rows == [{"id": 1, "label": "front", "score": 0.8}, {"id": 2, "label": "handle", "score": 0.9}]
    assert (lab[4:6, 4:6] == 2).all() and (lab[big & ~small] == 1).all() and lab.dtype == np.uint16
    lab, rows = paint_detections([Detection(big, "front", 0.8), Detection(big.copy(), "door", 0.7)], big.shape)
    assert len(rows) == 1 and sorted(np.unique(lab).tolist()) == [0, 1]  # a mask wholly painted over is dropped
    assert paint_detections([], (3, 4))[0].shape == (3, 4)


def test_network_shapes_weights_file_and_resize(tmp_path):
    m = TinyUNet(8)
    for h, w in ((37, 53), (8, 8), (1, 9)):
        assert m(torch.zeros(2, 3, h, w)).shape == (2, len(CLASSES), h, w)
    save_detector(tmp_path / "w.pt", m, {"note": 1})
    m2, info = load_detector(tmp_path / "w.pt")
    x = torch.randn(1, 3, 16, 20)
    assert torch.equal(m.eval()(x), m2(x)) and info == {"note": 1}
    torch.save({"kind": "other"}, tmp_path / "bad.pt")
    with pytest.raises(InputError, match="not the built-in detector"):
        load_detector(tmp_path / "bad.pt")
    with pytest.raises(InputError, match="dvc repro detector"):
        load_detector(tmp_path / "none.pt")
    a = np.zeros((4, 6), bool)
    a[1, 2] = True
    assert resize_mask(a, 8, 12)[2:4, 4:6].all() and resize_mask(a, 8, 12).sum() == 4


def test_an_ensemble_averages_its_members_probabilities_and_one_fit_keeps_its_file(tmp_path):
    """Several fits in one file (or across files) load as one network whose class probabilities
    are the members' mean, checked against each member's softmax averaged by hand; a file of one
    fit is written as before (no ``members`` key) and loads as that fit."""
    torch.manual_seed(0)
    a, b, c = TinyUNet(8).eval(), TinyUNet(8).eval(), TinyUNet(8).eval()
    save_detector(tmp_path / "one.pt", a, {"note": 1})
    assert "members" not in torch.load(tmp_path / "one.pt", weights_only=True)
    save_detector(tmp_path / "two.pt", [a, b], {"note": 2})
    save_detector(tmp_path / "c.pt", c, {"note": 3})
    rgb = np.random.default_rng(0).integers(0, 256, (30, 41, 3), dtype=np.uint8)
    x = normalise(rgb)[None]
    for files, members in (([tmp_path / "two.pt"], [a, b]), ([tmp_path / "two.pt", tmp_path / "c.pt"], [a, b, c])):
        ens, info = load_detector(files)
        assert isinstance(ens, DetectorEnsemble) and info == {"note": 2, "members": len(members)}
        with torch.no_grad():
            ref = torch.stack([torch.softmax(m(x)[0].double(), 0) for m in members]).mean(0)
        got = class_probs(ens, rgb, 41)
        assert got.shape == (len(CLASSES), 30, 41) and np.allclose(got, ref.numpy(), atol=1e-5)
        assert np.allclose(got.sum(0), 1, atol=1e-5)
    single, info = load_detector([tmp_path / "one.pt"])
    assert isinstance(single, TinyUNet) and info == {"note": 1}
    assert np.array_equal(class_probs(single, rgb, 41), class_probs(a, rgb, 41))
    with pytest.raises(ValueError, match="widths"):
        save_detector(tmp_path / "mixed.pt", [a, TinyUNet(16)], {})
    with pytest.raises(InputError, match="none.pt.*dvc repro detector"):
        load_detector([tmp_path / "one.pt", tmp_path / "none.pt"])
    with pytest.raises(InputError, match="no weights file"):
        load_detector([])
    for seeds in ([], [0, 0], [-1], list(range(9))):
        with pytest.raises(ConfigError, match=r"detector.seeds = \["):
            DetectorTrainConfig(seeds=seeds)


def test_crop_augmentation_keeps_labels_on_their_pixels():
    """Colour jitter changes pixels, never classes; scale jitter resizes both alike: a class
    boundary stays where the image's step is, and padding is ignored (-100)."""
    h, w = 60, 90
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[:, 45:] = 200  # a bright right half ...
    y = np.zeros((h, w), np.int64)
    y[:, 45:] = FRONT  # ... is front
    s = Sample(normalise(rgb), torch.as_tensor(y))
    plain = _crop_batch([s], 4, 48, torch.Generator().manual_seed(0))
    assert torch.equal(plain[0], _crop_batch([s], 4, 48, torch.Generator().manual_seed(0))[0])  # seeded
    for cj, sj in ((0.6, 1.0), (0.0, 1.6), (0.6, 1.6)):
        x, lab = _crop_batch([s], 16, 48, torch.Generator().manual_seed(1), cj, sj)
        assert x.shape == (16, 3, 48, 48) and lab.shape == (16, 48, 48) and torch.isfinite(x).all()
        bright = x.mean(1) > normalise(np.full((1, 1, 3), 100, np.uint8))[0, 0, 0]
        keep = lab != -100
        agree = (bright[keep] == (lab[keep] == FRONT)).float().mean()
        assert agree == 1 if sj == 1 else agree > 0.97  # resized: the step's one blended column may differ
        assert set(torch.unique(lab).tolist()) <= {-100, 0, FRONT}
    x, _ = _crop_batch([s], 16, 48, torch.Generator().manual_seed(1), 0.6, 1.0)
    xp, _ = _crop_batch([s], 16, 48, torch.Generator().manual_seed(1), 0.0, 1.0)
    assert not torch.allclose(x, xp)  # the jitter does change colours
    with pytest.raises(ConfigError, match="scale_jitter"):
        DetectorTrainConfig(scale_jitter=0.5)


def _rectangles(n: int = 6, seed: int = 0) -> list[Sample]:
    """Bright rectangles (fronts) with a dark one-pixel rim (edges) on grey, 48² each."""
    g = np.random.default_rng(seed)
    samples = []
    for _ in range(n):
        y = np.zeros((48, 48), np.int64)
        x = np.full((3, 48, 48), -0.5, np.float32)
        for _ in range(2):
            i, j = g.integers(2, 28, 2)
            y[i:i + 16, j:j + 16] = EDGE
            y[i + 1:i + 15, j + 1:j + 15] = FRONT
        x[:, y == FRONT] = 1.0
        x[:, y == EDGE] = -1.5
        samples.append(Sample(torch.as_tensor(x), torch.as_tensor(y)))
    return samples


def test_fit_learns_rectangles_on_a_flat_background():
    """A few hundred steps separate fronts from edges and background far beyond the majority
    class's share."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=150, batch=4, crop=32, lr=1e-2, log_every=50)
    model, losses = fit_detector(samples, cfg, seed=0)
    assert len(losses) == 3 and losses[-1] < losses[0]
    base = max(float((s.y == FRONT).float().mean()) for s in samples)
    assert pixel_accuracy(model, samples) > max(0.9, base)


def test_a_channels_last_network_computes_the_same_logits_and_its_file_reads_alike(tmp_path):
    """``memory_format: channels_last``: the logits of the same weights as the contiguous
    network's to float32 rounding, its file holds plain (contiguous) tensors and its format, and
    loads into a network of that format that gives the probabilities it was saved with, bit for
    bit; a file without the key loads contiguous; formats are checked."""
    torch.manual_seed(0)
    a = TinyUNet(8).eval()
    b = TinyUNet(8, memory_format="channels_last").eval()
    b.load_state_dict(a.state_dict())
    conv = b.enc[0][0].weight
    assert conv.is_contiguous(memory_format=torch.channels_last) and not conv.is_contiguous()
    x = torch.randn(2, 3, 37, 53)
    with torch.no_grad():
        la, lb = a(x), b(x)
    np.testing.assert_allclose(lb.numpy(), la.numpy(), atol=1e-5)
    save_detector(tmp_path / "cl.pt", b, {"note": 1})
    d = torch.load(tmp_path / "cl.pt", weights_only=True)
    assert d["memory_format"] == "channels_last" and all(v.is_contiguous() for v in d["state_dict"].values())
    m, _ = load_detector(tmp_path / "cl.pt")
    assert m.memory_format == "channels_last" and m.enc[0][0].weight.is_contiguous(memory_format=torch.channels_last)
    rgb = np.random.default_rng(0).integers(0, 256, (30, 41, 3), dtype=np.uint8)
    assert np.array_equal(class_probs(m, rgb, 41), class_probs(b, rgb, 41))
    del d["memory_format"]
    torch.save(d, tmp_path / "old.pt")
    assert load_detector(tmp_path / "old.pt")[0].memory_format == "contiguous"
    with pytest.raises(ValueError, match="memory formats"):
        save_detector(tmp_path / "mixed.pt", [a, b], {})
    with pytest.raises(ValueError, match="memory_format"):
        TinyUNet(8, memory_format="nhwc")
    with pytest.raises(ConfigError, match="detector.memory_format"):
        DetectorTrainConfig(memory_format="nhwc")


def test_a_fit_in_either_memory_format_starts_alike_and_learns():
    """The fit in ``channels_last`` and in ``contiguous``: the same initial weights and crops
    (the first loss agrees to float32 rounding), both learn the rectangles, and the fitted
    network keeps the format it was fitted in, as does its weight average."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=150, batch=4, crop=32, lr=1e-2, log_every=1)
    fits = {f: fit_detector(samples, dataclasses.replace(cfg, memory_format=f), seed=0)
            for f in ("contiguous", "channels_last")}
    (ma, la), (mb, lb) = fits["contiguous"], fits["channels_last"]
    np.testing.assert_allclose(lb[0], la[0], rtol=1e-5)
    assert mb.memory_format == "channels_last" and ma.memory_format == "contiguous"
    assert min(pixel_accuracy(ma, samples), pixel_accuracy(mb, samples)) > 0.9
    avg = average_fit(mb, samples, dataclasses.replace(cfg, average_steps=12, average_warmup=4), seed=3)
    assert avg.memory_format == "channels_last" and pixel_accuracy(avg, samples) > 0.9


@pytest.mark.gpu
def test_a_fit_on_cuda_starts_sees_and_ends_as_on_the_cpu(tmp_path):
    """``detector.device: cuda``: the same initial weights and crops as the CPU (its first
    loss agrees to float32 rounding, the next ones within 0.1 %), a detector at the end, weights back on the CPU that
    load and run there, its probabilities on the card the CPU's; the averaging and an
    interrupted fit go on there too. Two CUDA fits from one seed are compared and their
    difference printed (atomics in two backward passes: not bit for bit)."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=150, batch=4, crop=32, lr=1e-2, log_every=1, device="cuda")
    ref, ref_losses = fit_detector(samples, dataclasses.replace(cfg, device="cpu"), seed=0)
    model, losses = fit_detector(samples, cfg, seed=0)
    again, _ = fit_detector(samples, cfg, seed=0)
    assert all(p.device.type == "cpu" for p in model.parameters()) and not model.training
    np.testing.assert_allclose(losses[0], ref_losses[0], rtol=1e-5)  # the same weights and crops
    np.testing.assert_allclose(losses[:5], ref_losses[:5], rtol=1e-3)
    assert abs(losses[-1] - ref_losses[-1]) < 0.5 * ref_losses[0]
    assert pixel_accuracy(model, samples) > 0.9
    diff = max(float((a - b).abs().max()) for a, b in zip(model.state_dict().values(), again.state_dict().values()))
    print(f"two CUDA fits from one seed: largest weight difference {diff:.3g}")
    rgb = np.random.default_rng(0).integers(0, 256, (30, 41, 3), dtype=np.uint8)
    on_cpu = class_probs(model, rgb, 41)
    # full float32 on the card (no TF32, drawer_lib.devices.cuda_numerics): float32 rounding apart
    np.testing.assert_allclose(class_probs(copy.deepcopy(model).cuda(), rgb, 41), on_cpu, atol=1e-5)
    avg = average_fit(model, samples, dataclasses.replace(cfg, average_steps=12, average_warmup=4), seed=3)
    assert all(p.device.type == "cpu" for p in avg.parameters()) and pixel_accuracy(avg, samples) > 0.9
    state = tmp_path / "0.pt"
    short = dataclasses.replace(cfg, steps=12, log_every=2, checkpoint_every=4)
    with pytest.raises(KeyboardInterrupt):
        fit_detector(samples, short, seed=0, progress=_stop_after(7), resume=state)
    _, resumed = fit_detector(samples, short, seed=0, resume=state)
    _, whole = fit_detector(samples, short, seed=0)
    assert len(resumed) == 6 and torch.load(state, weights_only=False)["step"] == 12
    drop_fit_state(state)
    assert not state.exists()
    np.testing.assert_allclose(resumed, whole, rtol=1e-3)


def _stop_after(n: int):
    """A ``progress`` wrapper that is interrupted (as by Ctrl-C or SIGTERM) before its
    ``n + 1``-th item."""
    def progress(it, **kw):
        for i, x in enumerate(it):
            if i == n:
                raise KeyboardInterrupt("test")
            yield x
    return progress


def _term_at(n: int):
    """A ``progress`` wrapper that sends this process SIGTERM (a cluster's time limit, a killed
    ``dvc repro``) before its ``n + 1``-th item."""
    def progress(it, **kw):
        for i, x in enumerate(it):
            if i == n:
                os.kill(os.getpid(), signal.SIGTERM)
            yield x
    return progress


def test_an_interrupted_fit_goes_on_to_the_weights_of_an_uninterrupted_one(tmp_path):
    """Stopped mid-fit (between two saves: what it did since the last one is kept at the
    interrupt) and rerun, then stopped at a save with no step after it and rerun: the weights
    and the logged losses equal those of a fit never stopped, bit for bit; the curve gets every
    row once, in order; the saved state is gone once the fit is done."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=12, batch=4, crop=32, lr=1e-2, log_every=2, checkpoint_every=4)
    ref, ref_losses = fit_detector(samples, cfg, seed=0)
    state = tmp_path / "resume" / "0.pt"
    for stop in (7, 8):  # at step 7 (saved at 4, and at 7 by the interrupt), at step 8 (a save)
        with pytest.raises(KeyboardInterrupt):
            fit_detector(samples, cfg, seed=0, progress=_stop_after(stop), resume=state)
        assert torch.load(state, weights_only=False)["step"] == stop
        run = StageRun("t", tmp_path / f"o{stop}", tmp_path / f"d{stop}", 0)
        (tmp_path / f"d{stop}").mkdir()
        model, losses = fit_detector(samples, cfg, seed=0, curve=run.curve(["loss"]), resume=state)
        run._finish()
        assert losses == ref_losses
        for k, v in ref.state_dict().items():
            assert torch.equal(model.state_dict()[k], v), k
        drop_fit_state(state)
        assert not state.exists() and not state.parent.exists()
        steps = [int(r.split(",")[0]) for r in (tmp_path / f"d{stop}" / "curve.csv").read_text().split()[1:]]
        assert steps == [2, 4, 6, 8, 10, 12]


def test_a_signal_mid_fit_stops_it_at_the_end_of_that_step(tmp_path):
    """SIGTERM (a cluster's time limit, a killed ``dvc repro``) sent while a step runs: the step
    ends, its state is kept, the fit stops; the rerun makes the weights of a fit never stopped.
    The same on the last step: the rerun has no step left and returns those weights."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=8, batch=4, crop=32, lr=1e-2, log_every=2, checkpoint_every=100)
    ref, ref_losses = fit_detector(samples, cfg, seed=0)
    state = tmp_path / "0.pt"

    for n, kept in ((2, 3), (7, 8)):  # sent before step 3 runs (the handler runs in it), and before step 8
        with pytest.raises(KeyboardInterrupt, match=f"signal {int(signal.SIGTERM)}"):
            fit_detector(samples, cfg, seed=0, progress=_term_at(n), resume=state)
        assert torch.load(state, weights_only=False)["step"] == kept
        model, losses = fit_detector(samples, cfg, seed=0, resume=state)
        assert losses == ref_losses
        assert all(torch.equal(model.state_dict()[k], v) for k, v in ref.state_dict().items())
        drop_fit_state(state)


def test_a_finished_fit_keeps_its_state_until_its_outputs_are_written(tmp_path):
    """A fit run to its end leaves its last state: killed after the last step and before the
    stage wrote its outputs, the rerun takes no step and returns the same weights and losses.
    drop_fit_state removes the state, and the folder only when no other seed's state is in it."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=6, batch=4, crop=32, lr=1e-2, log_every=2, checkpoint_every=4)
    state, other = tmp_path / "resume" / "0.pt", tmp_path / "resume" / "1.pt"
    ref, ref_losses = fit_detector(samples, cfg, seed=0, resume=state)
    assert torch.load(state, weights_only=False)["step"] == 6
    taken = []

    def counting(it, **kw):
        for x in it:
            taken.append(x)
            yield x

    model, losses = fit_detector(samples, cfg, seed=0, progress=counting, resume=state)
    assert taken == [] and losses == ref_losses
    assert all(torch.equal(model.state_dict()[k], v) for k, v in ref.state_dict().items())
    other.write_bytes(b"another seed's unfinished fit")
    drop_fit_state(state)
    assert not state.exists() and other.exists()
    drop_fit_state(other)
    assert not state.parent.exists()
    drop_fit_state(state)  # nothing left to drop: no error


def test_a_saved_state_of_another_fit_is_not_gone_on_from(tmp_path, capsys):
    """A state saved by a fit with another seed, other settings or other views, or a truncated
    file, is reported and ignored: the fit starts at step 0 and makes a fresh fit's weights."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=8, batch=4, crop=32, lr=1e-2, log_every=2, checkpoint_every=2)
    ref, _ = fit_detector(samples, cfg, seed=0)
    state = tmp_path / "0.pt"
    others = ((cfg, 1, samples), (dataclasses.replace(cfg, lr=5e-3), 0, samples), (cfg, 0, _rectangles(seed=1)))
    for c, seed, views in others:
        with pytest.raises(KeyboardInterrupt):
            fit_detector(views, c, seed=seed, progress=_stop_after(5), resume=state)
        model, _ = fit_detector(samples, cfg, seed=0, resume=state)
        assert "other settings or views" in capsys.readouterr().err
        assert all(torch.equal(model.state_dict()[k], v) for k, v in ref.state_dict().items())
    state.write_bytes(b"not a state")
    model, _ = fit_detector(samples, cfg, seed=0, resume=state)
    assert "unreadable" in capsys.readouterr().err
    assert all(torch.equal(model.state_dict()[k], v) for k, v in ref.state_dict().items())
    with pytest.raises(ConfigError, match="checkpoint_every = -1"):
        DetectorTrainConfig(checkpoint_every=-1)


def test_weight_averaging_is_the_mean_of_the_weights_after_the_warm_up():
    """average_fit against a slow reference: the same steps taken one by one (the same crops,
    Adam afresh, the rate warmed up), each step's weights kept after the warm-up and their mean
    taken; the fit it starts from is left as it was, and the mean is no single step's weights."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=40, batch=4, crop=32, lr=1e-2, log_every=5,
                              average_steps=12, average_lr=5e-3, average_warmup=4)
    model, _ = fit_detector(samples, cfg, seed=0)
    before = {k: v.clone() for k, v in model.state_dict().items()}
    avg = average_fit(model, samples, cfg, seed=3)
    assert all(torch.equal(before[k], v) for k, v in model.state_dict().items())
    assert isinstance(avg, TinyUNet) and not avg.training

    net = copy.deepcopy(model).train()
    opt = torch.optim.Adam(net.parameters(), lr=cfg.average_lr)
    g, weight, kept = torch.Generator().manual_seed(3), class_weights(samples), []
    for step in range(1, cfg.average_steps + 1):
        opt.param_groups[0]["lr"] = cfg.average_lr * min(1.0, step / cfg.average_warmup)
        x, y = _crop_batch(samples, cfg.batch, cfg.crop, g)
        loss = torch.nn.functional.cross_entropy(net(x), y, weight=weight, ignore_index=-100)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step > cfg.average_warmup:
            kept.append({k: v.detach().clone() for k, v in net.state_dict().items()})
    assert len(kept) == 8
    got = avg.state_dict()
    for k in got:
        want = torch.stack([w[k] for w in kept]).mean(0)
        torch.testing.assert_close(got[k], want, rtol=1e-5, atol=1e-6)
    assert not torch.allclose(got["head.weight"], kept[-1]["head.weight"])
    assert not torch.allclose(got["head.weight"], before["head.weight"])
    assert pixel_accuracy(avg, samples) > 0.9  # still a detector


def test_an_interrupted_averaging_goes_on_to_the_mean_of_an_uninterrupted_one(tmp_path, capsys):
    """average_fit stopped before the warm-up ends, stopped between two saves after it, and
    stopped by SIGTERM within a step, each rerun from its state: the mean, bit for bit, and the
    logged losses of an averaging never stopped, the curve's rows once each. A finished one
    keeps its state (a rerun takes no step) until dropped; a state saved while averaging
    another fit's weights, or with another rate, is reported and not gone on from."""
    samples = _rectangles()
    cfg = DetectorTrainConfig(width=8, steps=20, batch=4, crop=32, lr=1e-2, log_every=2, checkpoint_every=4,
                              average_steps=12, average_lr=5e-3, average_warmup=4)
    model, _ = fit_detector(samples, cfg, seed=0)
    ref = average_fit(model, samples, cfg, seed=3)
    state = average_state_path(tmp_path / "resume" / "0.pt")
    assert state.name == "0.average.pt"

    for stop, interrupt, kept in ((2, _stop_after(2), 2), (9, _stop_after(9), 9), (6, _term_at(6), 7)):
        with pytest.raises(KeyboardInterrupt):
            average_fit(model, samples, cfg, seed=3, progress=interrupt, resume=state)
        assert torch.load(state, weights_only=False)["step"] == kept, stop
        run = StageRun("t", tmp_path / f"o{stop}", tmp_path / f"d{stop}", 0)
        (tmp_path / f"d{stop}").mkdir()
        got = average_fit(model, samples, cfg, seed=3, curve=run.curve(["seed", "loss"]), resume=state)
        run._finish()
        assert all(torch.equal(got.state_dict()[k], v) for k, v in ref.state_dict().items()), stop
        steps = [int(r.split(",")[0]) for r in (tmp_path / f"d{stop}" / "curve.csv").read_text().split()[1:]]
        assert steps == [2, 4, 6, 8, 10, 12]
        assert torch.load(state, weights_only=False)["step"] == 12  # the finished one, until dropped
        taken = []

        def counting(it, **kw):
            for x in it:
                taken.append(x)
                yield x

        again = average_fit(model, samples, cfg, seed=3, progress=counting, resume=state)
        assert taken == [] and all(torch.equal(again.state_dict()[k], v) for k, v in ref.state_dict().items())
        drop_fit_state(state)
        assert not state.exists() and not state.parent.exists()
    other, _ = fit_detector(samples, cfg, seed=1)
    for m, c in ((other, cfg), (model, dataclasses.replace(cfg, average_lr=1e-3))):
        with pytest.raises(KeyboardInterrupt):
            average_fit(m, samples, c, seed=3, progress=_stop_after(5), resume=state)
        got = average_fit(model, samples, cfg, seed=3, resume=state)
        assert "other settings or views, averaging from step 0" in capsys.readouterr().err
        assert all(torch.equal(got.state_dict()[k], v) for k, v in ref.state_dict().items())
        drop_fit_state(state)


def test_the_averaging_settings_are_checked():
    DetectorTrainConfig(average_steps=0)  # off: the warm-up is not looked at
    for kw, what in (({"average_steps": 100}, "average_warmup = 100"), ({"average_steps": -1}, "average_steps = -1"),
                     ({"average_steps": 200, "average_lr": 0.0}, "average_lr")):
        with pytest.raises(ConfigError, match=what):
            DetectorTrainConfig(**kw)
    with pytest.raises(ValueError, match="warm-up"):
        average_fit(TinyUNet(8), _rectangles(1), DetectorTrainConfig(average_steps=0), seed=0)


def test_match_fronts_counts_each_true_front_once():
    t = np.zeros((10, 20), np.int64)
    t[:, :10], t[:, 10:] = 1, 2
    t[0, 0] = 3  # a one-pixel part: not counted
    a, b = t == 1, t == 2
    half = np.zeros_like(a)
    half[:, 10:13] = True
    assert match_fronts([a, b], t, 2, 0.5) == (2, 2, 2)
    assert match_fronts([a, a.copy()], t, 2, 0.5) == (1, 2, 2)  # the duplicate is a false positive
    assert match_fronts([half], t, 2, 0.5) == (0, 1, 2)  # IoU 0.3
    assert match_fronts([], t, 2, 0.5) == (0, 0, 2)


def test_the_fit_kitchens_take_the_layout_keys_and_the_scored_ones_do_not(tmp_path):
    """detector.layout is merged over the fit (train) kitchens' layout after the split's values,
    never over the test kitchens it is scored on; an unknown key stops the fit before any work."""
    base = {"source": "synth", "synth": {"seed": 0, "layout": {"module_widths": [0.5]}}}
    over = {"module_widths": [0.3, 0.8], "no_handle_p": 0.2}
    fit = kitchen_scene(base, "train", 3, layout=over).synth.layout
    plain = kitchen_scene(base, "train", 3).synth.layout
    assert fit.module_widths == [0.3, 0.8] and fit.no_handle_p == 0.2
    assert plain.module_widths == [0.5] and plain.no_handle_p == 0.1  # the train split's own rate
    assert fit.carcass_height == plain.carcass_height  # the split's other values stay
    r = run_stage("detector_fit", tmp_path, "detector.kitchens=[0]", "detector.eval_kitchens=[0]",
                  "+detector.layout.module_width=[0.3]")
    assert r.returncode != 0 and "detector.layout: unknown keys ['module_width']" in r.stderr
    assert not (tmp_path / "bench" / "detector_fits" / "0").exists()
    for key in ("average_layout", "layout_beside"):
        with pytest.raises(ConfigError, match=rf"detector.{key}: unknown keys \['gap'\]"):
            check_layouts(DetectorTrainConfig(**{key: {"gap": 0.001}}))
    with pytest.raises(ConfigError, match="needs detector.average_steps > 0"):
        DetectorTrainConfig(average_layout={"front_gap": 0.001}, average_steps=0)
    with pytest.raises(ValueError, match="a layout over the test split's kitchens"):
        fit_views(DetectorTrainConfig(), base, RenderConfig(), "test", [0], StageRun("detector", tmp_path, tmp_path, 0),
                   {"front_gap": 0.001})


def test_detector_and_detect_stages_end_to_end(tmp_path, exact_capture):
    """Fits from seeds 0 and 1 (the detector_fit stage, one folder each); the detector stage
    makes seed 0 alone, not averaged, the very file of its fit, seeds [0, 1] one ensemble whose
    members are those fits bit for bit, and seed 0 averaged a network of its own; a fit that is
    missing or made with other settings stops it, naming the fit; then the detect stage reads
    the detector."""
    short = ["detector.kitchens=[0]", "detector.eval_kitchens=[0]", "detector.steps=6", "detector.log_every=3",
             "detector.frame_every=16", "detector.crop=64", "+detector.layout.no_handle_p=0.5",
             "detector.average_steps=0"]
    fits = tmp_path / "bench" / "detector_fits"
    for seed in (0, 1):  # seed 1 also on its kitchen drawn once more, with thinner gaps between fronts
        beside = ["+detector.layout_beside.front_gap=0.001"] if seed else []
        r = run_stage("detector_fit", tmp_path, *short, f"seed={seed}", "detector.checkpoint_every=2", *beside)
        assert r.returncode == 0, r.stderr[-3000:]
    assert not (tmp_path / "bench" / "detector_fit_resume").exists()  # kept at steps 2 and 4, gone when done
    m = json.loads((fits / "0" / "metrics.json").read_text())
    assert m["train_views"] == 3 and m["test_views"] == 3 and m["wall_s"] > 0 and "layout_beside" not in m
    mb = json.loads((fits / "1" / "metrics.json").read_text())
    assert mb["train_views"] == 6 and mb["layout_beside_views"] == 3 and mb["layout_beside"] == {"front_gap": 0.001}
    assert {"fronts_2d_precision_test", "fronts_2d_recall_test", "pixel_accuracy_test"} <= set(m)
    assert (fits / "0" / "curve.csv").read_text().splitlines()[0] == "step,wall_s,loss"
    d = tmp_path / "bench" / "detector"
    r = run_stage("detector", tmp_path, *short, "detector.seeds=[1,2]")
    assert r.returncode != 0 and "seed 2 is missing" in r.stderr and "dvc repro detector_fit@2" in r.stderr
    assert not d.exists()
    r = run_stage("detector", tmp_path, *[a for a in short if not a.startswith("detector.steps=")], "detector.steps=7")
    assert r.returncode != 0 and "'steps': 6" in r.stderr and "'steps': 7" in r.stderr and not d.exists()
    r = run_stage("detector", tmp_path, *short, "detector.seeds=[0]")  # one seed: the fit itself
    assert r.returncode == 0, r.stderr[-3000:]
    assert (d / "weights.pt").read_bytes() == (fits / "0" / "weights.pt").read_bytes()
    m1 = json.loads((d / "metrics.json").read_text())
    assert m1["seeds"] == [0] and m1["fronts_2d_recall_test"] == m["fronts_2d_recall_test"]
    assert m1["train_views"] == 3 and m1["wall_s"] != m["wall_s"]  # its own run's
    r = run_stage("detector", tmp_path, *short, "detector.seeds=[0,1]")
    assert r.returncode == 0, r.stderr[-3000:]
    m2 = json.loads((d / "metrics.json").read_text())
    each = [json.loads((fits / s / "metrics.json").read_text())["fronts_2d_recall_test"] for s in ("0", "1")]
    assert m2["seeds"] == [0, 1] and m2["fronts_2d_recall_test_members"] == each and m2["test_views"] == 3
    one, other, two = (torch.load(p, weights_only=True) for p in (fits / "0" / "weights.pt", fits / "1" / "weights.pt",
                                                                  d / "weights.pt"))
    assert len(two["members"]) == 2 and two["info"]["seeds"] == [0, 1]
    for k in one["state_dict"]:
        assert torch.equal(one["state_dict"][k], two["members"][0][k]) and torch.equal(other["state_dict"][k], two["members"][1][k])
    assert not all(torch.equal(two["members"][0][k], two["members"][1][k]) for k in one["state_dict"])
    assert isinstance(load_detector(d / "weights.pt")[0], DetectorEnsemble)
    r = run_stage("detector", tmp_path, *[a for a in short if not a.startswith("detector.average_steps=")],
                  "detector.seeds=[0]", "detector.average_steps=4", "detector.average_warmup=1")
    assert r.returncode == 0, r.stderr[-3000:]  # one fit trained on and its weights averaged
    avg = torch.load(d / "weights.pt", weights_only=True)
    assert avg["info"]["average"] == {"steps": 4, "lr": 1e-3, "warmup": 1} and "members" not in avg
    assert not all(torch.equal(one["state_dict"][k], avg["state_dict"][k]) for k in one["state_dict"])
    m3 = json.loads((d / "metrics.json").read_text())
    assert m3["average_steps"] == 4 and m3["train_views"] == 3 and m3["test_views"] == 3
    assert not (tmp_path / "bench" / "detector_fit_resume").exists()  # the averaging's state, gone when done
    assert m3["fronts_2d_recall_test_members"] == each[:1] and "fronts_2d_recall_test" in m3
    assert (d / "curve.csv").read_text().splitlines()[0] == "step,wall_s,seed,loss"
    # averaged over the fit kitchens rendered twice, the second time with thinner gaps between fronts
    r = run_stage("detector", tmp_path / "gaps", *[a for a in short if not a.startswith("detector.average_steps=")],
                  "detector.average_steps=4", "detector.average_warmup=1", "+detector.average_layout.front_gap=0.001")
    assert r.returncode != 0 and "seed 0 is missing" in r.stderr  # its own folder holds no fit yet
    shutil.copytree(fits, tmp_path / "gaps" / "bench" / "detector_fits")
    r = run_stage("detector", tmp_path / "gaps", *[a for a in short if not a.startswith("detector.average_steps=")],
                  "detector.average_steps=4", "detector.average_warmup=1", "+detector.average_layout.front_gap=0.001")
    assert r.returncode == 0, r.stderr[-3000:]
    mg = json.loads((tmp_path / "gaps" / "bench" / "detector" / "metrics.json").read_text())
    assert mg["train_views"] == 3 and mg["average_layout_views"] == 3 and mg["average_layout"] == {"front_gap": 0.001}
    gaps = torch.load(tmp_path / "gaps" / "bench" / "detector" / "weights.pt", weights_only=True)
    assert gaps["info"]["average"] == {"steps": 4, "lr": 1e-3, "warmup": 1, "layout": {"front_gap": 0.001}}
    assert not all(torch.equal(gaps["state_dict"][k], avg["state_dict"][k]) for k in one["state_dict"])
    # the detector_score stage: that detector as the pipeline decodes it, the fits' decoding beside it
    ds = tmp_path / "bench" / "detector_score"
    r = run_stage("detector_score", tmp_path, *short, "detect.builtin.merge_edge=0.5")  # the library's: both the same
    assert r.returncode == 0, r.stderr[-3000:]
    s5 = json.loads((ds / "metrics.json").read_text())
    assert s5["test_views"] == 3 and s5["merge_edge"] == 0.5 and s5["wall_s"] > 0
    assert s5["fronts_2d_recall_test"] == s5["fronts_2d_recall_test_fit_decoding"] == m3["fronts_2d_recall_test"]
    assert s5["fronts_2d_precision_test_fit_decoding"] == m3["fronts_2d_precision_test"]
    r = run_stage("detector_score", tmp_path, *short, "detect.builtin.merge_edge=0.0", "detect.builtin.min_score=0.0",
                  "detect.builtin.min_area_px=1")
    assert r.returncode == 0, r.stderr[-3000:]
    s0 = json.loads((ds / "metrics.json").read_text())
    assert s0["merge_edge"] == 0.0 and s0["fronts_2d_recall_test_fit_decoding"] == m3["fronts_2d_recall_test"]
    assert s0["fronts_pred"] >= s0["fronts_pred_fit_decoding"]  # no merging, no score floor: at least as many fronts
    r = run_stage("detector_score", tmp_path, *short, "detect.builtin.working_size=128")
    assert r.returncode != 0 and "working size 256" in r.stderr and "detect.builtin.working_size = 128" in r.stderr
    assert json.loads((ds / "metrics.json").read_text()) == s0  # what was computed is kept
    r = run_stage("detector_score", tmp_path / "elsewhere", *short)
    assert r.returncode != 0 and "the built-in detector is missing" in r.stderr and "dvc repro detector" in r.stderr
    assert not (tmp_path / "elsewhere" / "bench" / "detector_score").exists()
    sp = scene_paths(tmp_path)
    shutil.copytree(exact_capture[0], sp.capture)
    r = run_stage("detect", tmp_path, "detect.model=builtin", "detect.builtin.min_score=0.0", "detect.builtin.min_area_px=1")
    assert r.returncode == 0, r.stderr[-3000:]
    cap = apply_overlay(load_capture(sp.capture), sp.file("detect", "index"))
    for i in range(len(cap.frames)):
        lab, rows = cap.detections(i)
        assert sorted(np.unique(lab[lab > 0]).tolist()) == [r["id"] for r in rows]
        assert {r["label"] for r in rows} <= {"front", "handle", "object"}
    md = json.loads(sp.metrics("detect").read_text())
    assert md["model"] == "builtin" and md["near_band"] == DECODE_BAND  # decisions near their thresholds, counted
    assert set(md["near_decisions"]) == {"merge", "merge_band", "score"} and 0 <= md["near_frames"] <= len(cap.frames)
    assert sum(map(len, md["near_by_frame"].values())) <= sum(md["near_decisions"].values())
    assert "logit_jitter" not in md
    r = run_stage("detect", tmp_path, "detect.model=builtin", "detect.builtin.min_score=0.0", "detect.builtin.min_area_px=1",
                  "detect.builtin.logit_jitter=0.001")  # a stability study's run says so
    assert r.returncode == 0, r.stderr[-3000:]
    assert json.loads(sp.metrics("detect").read_text())["logit_jitter"] == 0.001
    if not torch.cuda.is_available():  # a device this machine lacks: one line naming the key, nothing lost
        before = sp.metrics("detect").read_text()
        r = run_stage("detect", tmp_path, "detect.model=builtin", "detect.device=cuda")
        assert r.returncode == 2 and r.stderr.strip().splitlines()[-1].startswith("error: detect.device = 'cuda'")
        assert sp.metrics("detect").read_text() == before
        r = run_stage("detector_fit", tmp_path / "gpu", *short, "detector.device=cuda")
        assert r.returncode == 2 and "error: detector.device = 'cuda'" in r.stderr and "render" not in r.stderr
        assert not (tmp_path / "gpu" / "bench").exists()
