"""DVC stage ``detector_fit@<seed>``: one fit of the built-in 2D detector, trained on renders of
the benchmark's train split from ``seed`` -> ``<paths.bench>/detector_fits/<seed>/``
(``weights.pt``, ``curve.csv``: loss against time, ``metrics.json``: its fronts' 2D precision and
recall on the train views and on the test split's kitchens, which it never saw). One stage per
seed of ``detector.seeds``, so adding a seed fits only that one; the ``detector`` stage makes
them the one detector later stages read.

    python -m stages.detector_fit -cn dvc_stage scene=kitchen_small seed=0        # as DVC runs it
    python -m stages.detector_fit scene=kitchen_small seed=1 paths.bench=DIR      # a fit from another seed, elsewhere
    python -m stages.detector_fit scene=kitchen_small detector.steps=300          # a short fit

An interrupted fit (Ctrl-C, SIGTERM, a cluster's time limit) keeps its state every
``detector.checkpoint_every`` steps in ``<paths.bench>/detector_fit_resume/<seed>.pt``; the same
command (or ``dvc repro``) goes on from there to the weights an uninterrupted fit makes. The
state is removed once the stage's outputs are in place, so a kill while the fit is scored
costs the rerun no training step.
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import bench_paths
from drawer_lib.detect.train import drop_fit_state, run_fit_detector, stage_inputs
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    tc, base, render = stage_inputs(cfg)
    dst = bench_paths(cfg)[1]
    resume = dst.detector_fit_resume(cfg.seed)
    with stage_run("detector_fit", dst.detector_fit(cfg.seed), seed=cfg.seed) as run:
        run.metrics.update(run_fit_detector(tc, base, render, cfg.seed, run, resume))
    drop_fit_state(resume)  # only now: a kill before the outputs landed costs the rerun no step


if __name__ == "__main__":
    main()
