"""DVC stage ``priors@<scene>``: monocular relative depth and normals for every frame ->
``out/<scene>/priors/`` (``mono_depth/<stem>.npy``, ``mono_normal/<stem>.npy`` in the capture
format, ``priors.json`` the index the SDF stage reads in place of the capture's own).

    python -m stages.priors -cn dvc_stage scene=kitchen_small                   # as DVC runs it
    python -m stages.priors scene=my_kitchen priors.model=depth_anything         # Depth Anything (local weights)
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import open_capture, scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.detect.config import PriorsConfig
from drawer_lib.detect.pipeline import run_priors
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    pc = to_typed(PriorsConfig, cfg.priors, "priors")
    src, dst = scene_paths(cfg, scene)
    cap = open_capture(src)
    with stage_run("priors", dst.priors, seed=cfg.seed) as run:
        run.metrics.update(run_priors(pc, cap, run))


if __name__ == "__main__":
    main()
