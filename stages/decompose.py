"""DVC stage ``decompose@<scene>``: capture detections + ``mesh/mesh.ply`` -> ``out/<scene>/decompose/``
(``segments.json``, ``face_labels.npz`` per face of ``perception_mesh.ply``, ``metrics.json``).

    python -m stages.decompose scene=kitchen_small                     # interactive, conf/
    python -m stages.decompose -cn dvc_stage scene=kitchen_small       # as DVC runs it: params.yaml
    python -m stages.decompose scene=kitchen_small decompose.source=geometric   # without detections
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import open_capture, scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.perception.config import DecomposeConfig
from drawer_lib.perception.pipeline import run_decompose
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    dc = to_typed(DecomposeConfig, cfg.decompose, "decompose")
    src, dst = scene_paths(cfg, scene)
    cap = open_capture(src, detections=True)
    with stage_run("decompose", dst.decompose, seed=cfg.seed) as run:
        run.metrics.update(run_decompose(dc, cap, src.mesh, run))


if __name__ == "__main__":
    main()
