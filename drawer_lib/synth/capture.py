"""Render a procedural kitchen into a capture folder (docs/formats.md#capture) with ground truth."""

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drawer_lib.errors import NonFiniteError
from drawer_lib.geometry.camera import Camera, Intrinsics, invert_rigid, opencv_to_opengl
from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.io.capture import Capture, Frame, split_every, write_transforms
from drawer_lib.io.images import write_depth, write_json, write_rgb, write_u16
from drawer_lib.io.manifest import Manifest
from drawer_lib.paths import capture_name
from drawer_lib.synth.camera_path import camera_path
from drawer_lib.synth.config import DepthSensorConfig, DetectionsConfig, MonoConfig, RenderConfig, SynthConfig
from drawer_lib.synth.gt import write_gt
from drawer_lib.synth.layout import sample_layout
from drawer_lib.synth.model import KitchenRenderer, build_model
from drawer_lib.synth.sensors import (
    DetectableEntity,
    DetectionStats,
    PartFailures,
    decide_part_failures,
    false_front_mask,
    mono_depth,
    mono_normals,
    place_false_fronts,
    sensor_depth,
    simulate_detections,
)


@dataclass(frozen=True)
class Sensors:
    depth: DepthSensorConfig
    mono: MonoConfig
    detections: DetectionsConfig
    render: RenderConfig


def _detectables(layout) -> list[DetectableEntity]:
    out = []
    for e in layout.entities:
        if e.family == "static":
            out.append(DetectableEntity("none", ""))
        elif e.family == "object":
            out.append(DetectableEntity("object", e.label))
        else:
            out.append(DetectableEntity("front", e.label))
    return out


