"""DVC stage ``capture@<scene>``: a scene config -> ``out/<scene>/capture/`` (DESIGN §4).

    python -m stages.capture scene=kitchen_small                    # interactive, conf/
    python -m stages.capture -cn dvc_stage scene=kitchen_small      # as DVC runs it: params.yaml
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig
from drawer_lib.config.stage import scene_of, stage_dir
from drawer_lib.config.typed import to_typed
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene, scene_cfg = scene_of(cfg)
    cap_cfg = to_typed(CaptureConfig, cfg.capture, "capture")
    with stage_run("capture", stage_dir(cfg, scene, "capture"), seed=cfg.seed) as run:
        _, metrics = build_capture(scene, scene_cfg, cap_cfg, run.dir, run.rng, Path.cwd(), run.progress)
        run.metrics.update(metrics)


if __name__ == "__main__":
    main()
