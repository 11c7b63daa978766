"""DVC stage ``sdf@<scene>``: capture -> ``out/<scene>/sdf/`` (``field.pt``, ``metrics.json``,
``curve.csv``): the neural SDF or the TSDF baseline, as ``conf/sdf/<name>.yaml`` selects.

    python -m stages.sdf scene=kitchen_small                       # interactive, conf/
    python -m stages.sdf scene=kitchen_small sdf=tsdf              # the TSDF baseline
    python -m stages.sdf -cn dvc_stage scene=kitchen_small         # as DVC runs it: params.yaml
    python -m stages.sdf -cn dvc_stage scene=kitchen_small sdf=neural_mono +geometry_variant=neural_mono
                                                                   # a comparison variant -> out/<scene>/geometry/<v>/sdf
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.sdf.config import SdfConfig
from drawer_lib.sdf.pipeline import run_sdf


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    sdf_cfg = to_typed(SdfConfig, cfg.sdf, "sdf")
    src, dst = scene_paths(cfg, scene)
    cap = load_capture(src.capture)
    with stage_run("sdf", dst.stage_dir("sdf"), seed=cfg.seed) as run:
        run.metrics.update(run_sdf(sdf_cfg, cap, run))


if __name__ == "__main__":
    main()
