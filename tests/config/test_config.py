"""Configs: params.yaml is the composition of conf/, every config converts to the typed
dataclasses without missing or unknown keys, the DVC primary config equals the interactive one,
and dvc.yaml declares params that exist."""

import itertools
import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import yaml
from helpers import CONF, ROOT, compose_cfg
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from drawer_lib.capture.config import CaptureConfig, SceneConfig
from drawer_lib.config.compose import compose_if_changed, compose_params, params_diff
from drawer_lib.config.typed import to_tree, to_typed
from drawer_lib.errors import ConfigError
from drawer_lib.mesh.config import MeshConfig
from drawer_lib.sdf.config import SdfConfig
from drawer_lib.splat.config import AppearanceConfig

SCENES = sorted(p.stem for p in (CONF / "scene").glob("*.yaml"))
VARIANTS = {g: sorted(p.stem for p in (CONF / "capture" / g).glob("*.yaml")) for g in ("depth", "mono", "detections")}


def test_params_yaml_in_sync_with_conf():
    diff = params_diff(CONF, ROOT / "params.yaml")
    assert diff == "", "params.yaml is stale: run `python scripts/compose_params.py`\n" + diff


def test_compose_matches_dvc_composition(tmp_path):
    """Our compose is byte-identical to DVC's own (dvc.utils.hydra.compose_and_dump)."""
    from dvc.utils.hydra import compose_and_dump

    compose_and_dump(tmp_path / "params.yaml", str(CONF), None, "config", str(tmp_path), [])
    assert (tmp_path / "params.yaml").read_text() == compose_params(CONF)
    compose_and_dump(tmp_path / "p2.yaml", str(CONF), None, "config", str(tmp_path), ["capture/detections=perfect"])
    assert (tmp_path / "p2.yaml").read_text() == compose_params(CONF, ["capture/detections=perfect"])


@pytest.mark.parametrize("scene", SCENES)
def test_every_scene_converts_strictly(scene):
    cfg = compose_cfg([f"scene={scene}"])
    sc = to_typed(SceneConfig, cfg.scene, f"conf/scene/{scene}.yaml:")
    assert sc.source in ("synth", "video", "dir")
    # the YAML sets every field: converting the dataclass back gives the same tree
    assert to_tree(sc) == OmegaConf.to_container(cfg.scene)


@pytest.mark.parametrize("combo", list(itertools.product(*VARIANTS.values())))
def test_every_capture_variant_converts_strictly(combo):
    ov = [f"capture/{g}={v}" for g, v in zip(VARIANTS, combo)]
    cfg = compose_cfg(ov)
    cap = to_typed(CaptureConfig, cfg.capture, "capture")
    assert to_tree(cap) == OmegaConf.to_container(cfg.capture)


@pytest.mark.parametrize("scene", ["kitchen_small", "kitchen_tiny"])
def test_dvc_stage_config_equals_interactive_config(scene, monkeypatch):
    monkeypatch.chdir(ROOT)  # dvc_stage finds params.yaml in the stage's working directory
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        a = compose(config_name="config", overrides=[f"scene={scene}"])
        b = compose(config_name="dvc_stage", overrides=[f"scene={scene}"])
    assert OmegaConf.to_container(a, resolve=True) == OmegaConf.to_container(b, resolve=True)


@pytest.mark.parametrize("variant", ["neural", "tsdf", "neural_mono"])
def test_geometry_variant_under_dvc_equals_interactive(variant, monkeypatch):
    """`geometry@<scene>-<v>` runs `-cn dvc_stage sdf=<v>`: conf/sdf/<v>.yaml merged over
    params.yaml's sdf must give what an interactive `sdf=<v>` run gives."""
    monkeypatch.chdir(ROOT)
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        a = compose(config_name="config", overrides=["scene=kitchen_tiny", f"sdf={variant}"])
        b = compose(config_name="dvc_stage", overrides=["scene=kitchen_tiny", f"sdf={variant}"])
    assert OmegaConf.to_container(a.sdf) == OmegaConf.to_container(b.sdf)
    sdf = to_typed(SdfConfig, a.sdf, "sdf")
    assert to_tree(sdf) == OmegaConf.to_container(a.sdf)  # every key known to the schema, none missing
    assert sdf.method == ("tsdf" if variant == "tsdf" else "neural")


