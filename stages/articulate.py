"""DVC stage ``articulate@<scene>``: ``decompose/`` + capture -> ``out/<scene>/articulate/``
(``parts.json`` in the ``drawer.parts/1`` format of docs/formats.md, ``decisions.json``: why each
segment got its type, ``metrics.json``).

    python -m stages.articulate scene=kitchen_small
    python -m stages.articulate -cn dvc_stage scene=kitchen_small
    python -m stages.articulate scene=kitchen_small articulate.types.use_labels=false   # no label votes
    python -m stages.articulate scene=kitchen_small articulate.types.weights=prior     # the hand-set weights
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.pipeline import run_articulate
from drawer_lib.articulation.weights import resolve_weights
from drawer_lib.config.stage import open_capture, scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.paths import BenchPaths
from drawer_lib.perception.config import DecomposeConfig
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    ac = to_typed(ArticulateConfig, cfg.articulate, "articulate")
    src, dst = scene_paths(cfg, scene)
    cap = open_capture(src, detections=True, check_files=False)
    weights = resolve_weights(ac.types, BenchPaths(Path(cfg.paths.bench)).weights)
    with stage_run("articulate", dst.stage_dir("articulate"), seed=cfg.seed) as run:
        recheck = (to_typed(DecomposeConfig, cfg.decompose, "decompose"), src.mesh)  # articulate.check reruns decompose
        run.metrics.update(run_articulate(ac, cap, src.decompose, run, weights, recheck=recheck))


if __name__ == "__main__":
    main()