def _front_boxes(layout, detectables: list[DetectableEntity]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Each front's axis-aligned box (m) in the kitchen's own frame (its walls along the axes)."""
    R, t = layout.pose[:3, :3], layout.pose[:3, 3]
    out = {}
    for k, (e, d) in enumerate(zip(layout.entities, detectables)):
        if d.kind == "front":
            v = (e.mesh().verts - t) @ R
            out[k] = (v.min(0), v.max(0))
    return out


def render_synth_capture(scene: str, synth: SynthConfig, sensors: Sensors, test_every: int, out: Path,
                         rng: np.random.Generator, progress: Callable = lambda it, **kw: it) -> tuple[Manifest, dict]:
    """Render ``synth`` into ``out`` (which must exist): images, depth, mono priors, detections,
    ground truth, ``transforms.json``. Returns the manifest and metrics.

    The layout and camera path depend only on ``synth`` (the scene's identity); sensor noise
    draws from ``rng``.
    """
    layout = sample_layout(synth)
    cc = synth.camera
    intr = Intrinsics.from_fovy(np.deg2rad(cc.fovy_deg), cc.width, cc.height)
    km = build_model(layout, intr, sensors.render)
    poses_cv = camera_path(layout, cc, np.random.default_rng([synth.seed, 2]))

    parts, mesh, _ = write_gt(layout, out / capture_name("gt"))
    (out / capture_name("gt_instances")).mkdir(parents=True, exist_ok=True)
    D = {k: capture_name(k) for k in ("images", "depth", "mono_depth", "mono_normal", "detections", "gt_instances")}
    rc = Raycaster(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    inst_of_entity = np.array([e.instance_id for e in layout.entities], np.uint16)
    detectables = _detectables(layout)

    dep_cfg, mono_cfg, det_cfg = sensors.depth, sensors.mono, sensors.detections
    dstats = DetectionStats()
    failures, part_rng = PartFailures(), None
    if det_cfg.enabled and det_cfg.persistent:  # decided once, per part (draws only when on)
        part_rng = np.random.default_rng(int(rng.integers(2**63)))
        failures = decide_part_failures(detectables, _front_boxes(layout, detectables), det_cfg, part_rng)
    depth_err, depth_valid, n_dets = [], [], []
    frames = []
    renderer = KitchenRenderer(km, intr)
    try:
        for k in progress(range(cc.n_frames), desc="render", total=cc.n_frames):
            stem = f"frame_{k:05d}"
            c2w_gl = opencv_to_opengl(poses_cv[k])
            renderer.set_camera(c2w_gl)
            rgb, z, ent, handle = renderer.render()
            if not np.all(np.isfinite(z)):
                raise NonFiniteError(f"{scene}: non-finite rendered depth in frame {stem}")
            w2c = invert_rigid(poses_cv[k])
            _, n_cam, _ = rc.depth_normals(intr, w2c)
            fr = {"file_path": f"{D['images']}/{stem}.png"}
            write_rgb(out / fr["file_path"], rgb)
            if dep_cfg.enabled:
                zs = sensor_depth(z, n_cam, intr, dep_cfg, rng)
                fr["depth_file_path"] = f"{D['depth']}/{stem}.png"
                write_depth(out / fr["depth_file_path"], zs, dep_cfg.unit_scale)
                ok = zs > 0
                depth_valid.append(float(ok.mean()))
                if ok.any():
                    depth_err.append(np.abs(zs[ok] - z[ok]))
            if mono_cfg.depth_enabled:
                fr["mono_depth_file_path"] = f"{D['mono_depth']}/{stem}.npy"
                np.save(out / fr["mono_depth_file_path"], mono_depth(z, mono_cfg, rng))
            if mono_cfg.normal_enabled:
                fr["mono_normal_file_path"] = f"{D['mono_normal']}/{stem}.npy"
                np.save(out / fr["mono_normal_file_path"], mono_normals(n_cam, mono_cfg, rng))
            if det_cfg.enabled:
                cam = Camera(intr, w2c)
                if k == 0 and det_cfg.n_false_fronts > 0:  # placed where the first view sees static surfaces
                    failures = dataclasses.replace(failures, false_fronts=place_false_fronts(
                        det_cfg.n_false_fronts, z, n_cam, ent == 0, cam, det_cfg.labels == "typed", part_rng))
                world_false = [(false_front_mask(ff, z, ent == 0, cam), ff.label) for ff in failures.false_fronts]
                lab, dets, st = simulate_detections(ent, handle, detectables, det_cfg, rng, failures, world_false)
                fr["detections_path"] = f"{D['detections']}/{stem}.png"
                write_u16(out / fr["detections_path"], lab)
                write_json((out / fr["detections_path"]).with_suffix(".json"), dets, indent=None)
                for f in dataclasses.fields(DetectionStats):
                    setattr(dstats, f.name, getattr(dstats, f.name) + getattr(st, f.name))
                n_dets.append(len(dets))
            inst = np.where(ent >= 0, inst_of_entity[np.maximum(ent, 0)], 0).astype(np.uint16)
            write_u16(out / D["gt_instances"] / f"{stem}.png", inst)
            frames.append(Frame(fr["file_path"], c2w_gl, fr.get("depth_file_path"), fr.get("mono_depth_file_path"),
                                fr.get("mono_normal_file_path"), fr.get("detections_path")))
    finally:
        renderer.close()

    train, test = split_every(len(frames), test_every)
    cap = Capture(out, intr, frames, train, test, dep_cfg.unit_scale,
                  extra={"scene": scene, "source": "synth", "seed": synth.seed})
    write_transforms(cap)

    kinds = parts.kinds()
    manifest = Manifest(
        scene=scene, source="synth", n_frames=len(frames), n_train=len(train), n_test=len(test),
        width=intr.width, height=intr.height,
        has={"rgb": True, "depth": dep_cfg.enabled, "mono_depth": mono_cfg.depth_enabled,
             "mono_normal": mono_cfg.normal_enabled, "detections": det_cfg.enabled, "sparse_points": False,
             "gt": True},
        lacks={"depth": "disabled by capture.depth.enabled=false",
               "mono_depth": "disabled by capture.mono.depth_enabled=false",
               "mono_normal": "disabled by capture.mono.normal_enabled=false",
               "detections": "disabled by capture.detections.enabled=false",
               "sparse_points": "synthetic capture: poses are exact, no structure-from-motion was run"},
        details={
            "depth": {"kind": "sensor", "exact": dep_cfg.exact} if dep_cfg.enabled else {},
            "mono_depth": {"exact": mono_cfg.exact} if mono_cfg.depth_enabled else {},
            "mono_normal": {"exact": mono_cfg.exact} if mono_cfg.normal_enabled else {},
            "detections": {"labels": det_cfg.labels, "perfect": det_cfg.perfect} if det_cfg.enabled else {},
            "poses": {"kind": "exact"},
        },
        world_frame={"metric_scale": True, "gravity": True,
                     "how": "synthetic world: metres, +z up, back wall at y = 0, fronts facing -y" if
                     np.allclose(layout.pose, np.eye(4)) else
                     "synthetic world: metres, +z up, the kitchen turned about z by "
                     f"{np.rad2deg(np.arctan2(layout.pose[1, 0], layout.pose[0, 0])):.2f} deg"},
        gt_part_kinds=kinds,
    )
    metrics = {
        "n_frames": len(frames), "n_train": len(train), "n_test": len(test),
        "n_parts_revolute": kinds["revolute"], "n_parts_prismatic": kinds["prismatic"],
        "n_parts_rigid": kinds["rigid"], "n_ignore_boxes": len(parts.ignore_boxes),
        "gt_mesh_faces": int(len(mesh.faces)),
    }
    if depth_err:
        e = np.concatenate(depth_err)
        metrics.update(depth_valid_fraction=round(float(np.mean(depth_valid)), 4),
                       depth_abs_err_median_m=round(float(np.median(e)), 5))
    if n_dets:
        metrics.update(detections_per_frame=round(float(np.mean(n_dets)), 2), detections_missed=dstats.missed,
                       detections_merged=dstats.merged, detections_false=dstats.false)
        if det_cfg.persistent:
            metrics.update({f"detections_{k}": v for k, v in failures.summary().items()},
                           detections_world_false=dstats.world_false)
    return manifest, metrics