@pytest.mark.parametrize("variant", ["textured_mesh", "static_gs", "movable_gs", "movable_gs_ste", "free_gs"])
def test_appearance_variant_under_dvc_equals_interactive_and_keeps_params_overrides(variant, monkeypatch):
    """`appearance@<scene>-<v>` runs `-cn dvc_stage appearance_variant=<v>`: the variant's few
    keys merged over params.yaml's `appearance`, so a `-S appearance.steps=...` still applies."""
    monkeypatch.chdir(ROOT)
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        a = compose(config_name="config", overrides=["scene=kitchen_tiny", f"appearance_variant={variant}"])
        b = compose(config_name="dvc_stage", overrides=["scene=kitchen_tiny", f"appearance_variant={variant}"])
        c = compose(config_name="dvc_stage", overrides=["scene=kitchen_tiny", f"appearance_variant={variant}",
                                                        "appearance.steps=7"])
    assert OmegaConf.to_container(a.appearance) == OmegaConf.to_container(b.appearance)
    app = to_typed(AppearanceConfig, a.appearance, "appearance")
    assert to_tree(app) == OmegaConf.to_container(a.appearance)
    assert app.variant == variant and c.appearance.steps == 7


def test_mesh_config_converts_strictly():
    cfg = compose_cfg([])
    assert to_tree(to_typed(MeshConfig, cfg.mesh, "mesh")) == OmegaConf.to_container(cfg.mesh)


def _param(params: dict, key: str):
    node = params
    for k in key.split("."):
        node = node[k]
    return node


def test_dvc_yaml_params_exist():
    dvc = yaml.safe_load((ROOT / "dvc.yaml").read_text())
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    for name, st in dvc["stages"].items():
        body = st.get("do", st)
        for p in body.get("params", []):
            if isinstance(p, dict):
                (path,) = p
                path = re.sub(r"\$\{(?!item)([a-z_.]+)\}", lambda m: str(_param(params, m.group(1))), path)
                assert "${item" in path or (ROOT / path).exists(), f"stage {name}: params file {path} is missing"
                continue
            node = params
            for k in p.split("."):
                assert k in node, f"stage {name}: params key {p!r} is not in params.yaml"
                node = node[k]


@dataclass(frozen=True)
class Inner:
    a: int = 1
    b: list[float] = field(default_factory=lambda: [1.0])


@dataclass(frozen=True)
class Outer:
    name: str = "x"
    inner: Inner | None = None
    flag: bool = False


def test_to_typed_errors_name_the_key():
    ok = to_typed(Outer, {"name": "n", "inner": {"a": 2, "b": [1, 2.5]}, "flag": True}, "f.yaml:")
    assert ok.inner.b == [1.0, 2.5] and isinstance(ok.inner.b[0], float)
    cases = [
        ({"name": "n", "inner": {"a": 2, "b": [], "c": 1}, "flag": True}, "f.yaml:inner: unknown key(s) ['c']"),
        ({"name": "n", "inner": {"a": 2}, "flag": True}, "f.yaml:inner: missing key(s) ['b']"),
        ({"name": "n", "inner": {"a": "two", "b": []}, "flag": True}, "f.yaml:inner.a: expected an integer"),
        ({"name": "n", "inner": None, "flag": "yes"}, "f.yaml:flag: expected true or false"),
        ({"name": "n", "inner": {"a": 1, "b": ["x"]}, "flag": True}, "f.yaml:inner.b[0]: expected a number"),
    ]
    for tree, msg in cases:
        with pytest.raises(ConfigError) as e:
            to_typed(Outer, tree, "f.yaml:")
        assert msg in str(e.value), str(e.value)
    assert to_typed(Outer, {"name": "n"}, "f.yaml:", strict=False).inner is None


