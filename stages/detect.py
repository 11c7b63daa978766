"""DVC stage ``detect@<scene>``: 2D instance masks of fronts, handles and objects for every frame
-> ``out/<scene>/detect/`` (``detections/<stem>.png`` + ``.json`` in the capture format,
``detect.json`` the index later stages read in place of the capture's own, ``metrics.json``).

    python -m stages.detect -cn dvc_stage scene=kitchen_small                  # as DVC runs it
    python -m stages.detect scene=kitchen_small detect.model=builtin            # the built-in detector
    python -m stages.detect scene=my_kitchen detect.model=owlv2_sam             # OWLv2 + SAM (local weights)
"""

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import bench_paths, open_capture, scene_name, scene_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.detect.config import DetectConfig
from drawer_lib.detect.pipeline import run_detect
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene = scene_name(cfg)
    dc = to_typed(DetectConfig, cfg.detect, "detect")
    src, dst = scene_paths(cfg, scene)
    cap = open_capture(src)
    weights = bench_paths(cfg)[0].detector_weights
    with stage_run("detect", dst.detect, seed=cfg.seed) as run:
        run.metrics.update(run_detect(dc, cap, weights, run))


if __name__ == "__main__":
    main()
