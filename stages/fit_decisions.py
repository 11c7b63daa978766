"""DVC stage ``fit_decisions``: the decision weights fitted on the benchmark's train kitchens
-> ``<paths.bench>/fit/`` (``weights.json``, which every ``articulate`` stage reads with
``articulate.types.weights: fitted``; ``cv.csv``: the cross-validated accuracy of each penalty;
``cases.json``: the hand-built hard cases with these weights; ``metrics.json``).

    python -m stages.fit_decisions -cn dvc_stage
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.bench.config import BenchConfig
from drawer_lib.bench.fit import run_fit
from drawer_lib.config.stage import bench_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    bc = to_typed(BenchConfig, cfg.bench, "bench")
    ac = to_typed(ArticulateConfig, cfg.articulate, "articulate")
    src, dst = bench_paths(cfg)
    with stage_run("fit", dst.fit, seed=bc.seed) as run:
        run.metrics.update(run_fit(bc, ac, src, run))


if __name__ == "__main__":
    main()