def test_to_typed_reads_tuples_of_any_length_and_fixed_ones():
    @dataclass(frozen=True)
    class T:
        xs: tuple[float, ...] = (1.0,)
        wh: tuple[int, int] = (1, 2)

    t = to_typed(T, {"xs": [1, 2.5, 3], "wh": [96, 72]}, "t:")
    assert t.xs == (1.0, 2.5, 3.0) and isinstance(t.xs[0], float) and t.wh == (96, 72)
    with pytest.raises(ConfigError, match="t:wh: expected 2 values"):
        to_typed(T, {"xs": [1], "wh": [1, 2, 3]}, "t:")
    with pytest.raises(ConfigError, match=r"t:xs\[1\]: expected a number"):
        to_typed(T, {"xs": [1, "a"], "wh": [1, 2]}, "t:")


def test_scene_source_must_have_its_block():
    with pytest.raises(ConfigError, match="no 'video' block"):
        SceneConfig(source="video")
    with pytest.raises(ConfigError, match="not one of"):
        SceneConfig(source="lidar")


def test_conf_files_are_plain_yaml():
    """DVC loads conf/scene/<name>.yaml as a params file: no interpolation, no defaults list."""
    for p in Path(CONF / "scene").glob("*.yaml"):
        text = p.read_text()
        assert "${" not in text and "defaults:" not in text, p


def test_appearance_schedule_is_by_steps_with_an_optional_time_cap():
    from drawer_lib.errors import ConfigError

    cfg = compose_cfg([])
    app = to_typed(AppearanceConfig, cfg.appearance, "appearance")
    assert app.max_seconds is None and app.budget_s > 0  # the default: no cap, the budget is reported
    assert AppearanceConfig(max_seconds=60.0).max_seconds == 60.0
    with pytest.raises(ConfigError, match="appearance.max_seconds"):
        AppearanceConfig(max_seconds=0.0)


def test_compose_if_changed_skips_only_when_conf_and_the_written_file_are_unchanged(tmp_path):
    import shutil

    conf, out, stamp = tmp_path / "conf", tmp_path / "params.yaml", tmp_path / "stamp.json"
    shutil.copytree(CONF, conf)
    assert compose_if_changed(conf, out, stamp) and out.read_text() == compose_params(CONF)
    assert not compose_if_changed(conf, out, stamp)  # nothing changed
    mesh = conf / "mesh" / "default.yaml"
    mesh.write_text(mesh.read_text().replace("target_faces: 200000", "target_faces: 100000"))
    assert compose_if_changed(conf, out, stamp) and "target_faces: 100000" in out.read_text()
    out.write_text(out.read_text().replace("target_faces: 100000", "target_faces: 5"))  # a hand edit
    assert compose_if_changed(conf, out, stamp) and "target_faces: 100000" in out.read_text()
    assert compose_if_changed(conf, out, stamp, ["seed=3"]) and "seed: 3" in out.read_text()  # overrides count
    stamp.write_text("not json")  # a broken stamp is only a cache miss
    assert compose_if_changed(conf, out, stamp) and not compose_if_changed(conf, out, stamp)


def test_set_param_sets_a_nested_key_from_yaml_and_names_a_bad_one():
    from drawer_lib.config.compose import set_param

    tree = {"sim": {"contact": {"part_static": False}, "timestep": 0.002}}
    set_param(tree, "sim.contact.part_static=true")
    set_param(tree, "sim.timestep=0.001")
    assert tree == {"sim": {"contact": {"part_static": True}, "timestep": 0.001}}
    for bad, what in (("sim.timestep", "key=value"), ("sim.nope.x=1", "no group 'nope'"), ("sim.dt=1", "no key 'dt'")):
        with pytest.raises(ConfigError, match=what):
            set_param(tree, bad)
