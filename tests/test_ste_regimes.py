"""scripts/ste_regimes.py: every regime composes into a valid appearance config, the learning-rate
reading matches what the config trains with, and the summary / plot are built from result rows."""

import importlib.util
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

from drawer_lib.config.typed import to_typed
from drawer_lib.splat.config import AppearanceConfig

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def mod():
    spec = importlib.util.spec_from_file_location("ste_regimes", ROOT / "scripts/ste_regimes.py")
    m = importlib.util.module_from_spec(spec)
    sys.modules["ste_regimes"] = m
    spec.loader.exec_module(m)
    return m


def _app(mod, regime: str, clip: str) -> AppearanceConfig:
    overrides, _ = mod.REGIMES[regime]
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", overrides=["scene=kitchen_small", f"appearance_variant={mod.CLIPS[clip]}",
                                                       *overrides])
    return to_typed(AppearanceConfig, cfg.appearance, "appearance")


def test_regimes_compose_and_lr_is_read_right(mod):
    for regime in mod.REGIMES:
        for clip in mod.CLIPS:
            app = _app(mod, regime, clip)
            assert app.clip == clip
            lr = mod.lr_of(regime)
            if lr is not None:  # a pure learning-rate regime: what the plot puts on x is what trains
                assert app.lr.position == pytest.approx(lr)
                assert app.lr.position_final == pytest.approx(lr / 100)
    assert mod.lr_of("official_lr") == pytest.approx(1.6e-4)
    assert mod.lr_of("tight_bounds") is None  # changes more than the learning rate: not on the lr axis
    assert _app(mod, "tight_bounds", "hard").bounds.elevate_coef == pytest.approx(0.15)


def test_summary_and_plot(mod, tmp_path):
    def row(regime, clip, psnr):
        return {"scene": "s", "regime": regime, "clip": clip, "seed": 0, "psnr": psnr, "ssim": 0.9, "lpips": 0.1}

    rows = [row("official_lr", "hard", 40.0), row("official_lr", "ste", 40.5),
            row("pos_lr_1.2e-3", "hard", 41.0), row("pos_lr_1.2e-3", "ste", 42.25)]
    text = mod.summary(rows)
    assert "| official_lr | 0 | 40.00 / 0.9000 / 0.1000 | 40.50 / 0.9000 / 0.1000 | – | +0.50 dB | – |" in text
    assert "+1.25 dB" in text
    assert mod.plot_lr(rows, tmp_path / "lr.png") and (tmp_path / "lr.png").stat().st_size > 0
    assert not mod.plot_lr([row("tight_bounds", "hard", 40.0)], tmp_path / "none.png")  # nothing on the lr axis
    assert not (tmp_path / "none.png").exists()
