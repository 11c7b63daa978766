"""DVC stage ``fit_decisions``: the decision weights fitted on the benchmark's train kitchens
-> ``<paths.bench>/fit/`` (``weights.json``, which every ``articulate`` stage reads with
``articulate.types.weights: fitted``; ``cv.csv``: the cross-validated accuracy of each penalty;
``cases.json``: the hand-built hard cases with these weights; ``metrics.json``).

    python -m stages.fit_decisions -cn dvc_stage
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.bench.config import BenchConfig
from drawer_lib.bench.fit import run_fit
from drawer_lib.config.typed import to_typed
from drawer_lib.paths import BenchPaths
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    bc = to_typed(BenchConfig, cfg.bench, "bench")
    ac = to_typed(ArticulateConfig, cfg.articulate, "articulate")
    bench = BenchPaths(Path(cfg.paths.bench))
    with stage_run("fit", bench.fit, seed=cfg.seed) as run:
        run.metrics.update(run_fit(bc, ac, bench, run))


if __name__ == "__main__":
    main()
