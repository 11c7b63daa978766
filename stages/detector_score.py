"""DVC stage ``detector_score``: the built-in detector later stages read
(``<paths.bench>/detector/weights.pt``) scored as they decode it (``detect.builtin``) ->
``<paths.bench>/detector_score/metrics.json``: its fronts' 2D precision and recall on the test
split's kitchens (``detector.eval_kitchens``), which no fit saw, with the fits' fixed decoding
beside it. A change to the decoding reruns this stage only, never a fit.

    python -m stages.detector_score -cn dvc_stage scene=kitchen_small                         # as DVC runs it
    python -m stages.detector_score scene=kitchen_small detect.builtin.merge_edge=0.5         # another decoding
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import bench_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.detect.config import DetectConfig
from drawer_lib.detect.train import run_score_detector, stage_inputs
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    tc, base, render = stage_inputs(cfg)
    dc = to_typed(DetectConfig, cfg.detect, "detect").builtin
    src, dst = bench_paths(cfg)
    with stage_run("detector_score", dst.detector_score, seed=cfg.seed) as run:
        run.metrics.update(run_score_detector(tc, dc, base, render, src.detector_weights, run))


if __name__ == "__main__":
    main()
