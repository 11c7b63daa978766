"""Helpers for stage entry points: the scene a stage runs on and where its outputs go.

Under DVC a stage runs as ``python -m stages.<name> -cn dvc_stage scene=<scene>``: the primary
config is the committed ``params.yaml`` and the scene comes from ``conf/scene/<scene>.yaml``
(a params file DVC tracks). In a Hydra multirun (``-m``) outputs go to the sweep's job
directory, never over DVC's outputs.
"""

from pathlib import Path

from drawer_lib.capture.config import SceneConfig
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError


def scene_of(cfg) -> tuple[str, SceneConfig]:
    """(scene name = the chosen conf/scene/ file, typed scene config)."""
    from hydra.core.hydra_config import HydraConfig

    name = None
    if HydraConfig.initialized():
        name = HydraConfig.get().runtime.choices.get("scene")
    if not name or cfg.get("scene") is None:
        raise ConfigError("no scene selected: pass scene=<name> (a file conf/scene/<name>.yaml), "
                          f"e.g. one of {list(cfg.get('scenes', []))}")
    return name, to_typed(SceneConfig, cfg.scene, f"conf/scene/{name}.yaml:")


def out_root(cfg) -> Path:
    """``paths.out`` (normal runs) or the job's output directory (Hydra multirun)."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    if HydraConfig.initialized():
        hc = HydraConfig.get()
        if hc.mode == RunMode.MULTIRUN:
            return Path(hc.runtime.output_dir)
    return Path(cfg.paths.out)


def stage_dir(cfg, scene: str, stage: str) -> Path:
    """``<out>/<scene>/<stage>`` (DESIGN §6)."""
    return out_root(cfg) / scene / stage


def geometry_dir(cfg, scene: str, stage: str, output: bool = True) -> Path:
    """Like :func:`stage_dir`, but a geometry comparison run (``+geometry_variant=<v>``, the
    ``geometry@<scene>-<v>`` stages) keeps its ``sdf``/``mesh`` under ``<out>/<scene>/geometry/<v>/``;
    the capture is always the scene's. Inputs (``output=False``) are always read from
    ``paths.out`` (in a Hydra multirun only outputs go to the job's directory)."""
    root = out_root(cfg) if output else Path(cfg.paths.out)
    variant = cfg.get("geometry_variant")
    if variant is None or stage == "capture":
        return root / scene / stage
    return root / scene / "geometry" / str(variant) / stage
