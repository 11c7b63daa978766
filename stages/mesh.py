"""DVC stage ``mesh@<scene>``: ``sdf/field.pt`` -> ``out/<scene>/mesh/`` (``mesh.ply``, and
``metrics.json`` against ``gt/mesh.ply`` when the capture has ground truth).

    python -m stages.mesh scene=kitchen_small                      # interactive, conf/
    python -m stages.mesh -cn dvc_stage scene=kitchen_small        # as DVC runs it: params.yaml
    python -m stages.mesh -cn dvc_stage scene=kitchen_small +geometry_variant=tsdf
                                                                   # a comparison variant's field
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.mesh.config import MeshConfig
from drawer_lib.mesh.pipeline import run_mesh
from drawer_lib.runner import main_guard, read_skips, stage_run
from drawer_lib.sdf.io import load_field


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    mesh_cfg = to_typed(MeshConfig, cfg.mesh, "mesh")
    src, dst = scene_paths(cfg, scene)
    cap = load_capture(src.capture, check_files=False)
    skipped = read_skips(src.metrics("sdf")).get("sdf") if cfg.get("geometry_variant") is not None else None
    if skipped:  # the comparison's sdf could not run on this scene: say so, write no mesh
        with stage_run("mesh", dst.stage_dir("mesh"), seed=cfg.seed) as run:
            run.skip("mesh", f"no field: the sdf was skipped ({skipped})")
        return
    field = load_field(src.field)
    with stage_run("mesh", dst.stage_dir("mesh"), seed=cfg.seed) as run:
        run.metrics.update(run_mesh(mesh_cfg, field, cap, run))


if __name__ == "__main__":
    main()
