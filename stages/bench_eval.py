"""DVC stages ``bench_eval@<split>`` and ``bench_eval_hand``: every kitchen of a benchmark split
(the hand split's: ``bench.hand_kitchens``) articulated with the fitted decision weights and
scored, with its articulation by the prior weights, against its ground truth ->
``<paths.bench>/eval/<split>/`` (``table.md``, ``rows.json``, ``metrics.json``;
``kitchen_<k>/articulate/``).

    python -m stages.bench_eval -cn dvc_stage +bench_split=test
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.weights import resolve_weights
from drawer_lib.bench.config import BenchConfig
from drawer_lib.bench.evaluate import run_eval
from drawer_lib.config.stage import bench_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    bc = to_typed(BenchConfig, cfg.bench, "bench")
    ac = to_typed(ArticulateConfig, cfg.articulate, "articulate")
    split = cfg.get("bench_split")
    if split is None:
        raise ConfigError(f"bench_eval: pass +bench_split=<one of {[*bc.splits, 'hand']}>")
    kitchens = bc.split_kitchens(split)
    src, dst = bench_paths(cfg)
    weights = resolve_weights(ac.types, src.weights)
    with stage_run("bench_eval", dst.eval(split), seed=bc.seed) as run:
        run.metrics.update(run_eval(split, kitchens, src, ac, weights, run))


if __name__ == "__main__":
    main()
