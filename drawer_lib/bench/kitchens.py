"""A benchmark kitchen: kitchen ``k`` of a split, built as the pipeline builds a scene (the
``bench_kitchen`` stage): capture -> sdf -> mesh -> decompose -> articulate with the prior
weights (its ``decisions.json`` records every front's features, which the fit learns from).
Each step is the pipeline's own function, written through its own stage folder, inside the
kitchen's folder (:meth:`drawer_lib.paths.BenchPaths.kitchen`)."""

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.pipeline import run_articulate
from drawer_lib.bench.config import GEOMETRY_KEYS
from drawer_lib.bench.scenes import kitchen_scene
from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig, SceneConfig
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.io.images import read_json
from drawer_lib.mesh.config import MeshConfig
from drawer_lib.mesh.pipeline import run_mesh
from drawer_lib.paths import ScenePaths
from drawer_lib.perception.config import DecomposeConfig
from drawer_lib.perception.pipeline import run_decompose
from drawer_lib.runner import stage_run
from drawer_lib.sdf.config import SdfConfig
from drawer_lib.sdf.io import load_field
from drawer_lib.sdf.pipeline import run_sdf
from drawer_lib.synth.splits import SPLITS

STEPS = ("capture", "sdf", "mesh", "decompose", "articulate")
__all__ = ["KitchenConfigs", "STEPS", "build_kitchen", "kitchen_scene", "kitchen_seed"]


def kitchen_seed(seed: int, split: str, k: int) -> int:
    """The seed of kitchen ``k`` of ``split``'s sensor noise and sampling: an independent stream
    per (seed, split, kitchen)."""
    return int(np.random.SeedSequence([int(seed), SPLITS.index(split), int(k)]).generate_state(1)[0])


@dataclass(frozen=True)
class KitchenConfigs:
    """The configs of the pipeline's steps a benchmark kitchen runs."""

    capture: CaptureConfig
    sdf: SdfConfig
    mesh: MeshConfig
    decompose: DecomposeConfig
    articulate: ArticulateConfig


def build_kitchen(name: str, scene: SceneConfig, cfgs: KitchenConfigs, dst: ScenePaths, seed: int, root: Path,
                  progress: Callable | None = None) -> dict:
    """Run the steps (:data:`STEPS`) into the scene folder ``dst.root``, each atomically into its
    stage folder; returns each step's wall time (``<step>_s``) and the mesh's geometry metrics
    against the ground truth (``chamfer_l1``, ``fscore_1cm``, ``fscore_2cm``)."""
    out: dict = {}

    def step(stage: str):
        return stage_run(stage, dst.stage_dir(stage), seed=seed)

    with step("capture") as r:
        _, m = build_capture(name, scene, cfgs.capture, r.dir, r.rng, root, progress or r.progress)
        r.metrics.update(m)
    out["capture_s"] = _wall(dst, "capture")
    cap = load_capture(dst.capture, check_files=False)
    with step("sdf") as r:
        r.metrics.update(run_sdf(cfgs.sdf, cap, r))
    out["sdf_s"] = _wall(dst, "sdf")
    with step("mesh") as r:
        m = run_mesh(cfgs.mesh, load_field(dst.field), cap, r)
        r.metrics.update(m)
    out["mesh_s"] = _wall(dst, "mesh")
    out.update({k: m[k] for k in GEOMETRY_KEYS if k in m})
    with step("decompose") as r:
        r.metrics.update(run_decompose(cfgs.decompose, cap, dst.mesh, r))
    out["decompose_s"] = _wall(dst, "decompose")
    with step("articulate") as r:
        r.metrics.update(run_articulate(cfgs.articulate, cap, dst.decompose, r, weights=cfgs.articulate.types.prior,
                                        recheck=(cfgs.decompose, dst.mesh)))
    out["articulate_s"] = _wall(dst, "articulate")
    return out


def _wall(dst: ScenePaths, stage: str) -> float:
    return float(read_json(dst.metrics(stage))["wall_s"])
