"""DVC stage ``detector``: the built-in 2D detector later stages read -> ``<paths.bench>/detector/``
(``weights.pt``, ``metrics.json``), from the fits of ``detector.seeds``
(``<paths.bench>/detector_fits/<seed>/``, the ``detector_fit@<seed>`` stages), each trained on
for ``detector.average_steps`` steps and its weights averaged over them (``curve.csv``: that
loss; 0: the fit as it is). One seed: that network; one seed, not averaged: the fit's very file
and figures. Several: one ensemble averaging their class probabilities. Scored again on the test
split's kitchens, which no fit saw.

    python -m stages.detector -cn dvc_stage scene=kitchen_small                     # as DVC runs it
    python -m stages.detector scene=kitchen_small 'detector.seeds=[0,1]'            # two fits as one (both fitted first)
    python -m stages.detector scene=kitchen_small detector.average_steps=0          # the fit as it is, not averaged

An interrupted averaging (Ctrl-C, SIGTERM, a cluster's time limit) keeps its state every
``detector.checkpoint_every`` steps beside the fit's, in
``<paths.bench>/detector_fit_resume/<seed>.average.pt``; the same command (or ``dvc repro``) goes
on from there to the detector an uninterrupted run makes. The states are removed once the
stage's outputs are in place.
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import bench_paths
from drawer_lib.detect.train import average_state_path, drop_fit_state, run_combine_detector, stage_inputs
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    tc, base, render = stage_inputs(cfg)
    dst = bench_paths(cfg)[1]
    resume = [average_state_path(dst.detector_fit_resume(s)) for s in tc.seeds]
    with stage_run("detector", dst.detector, seed=cfg.seed) as run:
        run.metrics.update(run_combine_detector(tc, base, render, [dst.detector_fit(s) for s in tc.seeds], run, resume))
    for r in resume:  # only now: a kill before the outputs landed costs the rerun no step
        drop_fit_state(r)


if __name__ == "__main__":
    main()
