"""The ``detect``, ``priors`` and ``detector`` stages' work.

``detect`` and ``priors`` write a model's per-frame outputs in the capture format, with an index
(:mod:`drawer_lib.io.overlay`) that later stages read in place of the capture's own files;
``capture`` copies what the capture carries (a synthetic scene's simulated sensors), ``none``
records that there is nothing. (The ``detector`` stage's fit: :mod:`drawer_lib.detect.train`.)
"""

import shutil
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from drawer_lib.detect.config import DetectConfig, PriorsConfig
from drawer_lib.detect.masks import paint_detections
from drawer_lib.errors import CaptureError, InputError
from drawer_lib.io.capture import Capture
from drawer_lib.io.images import read_json, read_u16, write_json, write_u16
from drawer_lib.io.overlay import FRAME_KEY, capture_manifest, write_overlay
from drawer_lib.metrics.detections import match_fronts
from drawer_lib.paths import capture_name
from drawer_lib.runner import StageRun


def _stems(cap: Capture) -> list[str]:
    stems = [f.stem for f in cap.frames]
    if len(set(stems)) != len(stems):
        dup = sorted({s for s in stems if stems.count(s) > 1})[:3]
        raise CaptureError(f"{cap.root / capture_name('transforms')}: frames share file names {dup}; the "
                           "detect and priors stages name their files after the frames'")
    return stems


def _copy_from_capture(cap: Capture, run: StageRun, stage: str, names: tuple[str, ...]) -> tuple[dict, dict]:
    """The capture's own files of modalities ``names`` copied into the stage folder."""
    man = capture_manifest(cap)
    modalities, frames = {}, {f.file_path: {} for f in cap.frames}
    for name in names:
        key = FRAME_KEY[name]
        if not (man.has[name] and cap.has(key)):
            why = man.lacks.get(name) or f"not every frame has {key}"
            modalities[name] = {"has": False, "lacks": f"{stage}.model = capture, and the capture has none: {why}"}
            continue
        out = run.out(name)
        out.mkdir(parents=True, exist_ok=True)
        for f in cap.frames:
            src = cap.root / getattr(f, key)
            dst = out / (f.stem + src.suffix)
            shutil.copyfile(src, dst)
            if name == "detections":
                shutil.copyfile(src.with_suffix(".json"), dst.with_suffix(".json"))
            frames[f.file_path][key] = f"{out.name}/{dst.name}"
        modalities[name] = {"has": True, "details": dict(man.details.get(name, {}))}
    return modalities, frames


def make_detector(cfg: DetectConfig, weights: Path | Sequence[Path]):
    if cfg.model == "builtin":
        from drawer_lib.detect.builtin import BuiltinDetector

        return BuiltinDetector(weights, cfg.builtin, cfg.device)
    from drawer_lib.detect.foundation import OwlSamDetector

    return OwlSamDetector(cfg)


