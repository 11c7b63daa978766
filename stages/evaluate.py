"""DVC stage ``evaluate@<scene>``: predictions vs the capture's ground truth -> ``out/<scene>/evaluate/``
(``metrics.json``: articulation precision, recall, EA-score and the motion EMD of the simulated
twin (docs/formats.md#metric-definitions); ``matches.json``: which prediction matched which GT part, per-part EMD). Scenes without GT record the skip and its reason.

    python -m stages.evaluate -cn dvc_stage scene=kitchen_small
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.io.capture import load_capture
from drawer_lib.metrics.evaluate import run_evaluate
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    src, dst = scene_paths(cfg, scene)
    cap = load_capture(src.capture, check_files=False)
    with stage_run("evaluate", dst.stage_dir("evaluate"), seed=cfg.seed) as run:
        tracks = src.file("simulate", "tracks")  # absent in a run without the twin: the EMD is skipped
        run.metrics.update(run_evaluate(cap, src.parts, run, tracks if tracks.is_file() else None))


if __name__ == "__main__":
    main()
