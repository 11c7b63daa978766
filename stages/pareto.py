"""DVC stage ``pareto@<scene>`` (only for scenes in ``pareto.scenes``; the ``pareto`` experiment):
Hydra multiruns of the sdf and appearance stage apps over iteration budget x resolution x variant
-> ``out/<scene>/pareto/`` (``jobs/``, ``table.md``, ``table.json``, ``curves.png``,
``metrics.json``: the best setting per wall-time budget).

    python -m stages.pareto -cn dvc_stage scene=kitchen_small pareto.scenes=[kitchen_small]
"""

from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from drawer_lib.config.stage import scene_name
from drawer_lib.config.typed import to_typed
from drawer_lib.report.pareto import DIR, ParetoConfig, run_grid
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    pcfg = to_typed(ParetoConfig, cfg.pareto, "pareto")
    with stage_run("pareto", Path(cfg.paths.out) / scene / DIR, seed=cfg.seed) as run:
        # the jobs compose the same primary config as this run (dvc_stage under DVC: params.yaml)
        run.metrics.update(run_grid(pcfg, scene, run.dir, HydraConfig.get().job.config_name, str(cfg.paths.out),
                                    run.progress_write))


if __name__ == "__main__":
    main()
