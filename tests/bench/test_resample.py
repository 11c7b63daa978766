"""Intervals from resampling the kitchens, against a slow reference (one draw at a time)."""

import numpy as np
import pytest

from drawer_lib.bench.resample import pooled_prf, resample_fits, resample_kitchens


def test_pooled_figures_sum_the_kitchens_first():
    c = np.array([[9, 10, 12], [1, 5, 2]])  # found, predicted, true
    p, r, f1 = pooled_prf(c)
    assert p == pytest.approx(10 / 15) and r == pytest.approx(10 / 14)
    assert f1 == pytest.approx(2 * p * r / (p + r))
    assert np.isnan(pooled_prf(np.array([[0, 0, 3]]))[0])  # nothing predicted: precision undefined ...
    assert pooled_prf(np.array([[0, 0, 3]]))[1:].tolist() == [0.0, 0.0]  # ... recall and F1 are 0
    assert pooled_prf(np.stack([c, c * 2]))[1].tolist() == pytest.approx(pooled_prf(c).tolist())  # batched
    with pytest.raises(ValueError, match="found, predicted, true"):
        pooled_prf(np.ones(3))


def _slow(base, other, draws, seed, level):
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(base), size=(draws, len(base)))
    rows = {"base": [], "other": [], "change": []}
    for i in range(draws):
        a, b = base[idx[i]].sum(0), other[idx[i]].sum(0)
        fa = [a[0] / a[1], a[0] / a[2], 2 * a[0] / (a[1] + a[2])]
        fb = [b[0] / b[1], b[0] / b[2], 2 * b[0] / (b[1] + b[2])]
        rows["base"].append(fa), rows["other"].append(fb), rows["change"].append(np.subtract(fb, fa))
    q = [50 * (1 - level), 50 * (1 + level)]
    return {k: {n: np.percentile(np.array(v)[:, j], q).tolist() for j, n in enumerate(("precision", "recall", "f1"))}
            for k, v in rows.items()}


def test_paired_intervals_equal_the_slow_reference():
    rng = np.random.default_rng(1)
    true = rng.integers(5, 20, size=9)
    pred = true + rng.integers(-3, 4, size=9)
    base = np.stack([np.minimum(pred, true) - rng.integers(0, 3, size=9), pred, true], 1)
    other = base + np.array([1, 0, 0])  # one more part found in every kitchen
    got = resample_kitchens(base, other, draws=400, seed=3, level=0.8)
    want = _slow(base.astype(float), other.astype(float), 400, 3, 0.8)
    for k in want:
        for n in want[k]:
            assert got[k][n] == pytest.approx(want[k][n], abs=1e-12), (k, n)
    assert got["change"]["recall"][0] > 0  # one more part everywhere: a change that every draw shows


def test_the_same_scores_change_by_nothing_and_bad_shapes_are_named():
    base = np.array([[3, 4, 5], [8, 8, 9], [0, 2, 1]])
    got = resample_kitchens(base, base.copy(), draws=50)
    assert all(v == [0.0, 0.0] for v in got["change"].values())
    assert got["base"] == got["other"] and "change" not in resample_kitchens(base, draws=5)
    with pytest.raises(ValueError, match="the same kitchens"):
        resample_kitchens(base, base[:2])
    with pytest.raises(ValueError, match=r"expected \[K >= 1, 3\]"):
        resample_kitchens(np.zeros((0, 3)))
    with pytest.raises(ValueError, match="level"):
        resample_kitchens(base, level=1.0)


def _slow_fits(base, other, draws, seed, level):
    """The two-level draw written out: kitchens, then each side's fits, one draw at a time."""
    rng = np.random.default_rng(seed)
    K = base.shape[1]
    idx = rng.integers(0, K, size=(draws, K))
    fits = [rng.integers(0, len(c), size=(draws, len(c))) for c in (base, other)]
    rows = {"base": [], "other": [], "change": []}
    for i in range(draws):
        f = []
        for c, fi in zip((base, other), fits):
            t = sum(c[j][k] for j in fi[i] for k in idx[i])
            f.append([t[0] / t[1], t[0] / t[2], 2 * t[0] / (t[1] + t[2])])
        rows["base"].append(f[0]), rows["other"].append(f[1]), rows["change"].append(np.subtract(f[1], f[0]))
    q = [50 * (1 - level), 50 * (1 + level)]
    return {k: {n: np.percentile(np.array(v)[:, j], q).tolist() for j, n in enumerate(("precision", "recall", "f1"))}
            for k, v in rows.items()}


def _counts(rng, k=9):
    true = rng.integers(5, 20, size=k)
    pred = true + rng.integers(-3, 4, size=k)
    return np.stack([np.minimum(pred, true) - rng.integers(0, 3, size=k), pred, true], 1)


def test_fits_drawn_with_the_kitchens_equal_the_slow_reference():
    rng = np.random.default_rng(2)
    base = np.stack([_counts(rng), _counts(rng)])
    other = np.stack([_counts(rng), _counts(rng), _counts(rng)])
    other[:, :, 2] = base[0, :, 2]  # the same kitchens: the same true parts
    base[:, :, 2] = base[0, :, 2]
    got = resample_fits(base, other, draws=300, seed=5, level=0.8)
    want = _slow_fits(base.astype(float), other.astype(float), 300, 5, 0.8)
    for k in want:
        for n in want[k]:
            assert got[k][n] == pytest.approx(want[k][n], abs=1e-12), (k, n)


def test_one_fit_a_side_is_the_kitchens_alone_and_fits_that_disagree_widen_the_change():
    rng = np.random.default_rng(4)
    base, other = _counts(rng, 12), _counts(rng, 12)
    other[:, 2] = base[:, 2]
    assert resample_fits(base[None], other[None], draws=500, seed=1) == resample_kitchens(base, other, draws=500, seed=1)
    # two fits of the base that find 3 parts more and 3 fewer in every kitchen: the same pooled
    # figures as one fit found twice, but a change whose interval is wider (against a setting
    # that finds one part more than the base everywhere, so the kitchens alone move it little)
    other = base + np.array([1, 1, 0])
    lo, hi = base.copy(), base.copy()
    lo[:, 0], hi[:, 0] = np.maximum(base[:, 0] - 3, 0), np.minimum(base[:, 0] + 3, base[:, 1])
    same = resample_fits(np.stack([base, base]), other[None], draws=2000, seed=0)["change"]["recall"]
    apart = resample_fits(np.stack([lo, hi]), other[None], draws=2000, seed=0)["change"]["recall"]
    assert apart[1] - apart[0] > 3 * (same[1] - same[0]) and same[0] > 0
    with pytest.raises(ValueError, match="fits of the same kitchens"):
        resample_fits(base[None], other[None, :5])
    with pytest.raises(ValueError, match=r"expected \[F >= 1, K >= 1, 3\]"):
        resample_fits(base, other[None])
