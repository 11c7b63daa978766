"""Shared test helpers: compose the real configs (and shrink them), render small captures."""

from pathlib import Path

import numpy as np
from hydra import compose, initialize_config_dir

from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig, SceneConfig
from drawer_lib.config.typed import to_typed

ROOT = Path(__file__).resolve().parent.parent
CONF = ROOT / "conf"


def compose_cfg(overrides: list[str] | None = None, config_name: str = "config"):
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return compose(config_name=config_name, overrides=list(overrides or []))


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
    """``python -m stages.<module> scene=kitchen_tiny`` with outputs and reports under ``tmp``."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", f"stages.{module}", "scene=kitchen_tiny", f"paths.out={tmp / 'out'}",
                           f"paths.reports={tmp / 'reports'}", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