def run_detect(cfg: DetectConfig, cap: Capture, weights: Path | Sequence[Path], run: StageRun) -> dict:
    """Detections of every frame of ``cap`` by ``cfg.model`` (``weights``: the built-in detector's
    file, or several whose fits are averaged), written into the stage folder;
    returns metrics (and, when the capture has ground truth, the front masks' 2D precision /
    recall against its articulated parts, :func:`_score`)."""
    index = run.out("index")
    stems = _stems(cap)
    run.out("detections").mkdir(parents=True, exist_ok=True)  # always there (a DVC output), empty without detections
    m: dict = {"n_frames": len(cap.frames)}
    if cfg.model == "auto":
        has = capture_manifest(cap).has["detections"] and cap.has("detections_path")
        cfg = replace(cfg, model="capture" if has else "builtin")
        m["chosen"] = f"auto: {'the capture has detections' if has else 'the capture has none'}"
    m["model"] = cfg.model
    if cfg.model in ("capture", "none"):
        if cfg.model == "none":
            modalities = {"detections": {"has": False, "lacks": "detect.model = none"}}
            frames: dict = {}
        else:
            modalities, frames = _copy_from_capture(cap, run, "detect", ("detections",))
        write_overlay(index, "detect", cfg.model, modalities, frames)
        m["has_detections"] = modalities["detections"]["has"]
        if m["has_detections"]:
            m.update(_score(cap, run.out("detections"), stems, run))
        return m
    det = make_detector(cfg, weights)
    out = run.out("detections")
    frames, counts = {}, {"front": 0, "drawer": 0, "door": 0, "handle": 0, "object": 0}
    near: dict[str, list[dict]] = {}  # the built-in decoding's decisions near their thresholds, per frame
    t0 = time.perf_counter()
    for i in run.progress(range(len(cap.frames)), desc=cfg.model, total=len(cap.frames)):
        f = cap.frames[i]
        rgb = cap.image(i)
        if cfg.model == "builtin":
            near[stems[i]] = []
            dets = det(rgb, near=near[stems[i]])
        else:
            dets = det(rgb)
        lab, rows = paint_detections(dets, rgb.shape[:2])
        write_u16(out / f"{stems[i]}.png", lab)
        write_json(out / f"{stems[i]}.json", rows, indent=None)
        frames[f.file_path] = {"detections_path": f"{out.name}/{stems[i]}.png"}
        for r in rows:
            counts[r["label"]] = counts.get(r["label"], 0) + 1
    s_per_frame = (time.perf_counter() - t0) / max(len(cap.frames), 1)
    details = {"model": cfg.model, "sources": det.sources}
    write_overlay(index, "detect", cfg.model, {"detections": {"has": True, "details": details}}, frames)
    m.update(has_detections=True, s_per_frame=round(s_per_frame, 4),
             **{f"{k}_per_frame": round(v / max(len(cap.frames), 1), 3) for k, v in counts.items() if v})
    if cfg.model == "builtin":
        m.update(near_summary(near))
        if cfg.builtin.logit_jitter > 0:  # a stability study's run, not a result
            m["logit_jitter"] = cfg.builtin.logit_jitter
    m.update(_score(cap, out, stems, run))
    return m


def near_summary(near: dict[str, list[dict]]) -> dict:
    """What the detect stage's metrics record of the built-in decoding's decisions near their
    thresholds (``near``: per frame, :func:`~drawer_lib.detect.builtin.decode_instances`'s
    lists): the band, how many decisions of each step and how many frames hold one, the least
    |margin| and up to ten frames with the most.

    >>> near_summary({"a": [{"step": "merge", "margin": -2e-4}], "b": []})["near_decisions"]
    {'merge': 1, 'merge_band': 0, 'score': 0}
    """
    from drawer_lib.detect.builtin import DECODE_BAND

    rows = [r for v in near.values() for r in v]
    worst = sorted((s for s in near if near[s]), key=lambda s: (-len(near[s]), s))[:10]
    return {"near_band": DECODE_BAND,
            "near_decisions": {k: sum(r["step"] == k for r in rows) for k in ("merge", "merge_band", "score")},
            "near_frames": sum(bool(v) for v in near.values()),
            "near_least_margin": min((abs(r["margin"]) for r in rows), default=None),
            "near_by_frame": {s: near[s] for s in worst}}


def _score(cap: Capture, det_dir: Path, stems: list[str], run: StageRun) -> dict:
    """2D precision / recall of the front masks against the ground truth's articulated parts
    (gt/ only; IoU >= 0.5, parts of at least 30 px): a mask on a fixed front or an appliance's
    panel counts against precision, as it would against the twin's."""
    man = capture_manifest(cap)
    if not run.needs(man, "detections_2d", "gt"):
        return {}
    from drawer_lib.io.parts import read_parts

    parts = read_parts(cap.root / capture_name("gt_parts"))
    art = np.array(sorted({int(p.instance_id) for p in parts.parts if p.articulated and p.instance_id is not None}))
    tp = n_pred = n_true = 0
    for i, f in enumerate(cap.frames):
        p = cap.root / capture_name("gt_instances") / f"{f.stem}.png"
        if not p.is_file():
            continue
        inst = read_u16(p).astype(np.int64)
        true_ids = np.where(np.isin(inst, art), inst, 0)
        lab = read_u16(det_dir / f"{stems[i]}.png")
        rows = read_json(det_dir / f"{stems[i]}.json")
        masks = [lab == r["id"] for r in rows if r["label"] in ("front", "drawer", "door")]
        a, b, c = match_fronts(masks, true_ids, 30, 0.5)
        tp, n_pred, n_true = tp + a, n_pred + b, n_true + c
    return {"parts_2d_precision": round(tp / n_pred, 4) if n_pred else None,
            "parts_2d_recall": round(tp / n_true, 4) if n_true else None,
            "parts_2d_true": n_true, "parts_2d_pred": n_pred}


