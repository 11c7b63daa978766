"""Compose ``conf/`` into ``params.yaml`` exactly as ``dvc exp run`` does (dvc.utils.hydra:
hydra.compose with version_base=None, resolve, to_yaml), and check that the committed file is
up to date."""

import difflib
import hashlib
import json
from importlib.metadata import version
from pathlib import Path


def compose_config(conf_dir: Path, overrides: list[str] | None = None, config_name: str = "config",
                   version_base: str | None = "1.3"):
    """The config tree (a ``DictConfig``) Hydra composes from ``conf_dir`` with ``overrides``, as
    a stage's ``@hydra.main`` would (``version_base`` 1.3)."""
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=str(Path(conf_dir).resolve()), version_base=version_base):
        return compose(config_name=config_name, overrides=list(overrides or []))


def compose_params(conf_dir: Path, overrides: list[str] | None = None, config_name: str = "config") -> str:
    """The YAML text DVC would write for ``conf_dir`` with Hydra ``overrides`` (DVC composes with
    ``version_base=None``)."""
    from omegaconf import OmegaConf

    cfg = compose_config(conf_dir, overrides, config_name, version_base=None)
    OmegaConf.resolve(cfg)
    return OmegaConf.to_yaml(cfg)


def params_diff(conf_dir: Path, params_path: Path, overrides: list[str] | None = None) -> str:
    """Unified diff between ``params_path`` and a fresh composition ('' when in sync)."""
    want = compose_params(conf_dir, overrides)
    have = Path(params_path).read_text() if Path(params_path).exists() else ""
    if want == have:
        return ""
    return "".join(difflib.unified_diff(have.splitlines(True), want.splitlines(True),
                                        fromfile=str(params_path), tofile="composed from conf/"))


def composition_key(conf_dir: Path, overrides: list[str] | None = None, config_name: str = "config") -> str:
    """A digest of everything a composition reads: every file under ``conf_dir`` (path and
    bytes), the overrides, the config name and the Hydra and OmegaConf versions."""
    h = hashlib.sha256(json.dumps([list(overrides or []), config_name, version("hydra-core"), version("omegaconf")]).encode())
    root = Path(conf_dir)
    for f in sorted(p for p in root.rglob("*") if p.is_file()):
        h.update(str(f.relative_to(root)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def compose_if_changed(conf_dir: Path, out: Path, stamp: Path, overrides: list[str] | None = None) -> bool:
    """Write the composition of ``conf_dir`` to ``out`` unless ``stamp`` records that ``out``
    already holds the composition of exactly these inputs (:func:`composition_key`) and ``out``
    still has the bytes written then; True when it wrote. Skipping saves the ~0.4 s of Hydra's
    imports and composition on a no-op ``make run``; the stamp (``.dvc/tmp/``) is a cache that
    may be deleted at any time."""
    key = composition_key(conf_dir, overrides)
    out, stamp = Path(out), Path(stamp)
    try:
        rec = json.loads(stamp.read_text())
        if (rec["key"] == key and rec["path"] == str(out.resolve())
                and rec["out"] == hashlib.sha256(out.read_bytes()).hexdigest()):
            return False
    except (OSError, ValueError, KeyError, TypeError):
        pass
    text = compose_params(conf_dir, overrides)
    out.write_text(text)
    stamp.parent.mkdir(parents=True, exist_ok=True)
    stamp.write_text(json.dumps({"key": key, "path": str(out.resolve()), "out": hashlib.sha256(text.encode()).hexdigest()}))
    return True


def set_param(tree: dict, assignment: str) -> None:
    """Set ``a.b.c=value`` (value parsed as YAML) in the nested params dict ``tree`` (a loaded
    ``params.yaml``), as the scripts' ``-S`` options do; a malformed assignment or a key that
    ``tree`` lacks is a :class:`~drawer_lib.errors.ConfigError` naming it."""
    import yaml

    from drawer_lib.errors import ConfigError

    key, sep, value = assignment.partition("=")
    if not sep:
        raise ConfigError(f"-S {assignment!r}: expected key=value")
    *path, last = key.split(".")
    node = tree
    for k in path:
        if not isinstance(node.get(k), dict):
            raise ConfigError(f"-S {assignment!r}: no group {k!r} in params.yaml")
        node = node[k]
    if last not in node:
        raise ConfigError(f"-S {assignment!r}: no key {last!r} in params.yaml")
    node[last] = yaml.safe_load(value)
