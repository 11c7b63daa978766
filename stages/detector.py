"""DVC stage ``detector``: the built-in 2D detector, trained on renders of the benchmark's train
split -> ``<paths.bench>/detector/`` (``weights.pt``, ``curve.csv``: loss against time,
``metrics.json``: its fronts' 2D precision and recall on the train views and on the test split's
kitchens, which it never saw).

    python -m stages.detector -cn dvc_stage scene=kitchen_small                # as DVC runs it
    python -m stages.detector scene=kitchen_small detector.steps=300            # a short fit
"""

import hydra
from omegaconf import DictConfig, OmegaConf

from drawer_lib.config.stage import bench_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.detect.config import DetectorTrainConfig
from drawer_lib.detect.train import run_train_detector
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.synth.config import RenderConfig


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    tc = to_typed(DetectorTrainConfig, cfg.detector, "detector")
    render = to_typed(RenderConfig, cfg.capture.render, "capture.render")
    base = OmegaConf.to_container(cfg.scene, resolve=True)
    dst = bench_paths(cfg)[1]
    with stage_run("detector", dst.detector, seed=cfg.seed) as run:
        run.metrics.update(run_train_detector(tc, base, render, cfg.seed, run))


if __name__ == "__main__":
    main()
