"""DVC stage ``twin@<scene>``: ``complete/`` + ``parts.json`` -> ``out/<scene>/twin/`` in the
format of docs/formats.md (``scene.xml``, ``urdf/scene.urdf``, ``scene.usda``, ``gaussians/``,
``renders/``, ``twin.json``), checked in MuJoCo before it is written; on synthetic scenes the
opened-state scores against the scene's own model.

    python -m stages.twin scene=kitchen_small
    python -m stages.twin -cn dvc_stage scene=kitchen_small twin.renders.max_views=2
"""

import drawer_lib.synth.gl  # noqa: F401, I001  (MuJoCo reads MUJOCO_GL once, at import: the reference renders offscreen)
import hydra
from omegaconf import DictConfig

from drawer_lib.capture.config import CaptureConfig, SceneConfig
from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.sim.config import SimConfig
from drawer_lib.twin.config import TwinConfig
from drawer_lib.twin.pipeline import run_twin


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    tc = to_typed(TwinConfig, cfg.twin, "twin")
    sim = to_typed(SimConfig, cfg.sim, "sim")
    sc = to_typed(SceneConfig, cfg.scene, f"conf/scene/{scene}.yaml:", strict=False)
    render = to_typed(CaptureConfig, cfg.capture, "capture").render
    src, dst = scene_paths(cfg, scene)
    cap = load_capture(src.capture, check_files=False)
    with stage_run("twin", dst.stage_dir("twin"), seed=cfg.seed) as run:
        run.metrics.update(run_twin(tc, sim, cap, src.parts, src.stage_dir("complete"), run, sc, render))


if __name__ == "__main__":
    main()
