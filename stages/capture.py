"""DVC stage ``capture@<scene>``: a scene config -> ``out/<scene>/capture/`` (docs/formats.md#capture).

    python -m stages.capture scene=kitchen_small                    # interactive, conf/
    python -m stages.capture -cn dvc_stage scene=kitchen_small      # as DVC runs it: params.yaml
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig, SceneConfig
from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    scene_cfg = to_typed(SceneConfig, cfg.scene, f"conf/scene/{scene}.yaml:", strict=False)
    cap_cfg = to_typed(CaptureConfig, cfg.capture, "capture")
    _, dst = scene_paths(cfg, scene)
    with stage_run("capture", dst.capture, seed=cfg.seed) as run:
        _, metrics = build_capture(scene, scene_cfg, cap_cfg, run.dir, run.rng, Path.cwd(), run.progress)
        run.metrics.update(metrics)


if __name__ == "__main__":
    main()
