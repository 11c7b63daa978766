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

from drawer_lib.config.stage import geometry_dir, scene_of
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.io.manifest import read_manifest
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.sdf.config import SdfConfig
from drawer_lib.sdf.pipeline import run_sdf


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene, _ = scene_of(cfg)
    sdf_cfg = to_typed(SdfConfig, cfg.sdf, "sdf")
    cap_dir = geometry_dir(cfg, scene, "capture", output=False)
    manifest = read_manifest(cap_dir / "manifest.json")
    cap = load_capture(cap_dir)
    with stage_run("sdf", geometry_dir(cfg, scene, "sdf"), seed=cfg.seed) as run:
        run.metrics.update(run_sdf(sdf_cfg, cap, manifest, run, run.dir))


if __name__ == "__main__":
    main()
