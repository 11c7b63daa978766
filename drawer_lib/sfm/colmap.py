"""Structure from motion with pycolmap: SIFT features, sequential or exhaustive matching,
incremental mapping with one shared camera, undistortion to a pinhole camera."""

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drawer_lib.geometry.camera import Intrinsics
from drawer_lib.sfm.config import VideoConfig

log = logging.getLogger(__name__)


@dataclass
class SfMResult:
    """Registered frames of the largest reconstruction, after undistortion (PINHOLE).

    ``c2w`` are OpenCV camera-to-world matrices in COLMAP's arbitrary world frame; ``depths``
    the median z-depth of the points each image observes."""

    intrinsics: Intrinsics
    image_dir: Path  # undistorted images, named as the inputs
    c2w: dict[str, np.ndarray]
    points: np.ndarray  # [P, 3]
    colors: np.ndarray  # [P, 3] uint8
    depths: dict[str, float]
    n_models: int
    mean_reproj_error_px: float


def reconstruct(image_dir: Path, names: list[str], work: Path, cfg: VideoConfig, seed: int = 0) -> SfMResult | None:
    """Run SfM on ``image_dir/<names>``; None when nothing could be reconstructed."""
    import pycolmap

    level = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = 1  # COLMAP's INFO lines drown the stage's own progress
    try:
        return _reconstruct(pycolmap, image_dir, names, work, cfg, seed)
    finally:
        pycolmap.logging.minloglevel = level


def _reconstruct(pycolmap, image_dir: Path, names: list[str], work: Path, cfg: VideoConfig, seed: int) -> SfMResult | None:
    work.mkdir(parents=True, exist_ok=True)
    db = work / "database.db"
    if db.exists():
        db.unlink()
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = cfg.camera_model
    extract = pycolmap.FeatureExtractionOptions()
    extract.sift.max_num_features = cfg.max_num_features
    extract.sift.peak_threshold = cfg.sift_peak_threshold
    extract.num_threads = cfg.num_threads
    extract.use_gpu = False
    log.info("SfM: SIFT features of %d frames", len(names))
    pycolmap.extract_features(db, image_dir, image_names=names, camera_mode=pycolmap.CameraMode.SINGLE,
                              reader_options=reader, extraction_options=extract, device=pycolmap.Device.cpu)
    log.info("SfM: %s matching", cfg.matcher)
    match = pycolmap.FeatureMatchingOptions()
    match.num_threads = cfg.num_threads
    match.use_gpu = False
    if cfg.matcher == "sequential":
        pairing = pycolmap.SequentialPairingOptions()
        pairing.overlap = cfg.overlap
        pairing.loop_detection = False
        pycolmap.match_sequential(db, matching_options=match, pairing_options=pairing, device=pycolmap.Device.cpu)
    else:
        pycolmap.match_exhaustive(db, matching_options=match, device=pycolmap.Device.cpu)

    opts = pycolmap.IncrementalPipelineOptions()
    opts.num_threads = cfg.num_threads
    opts.random_seed = seed
    opts.multiple_models = True
    sparse = work / "sparse"
    sparse.mkdir(exist_ok=True)
    log.info("SfM: incremental mapping")
    recs = pycolmap.incremental_mapping(db, image_dir, sparse, options=opts)
    if not recs:
        return None
    best_id = max(recs, key=lambda k: recs[k].num_reg_images())
    best = recs[best_id]
    model_dir = work / "model"
    model_dir.mkdir(exist_ok=True)
    best.write(model_dir)

    log.info("SfM: %d/%d frames registered; undistorting", best.num_reg_images(), len(names))
    undist = work / "undistorted"
    pycolmap.undistort_images(undist, model_dir, image_dir)
    rec = pycolmap.Reconstruction(undist / "sparse")

    cams = list(rec.cameras.values())
    cam = cams[0]
    intr = Intrinsics(float(cam.focal_length_x), float(cam.focal_length_y), float(cam.principal_point_x),
                      float(cam.principal_point_y), int(cam.width), int(cam.height))

    c2w, depths = {}, {}
    pts = {pid: p.xyz for pid, p in rec.points3D.items()}
    for img in rec.images.values():
        if not img.has_pose:
            continue
        cfw = img.cam_from_world()
        M = np.eye(4)
        M[:3, :4] = cfw.matrix()
        c2w[img.name] = np.linalg.inv(M)
        ids = [p2.point3D_id for p2 in img.points2D if p2.has_point3D()]
        if ids:
            X = np.stack([pts[i] for i in ids])
            z = X @ M[:3, :3].T[:, 2] + M[2, 3]
            depths[img.name] = float(np.median(z[z > 0])) if np.any(z > 0) else float("nan")
    P = np.stack([p.xyz for p in rec.points3D.values()]) if rec.points3D else np.zeros((0, 3))
    C = np.stack([p.color for p in rec.points3D.values()]).astype(np.uint8) if rec.points3D else np.zeros((0, 3), np.uint8)
    return SfMResult(intr, undist / "images", c2w, P, C, depths, len(recs),
                     float(rec.compute_mean_reprojection_error()))
