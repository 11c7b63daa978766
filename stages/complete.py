"""DVC stage ``complete@<scene>``: parts + mesh + SDF + appearance -> ``out/<scene>/complete/``
(the scene cut into bodies: interiors, rigid solids, the static remainder and its collision,
each body's Gaussians; ``complete.json``, ``metrics.json``).

    python -m stages.complete scene=kitchen_small
    python -m stages.complete -cn dvc_stage scene=kitchen_small
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.complete.config import CompleteConfig
from drawer_lib.complete.pipeline import CompleteInputs, run_complete
from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.sim.config import DensityConfig


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    cc = to_typed(CompleteConfig, cfg.complete, "complete")
    density = to_typed(DensityConfig, cfg.sim.densities, "sim.densities").part
    src, dst = scene_paths(cfg, scene)
    cap = load_capture(src.capture, check_files=False)
    inp = CompleteInputs(src.parts, src.mesh, src.decompose, src.field,
                         src.appearance_dir(cc.gaussians.variant))
    with stage_run("complete", dst.stage_dir("complete"), seed=cfg.seed) as run:
        run.metrics.update(run_complete(cc, cap, inp, run, density))


if __name__ == "__main__":
    main()
