"""DVC stage ``appearance@<scene>-<variant>``: capture + mesh -> ``out/<scene>/appearance/<variant>/``
(``model/``: ``gaussians.ply`` + ``binding.npz`` (face of each Gaussian) or the textured mesh,
test ``renders/``, ``metrics.json`` with PSNR / SSIM / LPIPS, ``curve.csv`` of test PSNR
against training time).

    python -m stages.appearance scene=kitchen_small                                  # interactive, the paper's method
    python -m stages.appearance scene=kitchen_small appearance_variant=static_gs     # an ablation variant
    python -m stages.appearance -cn dvc_stage scene=kitchen_small appearance_variant=static_gs   # as DVC runs it
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.splat.config import AppearanceConfig
from drawer_lib.splat.pipeline import run_appearance


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    app = to_typed(AppearanceConfig, cfg.appearance, "appearance")
    src, dst = scene_paths(cfg, scene)
    cap = load_capture(src.capture)
    with stage_run("appearance", dst.appearance_dir(app.variant), seed=cfg.seed) as run:
        run.metrics.update(run_appearance(app, cap, src.mesh, run, src.field))


if __name__ == "__main__":
    main()
