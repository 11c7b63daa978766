"""DVC stage ``articulate@<scene>``: ``decompose/`` + capture -> ``out/<scene>/articulate/``
(``parts.json`` in the ``drawer.parts/1`` format of DESIGN §5, ``decisions.json``: why each
segment got its type, ``metrics.json``).

    python -m stages.articulate scene=kitchen_small
    python -m stages.articulate -cn dvc_stage scene=kitchen_small
    python -m stages.articulate scene=kitchen_small articulate.use_labels=false   # geometry only
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import geometry_dir, scene_of, stage_dir
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.perception.config import ArticulateConfig
from drawer_lib.perception.pipeline import run_articulate
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene, _ = scene_of(cfg)
    ac = to_typed(ArticulateConfig, cfg.articulate, "articulate")
    cap = load_capture(geometry_dir(cfg, scene, "capture", output=False), check_files=False)
    seg_dir = Path(cfg.paths.out) / scene / "decompose"
    with stage_run("articulate", stage_dir(cfg, scene, "articulate"), seed=cfg.seed) as run:
        run.metrics.update(run_articulate(ac, cap, seg_dir, run.dir))


if __name__ == "__main__":
    main()
