"""DVC stage ``evaluate@<scene>``: predictions vs the capture's ground truth -> ``out/<scene>/evaluate/``
(``metrics.json``: articulation precision, recall, EA-score (DESIGN §6); ``matches.json``: which
prediction matched which GT part). Scenes without GT record the skip and its reason.

    python -m stages.evaluate -cn dvc_stage scene=kitchen_small
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.config.stage import geometry_dir, scene_of, stage_dir
from drawer_lib.io.capture import load_capture
from drawer_lib.io.manifest import read_manifest
from drawer_lib.perception.pipeline import run_evaluate
from drawer_lib.runner import main_guard, stage_run


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    scene, _ = scene_of(cfg)
    cap_dir = geometry_dir(cfg, scene, "capture", output=False)
    manifest = read_manifest(cap_dir / "manifest.json")
    cap = load_capture(cap_dir, check_files=False)
    parts = Path(cfg.paths.out) / scene / "articulate" / "parts.json"
    with stage_run("evaluate", stage_dir(cfg, scene, "evaluate"), seed=cfg.seed) as run:
        run.metrics.update(run_evaluate(cap, manifest, parts, run, run.dir))


if __name__ == "__main__":
    main()
