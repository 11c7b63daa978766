"""DVC stage ``sdf@<scene>``: capture -> ``out/<scene>/sdf/`` (``field.pt``, ``metrics.json``,
``curve.csv``): the neural SDF or the TSDF baseline, as ``conf/sdf/<name>.yaml`` selects.

    python -m stages.sdf scene=kitchen_small                       # interactive, conf/
    python -m stages.sdf scene=kitchen_small sdf=tsdf              # the TSDF baseline
    python -m stages.sdf -cn dvc_stage scene=kitchen_small         # as DVC runs it: params.yaml
    python -m stages.sdf -cn dvc_stage scene=kitchen_small sdf=neural_mono +geometry_variant=neural_mono
                                                                   # a comparison variant -> out/<scene>/geometry/<v>/sdf

A comparison variant the scene cannot run (the TSDF on a capture without metric depth) writes
only its ``metrics.json`` with the reason under ``skipped``, and the mesh stage after it does
the same: the comparison records the skip and the run goes on. The scene's own ``sdf`` stage
stops with the error instead.
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import open_capture, scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.io.overlay import capture_manifest
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.sdf.config import SdfConfig
from drawer_lib.sdf.pipeline import run_sdf, unmet_input


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    sdf_cfg = to_typed(SdfConfig, cfg.sdf, "sdf")
    src, dst = scene_paths(cfg, scene)
    cap = open_capture(src, priors=True)
    with stage_run("sdf", dst.stage_dir("sdf"), seed=cfg.seed) as run:
        why = unmet_input(sdf_cfg, capture_manifest(cap))
        if why and cfg.get("geometry_variant") is not None:  # a comparison the scene cannot run: recorded, not fatal
            run.skip("sdf", why)
            return
        run.metrics.update(run_sdf(sdf_cfg, cap, run))


if __name__ == "__main__":
    main()
