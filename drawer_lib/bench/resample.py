"""Intervals from resampling the kitchens. A benchmark's precision and recall are pooled over
its kitchens (parts found, predicted and true summed), so how far a figure could move is a
question of which kitchens were drawn: draw as many kitchens as there are, with replacement,
pool again, and read the spread (the percentile bootstrap, Efron & Tibshirani 1993). Two
settings scored on the same kitchens are compared on the same draws (paired), so a kitchen
that is hard for both does not widen their difference. When each setting was fitted more than
once (a learned detector from several seeds), the fits are drawn too, each side's from its own
(a two-level bootstrap: Davison & Hinkley 1997, §3.8), so a difference between two fits of one
setting widens the interval instead of passing for an effect."""

import numpy as np

__all__ = ["pooled_prf", "resample_fits", "resample_kitchens"]


def pooled_prf(counts: np.ndarray) -> np.ndarray:
    """Pooled precision, recall and F1 of ``counts`` [..., K, 3] (per kitchen: parts found,
    predicted, true; the last but one axis is summed) -> [..., 3]. A ratio whose denominator is
    0 is NaN (no part predicted: precision undefined), and so is F1 then."""
    c = np.asarray(counts, dtype=np.float64)
    if c.shape[-1] != 3 or c.ndim < 2:
        raise ValueError(f"pooled_prf: counts of shape {c.shape}, expected [..., K, 3] (found, predicted, true)")
    found, pred, true = np.moveaxis(c.sum(-2), -1, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(pred > 0, found / pred, np.nan)
        r = np.where(true > 0, found / true, np.nan)
        f1 = np.where(pred + true > 0, 2 * found / (pred + true), np.nan)  # = 2PR / (P + R) where both exist
    return np.stack([p, r, f1], -1)


def resample_kitchens(base: np.ndarray, other: np.ndarray | None = None, draws: int = 5000, seed: int = 0,
                      level: float = 0.9) -> dict[str, dict[str, list[float]]]:
    """Percentile intervals at ``level`` of pooled precision, recall and F1 of ``base`` [K, 3]
    (per kitchen: found, predicted, true), from ``draws`` draws of K kitchens with replacement
    (``seed`` fixes them); with ``other`` (the same K kitchens scored another way) also the
    intervals of ``other`` and of its change ``other - base``, on the same draws. Returns
    ``{"base": {"precision": [lo, hi], "recall": ..., "f1": ...}, "other": ..., "change": ...}``;
    a draw in which a figure is undefined (no part predicted) is left out of its interval."""
    a = np.asarray(base, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or len(a) == 0:
        raise ValueError(f"resample_kitchens: base of shape {a.shape}, expected [K >= 1, 3]")
    if other is not None and np.shape(other) != a.shape:
        raise ValueError(f"resample_kitchens: other of shape {np.shape(other)} against base {a.shape} (the same kitchens)")
    if not 0 < level < 1 or draws < 1:
        raise ValueError(f"resample_kitchens: level {level} must be in (0, 1) and draws {draws} >= 1")
    idx = np.random.default_rng(seed).integers(0, len(a), size=(draws, len(a)))
    fa = pooled_prf(a[idx])
    out = {"base": _interval(fa, level)}
    if other is not None:
        fb = pooled_prf(np.asarray(other, dtype=np.float64)[idx])
        out["other"], out["change"] = _interval(fb, level), _interval(fb - fa, level)
    return out


def _interval(v: np.ndarray, level: float) -> dict[str, list[float]]:
    """Percentile intervals at ``level`` of the draws ``v`` [draws, 3] (precision, recall, F1),
    undefined draws (NaN) left out; NaN bounds when every draw is undefined."""
    q = [50 * (1 - level), 50 * (1 + level)]
    return {name: [float(x) for x in np.nanpercentile(v[:, i], q)] if np.isfinite(v[:, i]).any() else [np.nan, np.nan]
            for i, name in enumerate(("precision", "recall", "f1"))}


def resample_fits(base: np.ndarray, other: np.ndarray, draws: int = 5000, seed: int = 0,
                  level: float = 0.9) -> dict[str, dict[str, list[float]]]:
    """:func:`resample_kitchens` for settings fitted several times: ``base`` [Fa, K, 3] and
    ``other`` [Fb, K, 3] hold each fit's counts on the same K kitchens. Each draw takes K
    kitchens with replacement (the same for both sides, as :func:`resample_kitchens` draws them
    from ``seed``), then Fa fits of ``base`` and Fb of ``other`` with replacement, and pools each
    side over its drawn fits and kitchens. One fit a side gives :func:`resample_kitchens`'s
    intervals exactly. Returns ``{"base", "other", "change"}`` as it does."""
    a, b = np.asarray(base, dtype=np.float64), np.asarray(other, dtype=np.float64)
    if a.ndim != 3 or a.shape[2] != 3 or 0 in a.shape[:2]:
        raise ValueError(f"resample_fits: base of shape {a.shape}, expected [F >= 1, K >= 1, 3]")
    if b.ndim != 3 or b.shape[1:] != a.shape[1:] or len(b) == 0:
        raise ValueError(f"resample_fits: other of shape {b.shape} against base {a.shape} (fits of the same kitchens)")
    if not 0 < level < 1 or draws < 1:
        raise ValueError(f"resample_fits: level {level} must be in (0, 1) and draws {draws} >= 1")
    K = a.shape[1]
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, K, size=(draws, K))  # first, as resample_kitchens draws them

    def pooled(c: np.ndarray) -> np.ndarray:  # [draws, 3]: fits drawn, then the draw's kitchens
        f = rng.integers(0, len(c), size=(draws, len(c)))
        return pooled_prf(c[f[:, :, None], idx[:, None, :]].reshape(draws, -1, 3))

    fa, fb = pooled(a), pooled(b)
    return {"base": _interval(fa, level), "other": _interval(fb, level), "change": _interval(fb - fa, level)}
