"""Studies as experiment files (conf/experiment/, lightning-hydra-template's `experiment/`): each
only overrides (`# @package _global_`), composes, changes something, and converts strictly to
every stage's typed config, the appearance variants it lists included."""

import importlib

import pytest
from helpers import CONF, compose_cfg
from omegaconf import OmegaConf

from drawer_lib.config.compose import compose_params
from drawer_lib.config.typed import to_typed

EXPERIMENTS = sorted(p.stem for p in (CONF / "experiment").glob("*.yaml"))
GROUPS = {  # the config group of each stage -> its typed config (what the stage converts)
    "capture": "drawer_lib.capture.config:CaptureConfig", "sdf": "drawer_lib.sdf.config:SdfConfig",
    "mesh": "drawer_lib.mesh.config:MeshConfig", "appearance": "drawer_lib.splat.config:AppearanceConfig",
    "decompose": "drawer_lib.perception.config:DecomposeConfig",
    "articulate": "drawer_lib.articulation.config:ArticulateConfig",
    "complete": "drawer_lib.complete.config:CompleteConfig", "twin": "drawer_lib.twin.config:TwinConfig",
    "simulate": "drawer_lib.simulate.pipeline:SimulateConfig", "stability": "drawer_lib.stability.pipeline:StabilityConfig",
    "pareto": "drawer_lib.report.pareto:ParetoConfig",
}


def _cls(path: str):
    mod, name = path.split(":")
    return getattr(importlib.import_module(mod), name)


def test_there_are_experiments_for_each_study():
    for prefix in ("paper_ablation", "ste_", "geometry_", "detections_", "quick"):
        assert any(e.startswith(prefix) for e in EXPERIMENTS), prefix


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_experiment_only_overrides_and_converts_strictly(name):
    text = (CONF / "experiment" / f"{name}.yaml").read_text()
    assert text.startswith("# @package _global_\n"), "an experiment overrides the whole config"
    assert compose_params(CONF, [f"experiment={name}"]) != compose_params(CONF), "it changes nothing"
    cfg = compose_cfg([f"experiment={name}"])
    assert cfg.study == name  # the column `dvc exp show` identifies it by
    for group, cls in GROUPS.items():
        to_typed(_cls(cls), cfg[group], group)  # strict: no unknown or missing key
    for scene in cfg.scenes:
        assert (CONF / "scene" / f"{scene}.yaml").is_file(), scene
    for v in cfg.geometry_variants:
        assert (CONF / "sdf" / f"{v}.yaml").is_file(), v
    app_cls = _cls(GROUPS["appearance"])
    for v in cfg.appearance_variants:  # as the appearance matrix merges them over the experiment's appearance
        merged = compose_cfg([f"experiment={name}", f"appearance_variant={v}"]).appearance
        app = to_typed(app_cls, merged, f"appearance + {v}")
        assert app.variant == v
        if "appearance" in OmegaConf.to_container(OmegaConf.load(CONF / "experiment" / f"{name}.yaml")):
            assert merged.lr.position == cfg.appearance.lr.position  # the variant keeps the study's overrides


def test_an_unknown_experiment_is_named():
    from hydra.errors import MissingConfigException

    with pytest.raises(MissingConfigException, match="nope"):
        compose_cfg(["experiment=nope"])


def test_dvc_exp_run_composes_an_experiment_as_we_do(tmp_path):
    """`dvc exp run -S experiment=<name>` writes the same params.yaml as compose_params."""
    from dvc.utils.hydra import compose_and_dump

    compose_and_dump(tmp_path / "params.yaml", str(CONF), None, "config", str(tmp_path), ["experiment=ste_short"])
    assert (tmp_path / "params.yaml").read_text() == compose_params(CONF, ["experiment=ste_short"])
