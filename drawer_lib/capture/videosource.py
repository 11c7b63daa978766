"""The ``video`` source: a video (or image folder) -> frames -> pycolmap SfM -> capture folder.

The capture has RGB, poses, intrinsics and sparse points; it has no depth and no detections
(the manifest says so). Its world frame is fixed as :func:`drawer_lib.sfm.align.gravity_frame`
describes (gravity from the mean camera up direction), and its metric scale is estimated from
the floor, the worktop and the cameras' height (:mod:`drawer_lib.sfm.scale`).
"""

import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import trimesh

from drawer_lib.capture.config import VideoSource
from drawer_lib.capture.dirsource import resolve_input
from drawer_lib.errors import CaptureError
from drawer_lib.geometry.camera import opencv_to_opengl
from drawer_lib.io.capture import Capture, Frame, load_capture, split_every, write_transforms
from drawer_lib.io.images import read_rgb, write_rgb
from drawer_lib.io.manifest import Manifest
from drawer_lib.io.mesh import load_mesh
from drawer_lib.paths import capture_name
from drawer_lib.sfm.align import Sim3, gravity_frame, pose_errors
from drawer_lib.sfm.colmap import reconstruct
from drawer_lib.sfm.config import VideoConfig
from drawer_lib.sfm.scale import estimate_scale
from drawer_lib.sfm.video import drop_blurriest, read_frames


def reference_distance(ref: Capture) -> float:
    """Median distance from the reference cameras to the scene (median valid depth), in the
    reference's units; NaN when the reference has neither depth nor a GT mesh."""
    if ref.has("depth_file_path"):
        meds = []
        for i in range(len(ref.frames)):
            d = ref.depth(i)
            if (d > 0).any():
                meds.append(float(np.median(d[d > 0])))
        return float(np.median(meds)) if meds else float("nan")
    mesh_path = ref.root / capture_name("gt_mesh")
    if mesh_path.is_file():
        from drawer_lib.geometry.raycast import Raycaster

        m = load_mesh(mesh_path)
        rc = Raycaster(np.asarray(m.vertices), np.asarray(m.faces))
        meds = []
        for f in ref.frames:
            z, _, _ = rc.depth_normals(ref.intrinsics, f.w2c)
            if (z > 0).any():
                meds.append(float(np.median(z[z > 0])))
        return float(np.median(meds)) if meds else float("nan")
    return float("nan")


def score_poses(cap: Capture, ref_dir: Path) -> dict:
    """Pose errors of ``cap`` against the reference capture at ``ref_dir`` (frames matched by
    file stem), after a similarity alignment of the camera centres."""
    ref = load_capture(ref_dir, check_files=False)
    ref_by_stem = {f.stem: f for f in ref.frames}
    pairs = [(f, ref_by_stem[f.stem]) for f in cap.frames if f.stem in ref_by_stem]
    if len(pairs) < 3:
        raise CaptureError(f"{ref_dir}: fewer than 3 frames share a name with the video's frames")
    est = np.stack([a.c2w for a, _ in pairs])
    gt = np.stack([b.c2w for _, b in pairs])
    err = pose_errors(est, gt)
    dist = reference_distance(ref)
    z_est_in_ref = err.sim3.R @ np.array([0.0, 0.0, 1.0])
    out = {
        "pose_rot_err_median_deg": round(float(np.median(err.rot_err_deg)), 4),
        "pose_rot_err_max_deg": round(float(np.max(err.rot_err_deg)), 4),
        "pose_center_err_median_m": round(float(np.median(err.center_err)), 5),
        "pose_center_err_max_m": round(float(np.max(err.center_err)), 5),
        "scale_to_reference": round(float(err.sim3.s), 4),
        "gravity_err_deg": round(float(np.rad2deg(np.arccos(np.clip(z_est_in_ref[2], -1, 1)))), 3),
    }
    if np.isfinite(dist):
        out["reference_distance_m"] = round(dist, 4)
        out["pose_center_err_rel"] = round(float(np.median(err.center_err)) / dist, 5)
    return out


