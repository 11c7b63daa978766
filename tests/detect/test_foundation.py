"""The detect and priors stages on the paper's foundation models, each built from a tiny
configuration with random weights (tiny_hf.py): loading from a local folder, pre- and
post-processing, and the capture format of what they write, end to end as programs; a missing
model is one line naming the command that fetches it."""

import dataclasses
import json
import shutil

import numpy as np
import pytest
from helpers import run_stage, scene_paths

from drawer_lib.detect.config import DetectConfig, PriorsConfig
from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import pixel_dirs
from drawer_lib.hub import HubModel, model_dir
from drawer_lib.io.capture import load_capture
from drawer_lib.io.images import read_json, read_u16
from drawer_lib.io.overlay import apply_overlay, capture_manifest

pytest.importorskip("transformers")
from tiny_hf import tiny_depth_anything, tiny_owlv2, tiny_sam  # noqa: E402


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    d = tmp_path_factory.mktemp("hf")
    return {"owl": tiny_owlv2(d / "owl"), "sam": tiny_sam(d / "sam"), "da": tiny_depth_anything(d / "da"),
            "da_metric": tiny_depth_anything(d / "da_metric", metric=True)}


@pytest.fixture()
def project(tmp_path, exact_capture):
    shutil.copytree(exact_capture[0], scene_paths(tmp_path).capture)
    return tmp_path


def test_owlv2_sam_detect_stage_writes_the_capture_format(project, models):
    r = run_stage("detect", project, "detect.model=owlv2_sam", f"detect.foundation.detector.path={models['owl']}",
                  f"detect.foundation.segmenter.path={models['sam']}", "detect.foundation.box_threshold=0.0",
                  "detect.foundation.min_area_px=1", "detect.foundation.max_per_frame=6")
    assert r.returncode == 0, r.stderr[-3000:]
    sp = scene_paths(project)
    m = json.loads(sp.metrics("detect").read_text())
    assert m["model"] == "owlv2_sam" and m["has_detections"] and m["s_per_frame"] > 0
    cap = apply_overlay(load_capture(sp.capture), sp.file("detect", "index"))
    labels = set()
    for i in range(len(cap.frames)):
        lab, rows = cap.detections(i)
        assert lab.dtype == np.uint16 and lab.shape == (cap.intrinsics.height, cap.intrinsics.width)
        assert sorted(np.unique(lab[lab > 0]).tolist()) == [r["id"] for r in rows]  # ids local to the frame, 1..n
        assert len(rows) <= 6 and all(0 <= r["score"] <= 1 for r in rows)
        labels |= {r["label"] for r in rows}
    assert labels and labels <= {"drawer", "door", "handle", "object"}
    man = capture_manifest(cap)
    assert man.has["detections"] and man.details["detections"]["model"] == "owlv2_sam"
    assert "parts_2d_precision" in m  # scored against the synthetic scene's ground truth


@pytest.mark.parametrize("metric", [False, True])
def test_depth_anything_priors_stage_writes_depth_and_unit_normals(project, models, metric):
    r = run_stage("priors", project, "priors.model=depth_anything",
                  f"priors.depth_model.path={models['da_metric' if metric else 'da']}", "priors.working_size=56")
    assert r.returncode == 0, r.stderr[-3000:]
    sp = scene_paths(project)
    cap = apply_overlay(load_capture(sp.capture), sp.file("priors", "index"))
    assert cap.has("mono_depth_file_path") and cap.has("mono_normal_file_path")
    d, n = cap.mono_depth(0), cap.mono_normal(0)  # the reader checks shape and dtype
    assert np.isfinite(d).all() and (d > 0).all()
    assert np.allclose(np.linalg.norm(n, axis=-1), 1.0, atol=2e-3)
    assert (np.sum(n * pixel_dirs(cap.intrinsics), axis=-1) <= 1e-3).all()  # facing the camera
    det = capture_manifest(cap).details["mono_depth"]
    assert det["model"] == "depth_anything" and det["metric"] is metric
    if not metric:  # 1 / (d / d_99 + shift): bounded by 1 / shift
        assert d.max() <= 1 / 0.05 + 1e-3


def test_a_missing_model_names_the_command_that_fetches_it(project, tmp_path, monkeypatch):
    monkeypatch.setenv("HF_HOME", str(tmp_path / "empty_hf_home"))
    with pytest.raises(InputError, match=r"hf download google/owlv2-base-patch16-ensemble"):
        model_dir(DetectConfig().foundation.detector, False, "detect.foundation.detector")
    with pytest.raises(InputError, match=r"no config.json"):
        model_dir(HubModel("x/y", path=str(tmp_path)), False, "priors.depth_model")
    r = run_stage("priors", project, "priors.model=depth_anything", f"priors.depth_model.path={tmp_path / 'nowhere'}")
    last = r.stderr.strip().splitlines()[-1]
    assert r.returncode == 2 and last.startswith("error: priors.depth_model.path") and "hf download" in last
    assert not scene_paths(project).priors.exists()
    assert PriorsConfig().depth_model.repo.startswith("depth-anything/")


@pytest.mark.gpu
def test_the_foundation_models_on_cuda_give_what_they_give_on_the_cpu(models):
    """``detect.device`` / ``priors.device: cuda``: the same boxes, scores and masks (a pixel
    or two may flip on a mask's rim) as on the CPU, and the same depth within 0.1 % at the
    median and 2 % at worst (cuDNN's TF32 convolutions, on by default for inference; an H200
    gave 0.86 % at worst)."""
    from drawer_lib.detect.config import FoundationDetectConfig
    from drawer_lib.detect.foundation import DepthAnythingPriors, OwlSamDetector
    from drawer_lib.geometry.camera import Intrinsics

    g = np.random.default_rng(0)
    rgb = np.full((96, 128, 3), 90, np.uint8)
    rgb[10:60, 8:60], rgb[20:90, 70:120] = (200, 180, 150), (60, 120, 200)
    rgb = np.clip(rgb + g.integers(-8, 9, rgb.shape), 0, 255).astype(np.uint8)
    f = FoundationDetectConfig(detector=HubModel("x/owl", path=str(models["owl"])),
                               segmenter=HubModel("x/sam", path=str(models["sam"])),
                               box_threshold=0.0, min_area_px=1, max_per_frame=6)
    cpu, gpu = (OwlSamDetector(DetectConfig(model="owlv2_sam", device=d, foundation=f))(rgb) for d in ("cpu", "cuda"))
    assert len(cpu) == len(gpu) > 0
    for a, b in zip(cpu, gpu):
        assert a.label == b.label and abs(a.score - b.score) < 1e-3
        assert (a.mask != b.mask).sum() <= max(2, 0.01 * a.mask.sum())
    intr = Intrinsics(100.0, 100.0, 64.0, 48.0, 128, 96)
    for key in ("da", "da_metric"):
        pc = PriorsConfig(model="depth_anything", depth_model=HubModel("x/da", path=str(models[key])), working_size=56)
        (dc, nc), (dg, ng) = (DepthAnythingPriors(dataclasses.replace(pc, device=d))(rgb, intr) for d in ("cpu", "cuda"))
        rel = np.abs(dg - dc) / dc
        assert np.median(rel) < 1e-3 and rel.max() < 2e-2, (np.median(rel), rel.max())
        assert np.median(np.abs(ng.astype(np.float32) - nc.astype(np.float32))) < 1e-2
