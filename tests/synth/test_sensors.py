"""Simulated sensors: statistics of the depth camera, monocular priors, detector noise; exact and
perfect settings are exact; degenerate frames are handled."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import trimesh

from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Camera, Intrinsics, pixel_dirs
from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.io.capture import load_capture
from drawer_lib.io.images import read_u16
from drawer_lib.synth.config import DepthSensorConfig, DetectionsConfig, MonoConfig
from drawer_lib.synth.sensors import (
    DetectableEntity,
    FalseFront,
    PartFailures,
    decide_part_failures,
    depth_edges,
    false_front_mask,
    mono_depth,
    mono_normals,
    sensor_depth,
    simulate_detections,
    touching_pairs,
)

K = Intrinsics(50.0, 50.0, 32.0, 24.0, 64, 48)

ROOT = Path(__file__).resolve().parents[2]


def plane(z0=2.0, H=48, W=64):
    z = np.full((H, W), z0)
    n = np.zeros((H, W, 3))
    n[..., 2] = -1.0
    return z, n


def test_exact_depth_is_passthrough(rng):
    z, n = plane()
    z[0, 0] = 0.0
    out = sensor_depth(z, n, K, DepthSensorConfig(exact=True), rng)
    np.testing.assert_array_equal(out, z.astype(np.float32))


def test_depth_noise_follows_the_axial_model(rng):
    cfg = DepthSensorConfig(dropout=0.0)
    for z0 in (1.0, 3.0):
        z, n = plane(z0, 200, 200)
        out = sensor_depth(z, n, Intrinsics(200.0, 200.0, 100.0, 100.0, 200, 200), cfg, rng)
        ok = out > 0
        assert ok.mean() > 0.99
        want = cfg.sigma_base + cfg.sigma_quad * (z0 - cfg.z_ref) ** 2
        assert np.std(out[ok] - z0) == pytest.approx(want, rel=0.1)
        assert abs(np.mean(out[ok] - z0)) < 3 * want / np.sqrt(ok.sum())


def test_depth_holes_at_grazing_angles_edges_and_range(rng):
    cfg = DepthSensorConfig(dropout=0.0, sigma_base=0.0, sigma_quad=0.0)
    H, W = 48, 64
    z, n = plane(2.0, H, W)
    # a strip seen edge-on: its normals are perpendicular to the viewing rays
    d = pixel_dirs(K)
    side = np.cross(d, [0.0, 1.0, 0.0])
    n[:, :10] = (side / np.linalg.norm(side, axis=-1, keepdims=True))[:, :10]
    z[:, 40:] = 3.0  # a depth step at column 40
    z[:5] = 9.0  # beyond max range
    out = sensor_depth(z, n, K, cfg, rng)
    assert np.all(out[5:, :10] == 0)  # grazing
    assert np.all(out[5:, 39:41] == 0)  # both sides of the step
    assert np.all(out[:5] == 0)
    assert np.all(out[10:, 15:35] == 2.0)
    edges = depth_edges(z, 0.04)
    assert edges[5:, 39:41].all() and not edges[10:, 15:35].any()


def test_mono_depth_is_affine_in_depth_when_exact(rng):
    z, _ = plane(2.0)
    yy, xx = np.mgrid[0:48, 0:64]
    z = z + 0.01 * xx + 0.02 * yy
    z[3, 3] = 0.0  # a hole is filled, not propagated
    m = mono_depth(z, MonoConfig(exact=True), rng)
    assert m.dtype == np.float32 and m.min() == 0.0 and m.max() == pytest.approx(1.0)
    ok = z > 0
    A = np.stack([z[ok], np.ones(ok.sum())], 1)
    coef, res, *_ = np.linalg.lstsq(A, m[ok], rcond=None)
    assert np.abs(A @ coef - m[ok]).max() < 1e-5
    noisy = mono_depth(z, MonoConfig(), rng)
    assert np.corrcoef(noisy[ok], z[ok])[0, 1] > 0.95
    with pytest.raises(ValueError, match="no valid depth"):
        mono_depth(np.zeros((4, 4)), MonoConfig(), rng)
    assert np.all(mono_depth(np.full((4, 4), 2.0), MonoConfig(exact=True), rng) == 0)  # flat: no NaN


def test_mono_normals_unit_and_close(rng):
    _, n = plane()
    exact = mono_normals(n, MonoConfig(exact=True), rng).astype(np.float32)
    np.testing.assert_allclose(exact, n, atol=1e-3)
    noisy = mono_normals(n, MonoConfig(normal_noise_deg=4.0), rng).astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(noisy, axis=-1), 1.0, atol=2e-3)
    ang = np.rad2deg(np.arccos(np.clip(np.sum(noisy * n, -1), -1, 1)))
    assert 0.3 < ang.mean() < 6.0


def test_the_shipped_mono_normals_are_as_wrong_as_a_real_estimator(rng):
    """conf/capture/mono/noisy.yaml on a room corner (a floor seen obliquely, two walls): a mean
    angular error of 10-20 deg, structured (a whole frame tilted together), not pixel noise."""
    import yaml

    from drawer_lib.config.typed import to_typed

    cfg = to_typed(MonoConfig, yaml.safe_load(open(ROOT / "conf/capture/mono/noisy.yaml")), "mono")
    H, W = 120, 160
    yy, xx = np.mgrid[0:H, 0:W]
    n = np.zeros((H, W, 3))
    n[...] = [0.0, 0.0, -1.0]
    n[yy > 80] = [0.0, -0.8, -0.6]
    n[(xx < 50) & (yy <= 80)] = [0.7, 0.0, -0.714]
    n[(xx > 110) & (yy <= 80)] = [-0.5, 0.0, -0.866]
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    errs, spread = [], []
    for _ in range(12):
        m = mono_normals(n, cfg, rng).astype(np.float64)
        e = np.rad2deg(np.arccos(np.clip((m * n).sum(-1), -1, 1)))
        errs.append(e.mean())
        spread.append(np.percentile(e[:70, 60:100], 90) - np.percentile(e[:70, 60:100], 10))  # within one wall
    assert 10.0 < np.mean(errs) < 20.0
    assert np.median(spread) < np.mean(errs)  # the error of a plane is mostly shared, not per pixel
    # the per-frame tilt comes from a child generator: the frame's later draws are unchanged
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    mono_normals(n, cfg, a)
    mono_normals(n, MonoConfig(normal_bias_deg=0.0), b)
    assert a.random() == b.random()
    with pytest.raises(ConfigError, match="normal_bias_deg"):
        MonoConfig(normal_bias_deg=95.0)


def _scene():
    """entity map with background, two touching fronts, an object, and a handle on front 1."""
    ent = np.zeros((40, 60), np.int32)
    ent[5:20, 5:25] = 1
    ent[5:20, 25:45] = 2
    ent[25:35, 10:20] = 3
    handle = np.zeros_like(ent, bool)
    handle[10:12, 8:22] = True
    ents = [DetectableEntity("none", ""), DetectableEntity("front", "drawer"), DetectableEntity("front", "door"),
            DetectableEntity("object", "cup")]
    return ent, handle, ents


def test_perfect_detections_are_the_visible_masks(rng):
    ent, handle, ents = _scene()
    cfg = DetectionsConfig(p_miss=0, p_merge=0, ragged_px=0, boundary_noise_px=0, false_rate=0, label_confusion=0,
                           min_area_px=5)
    assert cfg.perfect
    lab, dets, st = simulate_detections(ent, handle, ents, cfg, rng)
    by_label = {d["label"]: d["id"] for d in dets}
    assert sorted(by_label) == ["cup", "door", "drawer", "handle"]
    np.testing.assert_array_equal(lab == by_label["drawer"], (ent == 1) & ~handle)
    np.testing.assert_array_equal(lab == by_label["handle"], handle)
    np.testing.assert_array_equal(lab == by_label["cup"], ent == 3)
    assert st.missed == st.merged == st.false == 0


def test_noisy_detections_miss_merge_and_shuffle(rng):
    ent, handle, ents = _scene()
    cfg = DetectionsConfig(p_merge=1.0, p_miss=0.0, false_rate=0.0, min_area_px=5, labels="generic", detect_handles=False)
    lab, dets, st = simulate_detections(ent, handle, ents, cfg, rng)
    assert st.merged == 1 and {d["label"] for d in dets} == {"front", "object"}
    assert len(dets) == 2  # the two touching fronts came out as one mask
    ids = set()
    for _ in range(20):  # ids are local to the frame: they change from frame to frame
        lab, dets, _ = simulate_detections(ent, handle, ents, DetectionsConfig(min_area_px=5), rng)
        ids.add(tuple(d["id"] for d in dets if d["label"] in ("drawer", "door")))
        assert set(np.unique(lab).tolist()) - {0} == {d["id"] for d in dets}
    assert len(ids) > 1
    miss = simulate_detections(ent, handle, ents, DetectionsConfig(p_miss=1.0, false_rate=0.0), rng)
    assert miss[1] == [] and not miss[0].any()


def test_false_masks_land_on_static_surfaces(rng):
    ent, handle, ents = _scene()
    cfg = DetectionsConfig(p_miss=1.0, false_rate=5.0, min_area_px=5, ragged_px=0, boundary_noise_px=0)
    hits = 0
    for _ in range(10):
        lab, dets, st = simulate_detections(ent, handle, ents, cfg, rng)
        hits += st.false
        assert all(d["score"] <= (cfg.score_range[0] + cfg.score_range[1]) / 2 for d in dets)
    assert hits > 10


def test_empty_frame_gives_no_detections(rng):
    ent = np.full((20, 30), -1, np.int32)
    lab, dets, _ = simulate_detections(ent, np.zeros_like(ent, bool), [DetectableEntity("none", "")],
                                       DetectionsConfig(false_rate=0.0), rng)
    assert dets == [] and lab.dtype == np.uint16 and not lab.any()


def test_capture_sensors_against_ground_truth(noisy_capture, exact_capture):
    """The noisy capture's depth is close to the GT surface, with holes; its detections are
    ids local to frames that do not equal the GT instance ids."""
    out, manifest, metrics = noisy_capture
    cap = load_capture(out)
    mesh = trimesh.load(out / "gt" / "mesh.ply", process=False)
    rc = Raycaster(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    valid, errs = [], []
    for i in range(len(cap.frames)):
        z = cap.depth(i)
        z_rc, _, _ = rc.depth_normals(cap.intrinsics, cap.frames[i].w2c)
        ok = z > 0
        valid.append(ok.mean())
        errs.append(np.abs(z[ok] - z_rc[ok]))
    e = np.concatenate(errs)
    assert 0.8 < np.mean(valid) < 0.995
    assert 0.001 < np.median(e) < 0.02
    assert metrics["depth_valid_fraction"] == pytest.approx(np.mean(valid), abs=1e-3)
    assert manifest.has["detections"] and manifest.details["detections"]["perfect"] is False
    gt_ids = set()
    for i, f in enumerate(cap.frames):
        gt_ids |= set(np.unique(read_u16(out / "gt" / "instances" / f"{f.stem}.png")).tolist())
    lab, dets = cap.detections(0)
    assert {d["label"] for d in dets} <= {"drawer", "door", "handle", "cup", "bottle", "kettle", "box", "object"}
    exact_out, _, _ = exact_capture
    ecap = load_capture(exact_out)
    for i in range(len(ecap.frames)):
        lab, dets = ecap.detections(i)
        inst = read_u16(exact_out / "gt" / "instances" / f"{ecap.frames[i].stem}.png")
        for d in dets:  # perfect masks lie inside exactly one GT instance
            vals = np.unique(inst[lab == d["id"]])
            assert len(vals) == 1 and vals[0] > 0


def test_sensor_configs_reject_bad_values():
    from drawer_lib.errors import ConfigError

    with pytest.raises(ConfigError, match="dropout"):
        DepthSensorConfig(dropout=1.5)
    with pytest.raises(ConfigError, match="labels"):
        DetectionsConfig(labels="fancy")
    with pytest.raises(ConfigError, match="p_miss"):
        dataclasses.replace(DetectionsConfig(), p_miss=-0.1)
    with pytest.raises(ConfigError, match="p_never"):
        DetectionsConfig(p_never=1.5)
    with pytest.raises(ConfigError, match="n_false_fronts"):
        DetectionsConfig(n_false_fronts=-1)


CLEAN = dict(p_miss=0.0, p_merge=0.0, ragged_px=0, boundary_noise_px=0, false_rate=0.0, label_confusion=0.0,
             min_area_px=5)


def _labels_over_views(fail, n=200, rng=None, **cfg):
    """How often each label is detected over ``n`` views of the test scene with ``fail``."""
    ent, handle, ents = _scene()
    c = DetectionsConfig(**{**CLEAN, **cfg})
    counts, n_dets = {}, []
    for _ in range(n):
        _, dets, _ = simulate_detections(ent, handle, ents, c, rng, fail)
        for d in dets:
            counts[d["label"]] = counts.get(d["label"], 0) + 1
        n_dets.append(len(dets))
    return counts, n_dets


def test_a_part_never_detected_is_missing_from_every_view(rng):
    counts, _ = _labels_over_views(PartFailures(never=frozenset({1})), rng=rng)
    assert counts == {"door": 200, "cup": 200}  # the drawer and its handle


def test_a_sparse_part_is_seen_in_a_quarter_of_its_views(rng):
    counts, _ = _labels_over_views(PartFailures(sparse=frozenset({2})), rng=rng)
    assert 30 <= counts["door"] <= 70 and counts["drawer"] == 200  # Binomial(200, 0.25): 50 ± 6


def test_a_handle_never_found_and_a_label_swapped_in_every_view(rng):
    counts, _ = _labels_over_views(PartFailures(no_handle=frozenset({1}), swapped=frozenset({1, 2})), n=50, rng=rng)
    assert "handle" not in counts and counts == {"door": 50, "drawer": 50, "cup": 50}
    # generic labels have nothing to swap
    counts, _ = _labels_over_views(PartFailures(swapped=frozenset({1})), n=5, rng=rng, labels="generic")
    assert counts == {"front": 10, "handle": 5, "object": 5}


def test_touching_fronts_merged_in_most_views(rng):
    counts, n_dets = _labels_over_views(PartFailures(merged=((1, 2),)), rng=rng, detect_handles=False)
    merged = sum(n == 2 for n in n_dets)  # drawer + door as one mask, and the cup
    assert set(n_dets) <= {2, 3} and 140 <= merged <= 180  # Binomial(200, 0.8): 160 ± 6
    # fronts that do not touch in the image are never merged
    ent, handle, ents = _scene()
    ent[5:20, 25:30] = 0  # a 5-px gap: farther than the 2-px dilation reaches
    _, dets, st = simulate_detections(ent, handle, ents, DetectionsConfig(**CLEAN, merge_views=1.0), rng,
                                      PartFailures(merged=((1, 2),)))
    assert st.merged == 0 and {d["label"] for d in dets} >= {"drawer", "door"}


def test_touching_pairs_of_boxes():
    box = lambda lo, hi: (np.array(lo, float), np.array(hi, float))  # noqa: E731
    boxes = {1: box([0, 0, 0], [0.5, 0.02, 0.7]), 2: box([0.503, 0, 0], [1.0, 0.02, 0.7]),  # 3 mm gap
             3: box([0, 0, 0.72], [0.5, 0.02, 0.9]),  # 2 cm above 1: too far
             4: box([2, 0, 0], [2.5, 0.02, 0.7])}
    assert touching_pairs(boxes) == [(1, 2)]
    assert touching_pairs(boxes, gap=0.025) == [(1, 2), (1, 3), (2, 3)]


def test_part_failures_are_decided_per_part_and_draw_nothing_when_off():
    ent, handle, ents = _scene()
    boxes = {1: (np.zeros(3), np.array([0.5, 0.02, 0.7])), 2: (np.array([0.5, 0, 0]), np.array([1.0, 0.02, 0.7]))}
    r = np.random.default_rng(3)
    state = r.bit_generator.state
    assert decide_part_failures(ents, boxes, DetectionsConfig(), r) == PartFailures()
    assert r.bit_generator.state == state
    every = DetectionsConfig(p_never=0.0, p_sparse=1.0, p_merge_part=1.0, p_no_handle=1.0, p_label_part=1.0)
    f = decide_part_failures(ents, boxes, every, r)
    assert f.sparse == {1, 2, 3} and f.merged == ((1, 2),) and f.no_handle == {1, 2} and f.swapped == {1, 2}
    f = decide_part_failures(ents, boxes, dataclasses.replace(every, p_never=1.0), r)
    assert f.never == {1, 2, 3} and not f.sparse  # a part never seen is not also sparse


def test_a_false_front_is_fixed_in_the_world_and_occluded_like_a_surface():
    H, W = K.height, K.width
    z, _ = plane(2.0, H, W)
    static = np.ones((H, W), bool)
    cam = Camera(K, np.eye(4))
    ff = FalseFront(np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, -1.0]), np.array([1.0, 0.0, 0.0]),
                    np.array([0.0, 1.0, 0.0]), (0.2, 0.1), "front")
    m = false_front_mask(ff, z, static, cam)
    # 0.4 m x 0.2 m at 2 m with f = 50 px: the pixel centres within 5 x 2.5 px of (32, 24)
    ys, xs = np.nonzero(m)
    assert m.sum() == 40 and (xs.min(), xs.max(), ys.min(), ys.max()) == (27, 36, 22, 25)
    # seen from elsewhere it stays where it is in the world: the camera 0.4 m to the right sees it shifted left
    w2c_r = np.eye(4)
    w2c_r[0, 3] = -0.4
    xs_r = np.nonzero(false_front_mask(ff, z, static, Camera(K, w2c_r)))[1]
    assert xs_r.min() == xs.min() - 10
    # a part in front of it hides it; a surface 5 cm behind it is not it
    occ = static.copy()
    occ[:, :32] = False
    assert false_front_mask(ff, z, occ, cam).sum() == 20
    assert not false_front_mask(ff, z + 0.05, static, cam).any()


def test_a_capture_with_persistent_failures_reports_them(tmp_path, tiny_scene):
    from helpers import render_capture, sensor_cfg

    cap = sensor_cfg(detections="persistent")
    cap = dataclasses.replace(cap, detections=dataclasses.replace(cap.detections, p_never=0.5, n_false_fronts=2))
    _, metrics = render_capture(tiny_scene, cap, tmp_path)
    assert metrics["detections_false_fronts"] == 2 and metrics["detections_world_false"] > 0
    assert metrics["detections_parts_never_detected"] >= 1
