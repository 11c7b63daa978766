"""Helpers for stage entry points: the scene a stage runs on and where it reads and writes.

Under DVC a stage runs as ``python -m stages.<name> -cn dvc_stage scene=<scene>``: the primary
config is the committed ``params.yaml`` and the scene comes from ``conf/scene/<scene>.yaml``
(a params file DVC tracks). In a Hydra multirun (``-m``) outputs go to the sweep's job
directory, never over DVC's outputs; inputs are always read from ``paths.out`` (the
benchmark's from ``paths.bench``).
"""

from pathlib import Path

from drawer_lib.errors import ConfigError
from drawer_lib.io.capture import Capture, load_capture
from drawer_lib.io.overlay import apply_overlay
from drawer_lib.paths import BenchPaths, ScenePaths


def scene_name(cfg) -> str:
    """The scene of this run: the chosen ``conf/scene/<name>.yaml``."""
    from hydra.core.hydra_config import HydraConfig

    name = None
    if HydraConfig.initialized():
        name = HydraConfig.get().runtime.choices.get("scene")
    if not name or cfg.get("scene") is None:
        raise ConfigError("no scene selected: pass scene=<name> (a file conf/scene/<name>.yaml), "
                          f"e.g. one of {list(cfg.get('scenes', []))}")
    return name


def out_root(cfg) -> Path:
    """``paths.out`` (normal runs) or the job's output directory (Hydra multirun)."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    if HydraConfig.initialized():
        hc = HydraConfig.get()
        if hc.mode == RunMode.MULTIRUN:
            return Path(hc.runtime.output_dir)
    return Path(cfg.paths.out)


def scene_paths(cfg, scene: str) -> tuple[ScenePaths, ScenePaths]:
    """(where this run reads ``scene``'s inputs, where it writes its outputs). A geometry
    comparison run (``+geometry_variant=<v>``, the ``geometry@<scene>-<v>`` stages) reads and
    writes ``sdf``/``mesh`` under ``<scene>/geometry/<v>/`` (:class:`~drawer_lib.paths.ScenePaths`)."""
    variant = cfg.get("geometry_variant")
    variant = None if variant is None else str(variant)
    return ScenePaths(Path(cfg.paths.out), scene, variant), ScenePaths(out_root(cfg), scene, variant)


def bench_paths(cfg) -> tuple[BenchPaths, BenchPaths]:
    """(where this run reads the benchmark's outputs, where it writes its own): ``paths.bench``,
    or in a Hydra multirun the job's output directory for what it writes."""
    src = BenchPaths(Path(cfg.paths.bench))
    dst = src if out_root(cfg) == Path(cfg.paths.out) else BenchPaths(out_root(cfg) / Path(cfg.paths.bench).name)
    return src, dst


def open_capture(src: ScenePaths, *, detections: bool = False, priors: bool = False,
                 check_files: bool = True) -> Capture:
    """The scene's capture as a stage reads it: with ``detections`` the ``detect`` stage's 2D
    detections in place of the capture's own, with ``priors`` the ``priors`` stage's monocular
    depth and normals (:mod:`drawer_lib.io.overlay`)."""
    cap = load_capture(src.capture, check_files=check_files)
    if detections:
        cap = apply_overlay(cap, src.file("detect", "index"))
    if priors:
        cap = apply_overlay(cap, src.file("priors", "index"))
    return cap
