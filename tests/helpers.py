"""Shared test helpers: compose the real configs (and shrink them), render small captures."""

from pathlib import Path

import numpy as np

from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig, SceneConfig
from drawer_lib.config.compose import compose_config
from drawer_lib.config.typed import to_typed

ROOT = Path(__file__).resolve().parent.parent
CONF = ROOT / "conf"


def compose_cfg(overrides: list[str] | None = None, config_name: str = "config"):
    return compose_config(CONF, overrides, config_name)


def load_scene(name: str) -> SceneConfig:
    cfg = compose_cfg([f"scene={name}"])
    return to_typed(SceneConfig, cfg.scene, f"conf/scene/{name}.yaml:")


def sensor_cfg(depth: str = "sensor", mono: str = "noisy", detections: str = "noisy", **video) -> CaptureConfig:
    cfg = compose_cfg([f"capture/depth={depth}", f"capture/mono={mono}", f"capture/detections={detections}"]
                      + [f"capture.video.{k}={v}" for k, v in video.items()])
    return to_typed(CaptureConfig, cfg.capture, "capture")


def render_capture(scene: SceneConfig, cap: CaptureConfig, out: Path, name: str = "test", seed: int = 0):
    out.mkdir(parents=True, exist_ok=True)
    return build_capture(name, scene, cap, out, np.random.default_rng(seed), ROOT)


def run_stage(module: str, tmp: Path, *args: str):
    """``python -m stages.<module> scene=kitchen_tiny`` with outputs, reports and the benchmark
    under ``tmp``."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", f"stages.{module}", "scene=kitchen_tiny", f"paths.out={tmp / 'out'}",
                           f"paths.reports={tmp / 'reports'}", f"paths.bench={tmp / 'bench'}", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)


def run_script(name: str, *args, timeout: int = 120):
    """``python scripts/<name> args...`` (arguments as strings), its output captured."""
    import subprocess
    import sys

    return subprocess.run([sys.executable, str(ROOT / "scripts" / name), *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


def door_part(pid: str, cx: float, kind: str = "revolute"):
    """A 0.5 x 0.7 m front centred at x = ``cx`` facing -y, as a part of ``kind`` hinged on its
    left edge (the parts the scripts' tests write as predictions and ground truth)."""
    from drawer_lib.io.parts import Axis, Front, Part

    fr = Front((cx, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.5, 0.7))
    edge = np.asarray(fr.center) - np.asarray(fr.u) * 0.25
    return Part(pid, kind, Axis(tuple(edge), (0.0, 0.0, -1.0)), (0.0, 1.57), fr)


NS_DIST = (-0.12, 0.03, 0.001, -0.0008)  # a barrel lens, as COLMAP's OPENCV model fits phone cameras


def write_ns_capture(src: Path, out: Path, dist=NS_DIST, quality: int = 95) -> None:
    """The capture at ``src`` (pinhole) as ``ns-process-data`` writes a COLMAP capture: the
    images seen through a lens with OPENCV distortion ``dist`` (same fl_x, fl_y, cx, cy),
    saved as JPEG, ``camera_model: OPENCV`` with k1, k2, p1, p2, ``applied_transform``, no
    train / test lists, no depth or other modalities."""
    import json

    from PIL import Image

    from drawer_lib.geometry.camera import pixel_dirs
    from drawer_lib.geometry.distortion import remap, undistort
    from drawer_lib.io.capture import load_capture

    cap = load_capture(src)
    it = cap.intrinsics
    # where each pixel of the distorted image looks: undistort its normalised coordinates
    xy = undistort(pixel_dirs(it)[..., :2], dist)
    rows, cols = xy[..., 1] * it.fy + it.cy - 0.5, xy[..., 0] * it.fx + it.cx - 0.5
    (out / "images").mkdir(parents=True)
    frames = []
    for k, fr in enumerate(cap.frames):
        name = f"images/frame_{k + 1:05d}.jpg"
        Image.fromarray(remap(cap.image(k), rows, cols)).save(out / name, quality=quality)
        frames.append({"file_path": name, "transform_matrix": np.asarray(fr.c2w_gl).tolist(), "colmap_im_id": k + 1})
    tf = {"w": it.width, "h": it.height, "fl_x": it.fx, "fl_y": it.fy, "cx": it.cx, "cy": it.cy,
          "k1": dist[0], "k2": dist[1], "p1": dist[2], "p2": dist[3], "camera_model": "OPENCV", "frames": frames,
          "applied_transform": [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0]]}
    (out / "transforms.json").write_text(json.dumps(tf, indent=4))


def scene_paths(tmp: Path, scene: str = "kitchen_tiny"):
    """Where :func:`run_stage` puts ``scene``'s outputs (``paths.out`` = ``tmp/out``)."""
    from drawer_lib.paths import ScenePaths

    return ScenePaths(tmp / "out", scene)


def gt_mesh_project(tmp: Path, capture: Path, scene: str = "kitchen_tiny") -> Path:
    """``tmp`` as a project whose ``scene`` has ``capture`` (copied) and its GT mesh as the mesh
    stage's output, for the stages after ``mesh``; returns ``tmp``."""
    import shutil

    from drawer_lib.paths import capture_name

    sp = scene_paths(tmp, scene)
    shutil.copytree(capture, sp.capture)
    sp.mesh.parent.mkdir(parents=True)
    shutil.copy(sp.capture / capture_name("gt_mesh"), sp.mesh)
    return tmp


def quat_to_rot(q):
    """Rotation matrix of one wxyz quaternion of any norm, written out term by term: the slow
    reference the rotation code is tested against."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def add_overlays(tmp: Path, scene: str = "kitchen_tiny", detect: bool = True, priors: bool = True) -> None:
    """The ``detect`` and ``priors`` stages with ``model: capture`` (the capture's own files), as
    ``dvc repro`` runs them before the stages that read them, into ``tmp/out/<scene>/``."""
    from drawer_lib.detect.config import DetectConfig, PriorsConfig
    from drawer_lib.detect.pipeline import run_detect, run_priors
    from drawer_lib.io.capture import load_capture
    from drawer_lib.runner import stage_run

    sp = scene_paths(tmp, scene)
    cap = load_capture(sp.capture, check_files=False)
    if detect:
        with stage_run("detect", sp.detect, seed=0) as r:
            r.metrics.update(run_detect(DetectConfig(), cap, tmp / "bench" / "detector" / "weights.pt", r))
    if priors:
        with stage_run("priors", sp.priors, seed=0) as r:
            r.metrics.update(run_priors(PriorsConfig(), cap, r))