def import_video_capture(scene: str, src: VideoSource, cfg: VideoConfig, test_every: int, out: Path, root: Path,
                         seed: int = 0, progress: Callable = lambda it, **kw: it) -> tuple[Manifest, dict]:
    path = resolve_input(root, src.path, f"scene {scene}: video.path")
    t0 = time.perf_counter()
    frames = read_frames(path, cfg.frame_step, cfg.max_frames, cfg.max_image_size)
    if len(frames) < 3:
        raise CaptureError(f"{path}: {len(frames)} frames decoded; SfM needs at least 3")
    kept, dropped = drop_blurriest(frames, cfg.drop_blurriest)
    names = [f"frame_{f.index:05d}.png" for f in kept]
    with tempfile.TemporaryDirectory(prefix="drawer_sfm_") as tmp:
        work = Path(tmp)
        raw = work / "raw"
        raw.mkdir()
        for f, n in zip(progress(kept, desc="write frames", total=len(kept)), names):
            write_rgb(raw / n, np.ascontiguousarray(f.rgb))
        t_sfm = time.perf_counter()
        res = reconstruct(raw, names, work / "colmap", cfg, seed)
        sfm_s = time.perf_counter() - t_sfm
        n_reg = 0 if res is None else len(res.c2w)
        frac = n_reg / len(kept)
        if res is None or frac < cfg.min_registered_fraction:
            missing = sorted(set(names) - set(res.c2w if res else {}))
            raise CaptureError(
                f"{path}: structure-from-motion registered {n_reg}/{len(kept)} frames "
                f"({frac:.0%} < video.min_registered_fraction = {cfg.min_registered_fraction:.0%}); "
                f"unregistered: {missing[:10]}{' ...' if len(missing) > 10 else ''}")
        reg = [n for n in names if n in res.c2w]
        c2w = np.stack([res.c2w[n] for n in reg])
        depths = np.array([res.depths.get(n, np.nan) for n in reg])
        sim = gravity_frame(c2w, res.points, depths, cfg.assumed_median_depth_m)
        # the metric scale from what the reconstruction shows (floor, worktop, camera height)
        scale = estimate_scale(sim.apply(res.points) if len(res.points) else np.zeros((0, 3)),
                               sim.apply(c2w[:, :3, 3]), depths * sim.s, cfg.scale, src.counter_height_m)
        sim = Sim3(sim.s * scale.factor, sim.R, sim.t * scale.factor)
        c2w_w = sim.apply_c2w(c2w)
        out_frames = []
        for n, T in zip(reg, c2w_w):
            out_frames.append(Frame(f"{capture_name('images')}/{n}", opencv_to_opengl(T)))
            write_rgb(out / out_frames[-1].file_path, read_rgb(res.image_dir / n))
        pts = sim.apply(res.points) if len(res.points) else res.points
        trimesh.PointCloud(pts, colors=res.colors).export(out / capture_name("sparse_points"))

    train, test = split_every(len(out_frames), test_every)
    if not train or not test:
        raise CaptureError(f"{path}: {len(out_frames)} registered frames are too few for a train/test split")
    cap = Capture(out, res.intrinsics, out_frames, train, test,
                  extra={"scene": scene, "source": "video", "ply_file_path": capture_name("sparse_points")})
    write_transforms(cap)
    metrics = {
        "n_frames": len(out_frames), "n_train": len(train), "n_test": len(test),
        "video_frames_read": len(frames), "video_frames_dropped_blurry": len(dropped),
        "video_frames_kept": len(kept), "video_frames_registered": n_reg,
        "registered_fraction": round(frac, 4), "sfm_points": int(len(pts)), "sfm_models": res.n_models,
        "sfm_reproj_error_px": round(res.mean_reproj_error_px, 4), "sfm_s": round(sfm_s, 3),
        "video_total_s": round(time.perf_counter() - t0, 3),
    }
    if src.reference:
        metrics.update(score_poses(cap, resolve_input(root, src.reference, f"scene {scene}: video.reference")))
    used = [k for k, c in scale.cues.items() if c.get("used")]
    metrics |= {"scale_sigma_log": round(scale.sigma, 4), "scale_cues": "+".join(used)}
    why = "RGB video: no depth sensor"
    manifest = Manifest(
        scene=scene, source="video", n_frames=len(out_frames), n_train=len(train), n_test=len(test),
        width=res.intrinsics.width, height=res.intrinsics.height,
        has={"rgb": True, "depth": False, "mono_depth": False, "mono_normal": False, "detections": False,
             "sparse_points": True, "gt": False},
        lacks={"depth": why, "mono_depth": "no monocular estimator has been run on the video",
               "mono_normal": "no monocular estimator has been run on the video",
               "detections": "no 2D detector has been run on the video", "gt": "real video: no ground truth"},
        details={"poses": {"kind": "sfm", "registered": n_reg, "kept": len(kept),
                           "unregistered": sorted(set(names) - set(reg)), "dropped_blurry": dropped},
                 "sparse_points": {"n": int(len(pts))}},
        world_frame={"metric_scale": bool(scale.sigma <= cfg.scale.metric_sigma), "gravity": False,
                     "how": (f"RGB only: +z = the direction orthogonal to the cameras' x axes (assumes no roll, not "
                             f"measured); scale estimated from {', '.join(used)} to about "
                             f"{100 * (math.exp(scale.sigma) - 1):.0f} % (1 sigma)"),
                     "scale": scale.to_json() | {"metric_sigma": cfg.scale.metric_sigma}},
    )
    return manifest, metrics
