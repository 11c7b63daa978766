"""Test configuration: runtime shape/type checks of drawer_lib, hermetic DVC/Hydra settings,
and small rendered captures shared by the tests."""

import os
import sys
from pathlib import Path

# Runtime checking of the jaxtyping annotations (shapes and dtypes) in every drawer_lib module.
# Must run before drawer_lib is imported.
from jaxtyping import install_import_hook

sys.path.insert(0, str(Path(__file__).resolve().parent))
install_import_hook("drawer_lib", "typecheck.typechecker")

import drawer_lib.synth.gl  # noqa: E402,F401  (picks MUJOCO_GL before any test imports mujoco)

os.environ["DVC_NO_ANALYTICS"] = "1"
for _k in ("DVC_ROOT", "DVC_STAGE", "DVC_EXP_NAME"):
    os.environ.pop(_k, None)

import numpy as np  # noqa: E402
import pytest  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def tiny_scene():
    """The kitchen_tiny scene config, as the stage reads it."""
    from helpers import load_scene

    return load_scene("kitchen_tiny")


@pytest.fixture(scope="session")
def exact_capture(tmp_path_factory, tiny_scene):
    """kitchen_tiny rendered with exact depth, exact priors and perfect detections."""
    from helpers import render_capture, sensor_cfg

    out = tmp_path_factory.mktemp("exact_capture")
    cap = sensor_cfg(depth="exact", mono="exact", detections="perfect")
    manifest, metrics = render_capture(tiny_scene, cap, out)
    return out, manifest, metrics


@pytest.fixture(scope="session")
def noisy_capture(tmp_path_factory, tiny_scene):
    """kitchen_tiny rendered with the default (noisy) sensors."""
    from helpers import render_capture, sensor_cfg

    out = tmp_path_factory.mktemp("noisy_capture")
    manifest, metrics = render_capture(tiny_scene, sensor_cfg(), out)
    return out, manifest, metrics


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


def pytest_collection_modifyitems(config, items):
    """``gpu``-marked tests run only where CUDA is present."""
    import torch

    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="needs CUDA, which this machine does not have")
    for item in items:
        if "gpu" in item.keywords:
            item.add_marker(skip)
