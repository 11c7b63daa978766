"""DVC stage ``simulate@<scene>``: ``twin/scene.xml`` + ``parts.json`` -> ``out/<scene>/simulate/``
(every articulated part driven open through its actuator: ``tracks.npz`` of its front's points,
``motion.json``, ``metrics.json``; the motion EMD against GT is computed by ``evaluate``).

    python -m stages.simulate scene=kitchen_small
    python -m stages.simulate -cn dvc_stage scene=kitchen_small
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.simulate.pipeline import SimulateConfig, run_simulate


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    sc = to_typed(SimulateConfig, cfg.simulate, "simulate")
    src, dst = scene_paths(cfg, scene)
    with stage_run("simulate", dst.stage_dir("simulate"), seed=cfg.seed) as run:
        run.metrics.update(run_simulate(sc, src.parts, src.stage_dir("twin"), run, src.file("stability", "choice")))


if __name__ == "__main__":
    main()
