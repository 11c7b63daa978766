"""DVC stage ``stability@<scene>``: ``twin/scene.xml`` + ``parts.json`` -> ``out/<scene>/stability/``
(the integrator x timestep x case matrix, its heat map, and ``choice.json``: the integrator and
timestep ``simulate`` runs the twin with; see drawer_lib/stability/pipeline.py).

    python -m stages.stability scene=kitchen_small
    python -m stages.stability -cn dvc_stage scene=kitchen_small
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.stability.pipeline import StabilityConfig, run_stability


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    sc = to_typed(StabilityConfig, cfg.stability, "stability")
    src, dst = scene_paths(cfg, scene)
    default = (str(cfg.sim.integrator), float(cfg.sim.timestep))
    with stage_run("stability", dst.stage_dir("stability"), seed=cfg.seed) as run:
        run.metrics.update(run_stability(sc, src.parts, src.stage_dir("twin"), default, run))


if __name__ == "__main__":
    main()
