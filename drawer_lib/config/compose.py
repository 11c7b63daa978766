"""Compose ``conf/`` into ``params.yaml`` exactly as ``dvc exp run`` does (dvc.utils.hydra:
hydra.compose with version_base=None, resolve, to_yaml), and check that the committed file is
up to date."""

import difflib
from pathlib import Path


def compose_params(conf_dir: Path, overrides: list[str] | None = None, config_name: str = "config") -> str:
    """The YAML text DVC would write for ``conf_dir`` with Hydra ``overrides``."""
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    with initialize_config_dir(config_dir=str(Path(conf_dir).resolve()), version_base=None):
        cfg = compose(config_name=config_name, overrides=list(overrides or []))
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
