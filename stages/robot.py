"""DVC stage ``robot@<scene>``: ``twin/`` + ``parts.json`` -> ``out/<scene>/robot/`` (a Panda opens
and closes every part of the twin by its handle, each demonstration replayed in the scene's own
kitchen when it has one; ``attempts.json``, the demonstrations as a LeRobot v3.0 dataset under
``dataset/``, ``metrics.json`` with ``robot_success`` and ``robot_transfer_success``).

    python -m stages.robot scene=kitchen_small
    python -m stages.robot -cn dvc_stage scene=kitchen_small robot.camera=[0,0]
"""

import drawer_lib.synth.gl  # noqa: F401, I001  (MuJoCo reads MUJOCO_GL once, at import: the camera renders offscreen)
import hydra
from omegaconf import DictConfig

from drawer_lib.capture.config import SceneConfig
from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.robot.pipeline import run_robot, scene_ground_truth
from drawer_lib.robot.plan import RobotConfig
from drawer_lib.sim.config import SimConfig
from drawer_lib.stability.pipeline import choice_option


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    rc = to_typed(RobotConfig, cfg.robot, "robot")
    sim = to_typed(SimConfig, cfg.sim, "sim")
    sc = to_typed(SceneConfig, cfg.scene, f"conf/scene/{scene}.yaml:", strict=False)
    src, dst = scene_paths(cfg, scene)
    choice = src.file("stability", "choice")  # the integrator and timestep of the stability study
    with stage_run("robot", dst.stage_dir("robot"), seed=cfg.seed) as run:
        option = choice_option(choice) if choice.is_file() else None
        if option is None:
            run.skip("stability_choice", f"{choice} is missing: the twin's own integrator and timestep")
        gt = scene_ground_truth(sc, sim) if rc.transfer else None
        run.metrics.update(run_robot(rc, src.stage_dir("twin"), src.parts, run, option, gt))


if __name__ == "__main__":
    main()
