"""DVC stages ``bench_kitchen@<split>-<k>`` and ``bench_hand@<k>`` (the hand split): kitchen ``k``
of a benchmark split, built as the pipeline builds a scene -> ``<paths.bench>/<split>/kitchen_<k>/``
(``capture/``, ``sdf/``, ``mesh/``, ``decompose/`` and ``articulate/`` with the prior weights, whose ``decisions.json``
the ``fit_decisions`` stage learns from; ``metrics.json``: each step's wall time and the mesh's
geometry against the ground truth). dvc.yaml passes the benchmark's sensors and geometry as
Hydra overrides:

    python -m stages.bench_kitchen -cn dvc_stage scene=kitchen_small capture/detections=noisy_generic \
        capture/depth=sensor sdf=tsdf +bench_split=train +bench_kitchen=3
"""

from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.bench.config import BenchConfig
from drawer_lib.bench.kitchens import KitchenConfigs, build_kitchen, kitchen_scene, kitchen_seed
from drawer_lib.capture.config import CaptureConfig
from drawer_lib.config.stage import bench_paths
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError
from drawer_lib.mesh.config import MeshConfig
from drawer_lib.paths import ScenePaths
from drawer_lib.perception.config import DecomposeConfig
from drawer_lib.runner import main_guard, stage_run
from drawer_lib.sdf.config import SdfConfig


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    bc = to_typed(BenchConfig, cfg.bench, "bench")
    if cfg.get("bench_split") is None or cfg.get("bench_kitchen") is None:
        raise ConfigError("bench_kitchen: pass +bench_split=<train|test|hand> +bench_kitchen=<k>")
    split, k = str(cfg.bench_split), int(cfg.bench_kitchen)
    listed = bc.split_kitchens(split)
    if k not in listed:
        raise ConfigError(f"bench_kitchen: kitchen {k} of the {split} split is not in the benchmark ({listed})")
    choices = HydraConfig.get().runtime.choices
    want = {"scene": bc.base_scene, "capture/detections": bc.detections, "capture/depth": bc.depth, "sdf": bc.sdf}
    wrong = {g: choices.get(g) for g, v in want.items() if choices.get(g) != v}
    if wrong:
        raise ConfigError(f"bench_kitchen: run with the benchmark's choices {want} (as dvc.yaml does), got {wrong}")
    scene = kitchen_scene(OmegaConf.to_container(cfg.scene, resolve=True), split, k, bc.camera)
    cfgs = KitchenConfigs(to_typed(CaptureConfig, cfg.capture, "capture"), to_typed(SdfConfig, cfg.sdf, "sdf"),
                          to_typed(MeshConfig, cfg.mesh, "mesh"), to_typed(DecomposeConfig, cfg.decompose, "decompose"),
                          to_typed(ArticulateConfig, cfg.articulate, "articulate"))
    dst = bench_paths(cfg)[1].kitchen(split, k)
    seed = kitchen_seed(bc.seed, split, k)
    with stage_run("bench_kitchen", dst.root, seed=seed) as run:
        inside = ScenePaths(run.dir.parent, run.dir.name)
        run.metrics.update(build_kitchen(f"{split}_{dst.scene}", scene, cfgs, inside, seed, Path.cwd()))


if __name__ == "__main__":
    main()
