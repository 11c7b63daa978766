"""DVC stage ``appearance@<scene>-<variant>``: capture + mesh -> ``out/<scene>/appearance/<variant>/``
(``gaussians.ply`` + ``binding.npz`` (face of each Gaussian), test ``renders/``,
``metrics.json`` with PSNR / SSIM / LPIPS, ``curve.csv`` of test PSNR against training time).

    python -m stages.appearance scene=kitchen_small                                  # interactive, the paper's method
    python -m stages.appearance scene=kitchen_small appearance_variant=static_gs     # an ablation variant
    python -m stages.appearance -cn dvc_stage scene=kitchen_small appearance_variant=static_gs   # as DVC runs it
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import geometry_dir, out_root, scene_of
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.splat.config import AppearanceConfig
from drawer_lib.splat.pipeline import run_appearance


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene, _ = scene_of(cfg)
    app = to_typed(AppearanceConfig, cfg.appearance, "appearance")
    cap = load_capture(geometry_dir(cfg, scene, "capture", output=False))
    mesh = geometry_dir(cfg, scene, "mesh", output=False) / "mesh.ply"
    variant = app.variant
    with stage_run("appearance", out_root(cfg) / scene / "appearance" / variant, seed=cfg.seed) as run:
        field = geometry_dir(cfg, scene, "sdf", output=False) / "field.pt"
        run.metrics.update(run_appearance(app, cap, mesh, run, run.dir, field))


if __name__ == "__main__":
    main()