def run_priors(cfg: PriorsConfig, cap: Capture, run: StageRun) -> dict:
    """Monocular depth and normals of every frame by ``cfg.model``, written into the stage folder."""
    index = run.out("index")
    stems = _stems(cap)
    for key in ("mono_depth", "mono_normal"):  # always there (DVC outputs), empty without them
        run.out(key).mkdir(parents=True, exist_ok=True)
    m: dict = {"n_frames": len(cap.frames)}
    if cfg.model == "auto":
        man = capture_manifest(cap)
        has = any(man.has[k] and cap.has(FRAME_KEY[k]) for k in ("mono_depth", "mono_normal"))
        cfg = replace(cfg, model="capture" if has else "none")
        m["chosen"] = f"auto: {'the capture has monocular priors' if has else 'the capture has none'}"
    m["model"] = cfg.model
    if cfg.model in ("capture", "none"):
        if cfg.model == "none":
            why = ("priors.model = auto and the capture has none (priors.model=depth_anything computes them from local "
                   "weights)" if "chosen" in m else "priors.model = none")
            modalities = {"mono_depth": {"has": False, "lacks": why}, "mono_normal": {"has": False, "lacks": why}}
            frames: dict = {}
        else:
            modalities, frames = _copy_from_capture(cap, run, "priors", ("mono_depth", "mono_normal"))
        write_overlay(index, "priors", cfg.model, modalities, frames)
        m.update({f"has_{k}": v["has"] for k, v in modalities.items()})
        return m
    from drawer_lib.detect.foundation import DepthAnythingPriors

    est = DepthAnythingPriors(cfg)
    dd, nd = run.out("mono_depth"), run.out("mono_normal")
    frames = {}
    t0 = time.perf_counter()
    for i in run.progress(range(len(cap.frames)), desc=cfg.model, total=len(cap.frames)):
        f = cap.frames[i]
        rgb = cap.image(i)
        intr = cap.frame_intrinsics(i)
        if rgb.shape[:2] != (intr.height, intr.width):
            raise InputError(f"{cap.root / f.file_path}: image {rgb.shape[1]}x{rgb.shape[0]} but its camera is "
                             f"{intr.width}x{intr.height}")
        depth, normal = est(rgb, intr)
        np.save(dd / f"{stems[i]}.npy", depth)
        frames[f.file_path] = {"mono_depth_file_path": f"{dd.name}/{stems[i]}.npy"}
        if normal is not None:
            np.save(nd / f"{stems[i]}.npy", normal)
            frames[f.file_path]["mono_normal_file_path"] = f"{nd.name}/{stems[i]}.npy"
    details = {"model": cfg.model, "sources": est.sources, "metric": est.metric,
               "conversion": "metric depth" if est.metric else f"1 / (d / d_99 + {cfg.inverse_shift})"}
    modalities = {"mono_depth": {"has": True, "details": details},
                  "mono_normal": ({"has": True, "details": {**details, "from": "the depth's gradients"}} if cfg.normals
                                  else {"has": False, "lacks": "priors.normals = false"})}
    write_overlay(index, "priors", cfg.model, modalities, frames)
    m.update(has_mono_depth=True, has_mono_normal=cfg.normals,
             s_per_frame=round((time.perf_counter() - t0) / max(len(cap.frames), 1), 4))
    return m
