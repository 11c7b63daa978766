"""The metric scale of an RGB-only reconstruction from the floor, the worktop and the cameras'
height (drawer_lib/sfm/scale.py), on analytic point clouds of a kitchen shrunk by an unknown
factor."""

import math

import numpy as np
import pytest

from drawer_lib.errors import ConfigError, InputError
from drawer_lib.sfm.scale import ScaleConfig, estimate_scale


def kitchen_points(rng, counter=0.91, floor=True, handles_at=None, n=4000):
    """SfM-like points of a kitchen (m): the floor, the worktop's top and front edge, fronts and
    wall cabinets spread over their heights, optionally a row of handles; cameras at 1.45 m."""
    parts = []
    if floor:
        parts.append(np.c_[rng.uniform(-1, 1, (n // 4, 2)) * [2, 1] + [0, -0.5], rng.normal(0, 0.003, n // 4)])
    parts.append(np.c_[rng.uniform(-2, 2, n // 8), rng.uniform(0, 0.6, n // 8), counter + rng.normal(0, 0.003, n // 8)])
    parts.append(np.c_[rng.uniform(-2, 2, n // 4), np.zeros(n // 4), rng.uniform(0.1, counter, n // 4)])  # fronts
    parts.append(np.c_[rng.uniform(-2, 2, n // 4), np.full(n // 4, 0.3), rng.uniform(1.4, 2.2, n // 4)])  # wall units
    if handles_at is not None:
        parts.append(np.c_[rng.uniform(-2, 2, n // 6), np.full(n // 6, -0.03), handles_at + rng.normal(0, 0.003, n // 6)])
    P = np.concatenate(parts)
    C = np.c_[rng.uniform(-1.5, 1.5, 40), rng.uniform(-2.2, -1.8, 40), rng.normal(1.45, 0.03, 40)]
    depths = np.full(40, 1.9)
    return P, C, depths


@pytest.mark.parametrize("shrink", [0.37, 1.0, 4.2])
def test_the_worktop_and_the_floor_give_the_scale_within_a_few_percent(shrink):
    rng = np.random.default_rng(0)
    P, C, d = kitchen_points(rng)
    est = estimate_scale(P * shrink, C * shrink, d * shrink, ScaleConfig())
    assert est.factor * shrink == pytest.approx(1.0, rel=0.03)
    assert est.cues["counter"]["used"] and est.cues["camera"]["used"] and est.sigma < ScaleConfig().metric_sigma
    assert est.floor == pytest.approx(0.0, abs=0.02 * shrink) and est.counter == pytest.approx(0.91 * shrink, rel=0.02)
    # a worktop the user measured is believed
    est = estimate_scale(P * shrink, C * shrink, d * shrink, ScaleConfig(), measured_counter_m=0.91)
    assert est.cues["counter"]["measured"] and est.sigma < 0.02 and est.factor * shrink == pytest.approx(1.0, rel=0.02)


def test_a_kitchen_with_another_worktop_height_is_off_by_that_ratio_and_says_how_sure_it_is():
    rng = np.random.default_rng(1)
    P, C, d = kitchen_points(rng, counter=0.80)  # a low worktop: 0.91 / 0.80 = +14 %; the cameras say +0 %
    est = estimate_scale(P, C, d, ScaleConfig(counter_sigma=0.01))
    assert est.factor == pytest.approx(0.91 / 0.80, rel=0.02)
    est = estimate_scale(P, C, d, ScaleConfig())  # the default: the worktop's height as unsure as the cameras'
    assert 1.0 < est.factor < 0.91 / 0.80 and est.cues["counter"]["used"]
    est = estimate_scale(P, C, d, ScaleConfig(), measured_counter_m=0.80)
    assert est.factor == pytest.approx(1.0, rel=0.02)


def test_without_a_floor_only_the_weak_cue_is_left_and_the_frame_is_not_metric():
    rng = np.random.default_rng(2)
    P, C, d = kitchen_points(rng, floor=False)
    P = P[P[:, 2] > 0.3]  # nothing low enough to be a floor
    est = estimate_scale(P, C, d, ScaleConfig())
    assert not est.cues["camera"]["used"] and "no floor" in est.cues["camera"]["why"]
    assert est.sigma == pytest.approx(0.35) and est.sigma > ScaleConfig().metric_sigma
    assert est.factor == pytest.approx(1.8 / 1.9)


def test_a_cue_far_off_the_others_is_dropped():
    rng = np.random.default_rng(3)
    P, C, d = kitchen_points(rng)
    # the cameras' height says x1, the worktop x1; a median depth that says x4 is dropped
    est = estimate_scale(P, C, d / 4.0, ScaleConfig(median_depth_sigma=0.05))
    assert not est.cues["median_depth"]["used"] and "disagrees" in est.cues["median_depth"]["why"]
    assert est.factor == pytest.approx(1.0, rel=0.03)


def test_median_depth_method_nans_and_bad_config():
    rng = np.random.default_rng(4)
    P, C, d = kitchen_points(rng)
    P[:5] = np.nan
    est = estimate_scale(P, C, d, ScaleConfig(method="median_depth"))
    assert set(est.cues) == {"median_depth"} and est.factor == pytest.approx(1.8 / 1.9) and math.isfinite(est.sigma)
    est = estimate_scale(P, C, d, ScaleConfig())
    assert math.isfinite(est.factor) and est.cues["counter"]["used"]
    with pytest.raises(InputError, match="no point depths"):
        estimate_scale(P, C, np.array([0.0, np.nan]), ScaleConfig())
    with pytest.raises(ConfigError, match="counter_window"):
        ScaleConfig(counter_window=(0.9, 0.5))
    with pytest.raises(ConfigError, match="method"):
        ScaleConfig(method="guess")
