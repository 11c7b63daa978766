"""drawer_lib.bench.evaluate.summarise: a split's pooled and per-kitchen figures from the rows
score_kitchen gives, with the precision of the parts flagged low_margin and of the others."""

import pytest

from drawer_lib.bench.evaluate import split_metrics, summarise


def _score(p, r, n_pred, n_gt, n_correct, flagged=None):
    s = {"precision": p, "recall": r, "n_pred": n_pred, "n_gt": n_gt, "n_correct": n_correct, "n_ignored": 0,
         "eas": [0.9] * n_correct, "emds": []}
    if flagged is not None:
        s["flagged"] = flagged
    return s


def test_pooled_figures_and_the_flags_precision():
    rows = [{"kitchen": 0, "fitted": _score(0.75, 1.0, 4, 3, 3, {"low_margin": [1, 2], "others": [2, 2]})},
            {"kitchen": 1, "fitted": _score(0.5, 0.5, 2, 2, 1, {"low_margin": [0, 1], "others": [1, 1]})}]
    s = summarise(rows, "fitted")
    assert s["precision"] == pytest.approx(4 / 6) and s["recall"] == pytest.approx(4 / 5)
    assert s["precision_mean"] == pytest.approx(0.625) and s["precision_worst"] == 0.5
    assert s["n_low_margin"] == 3 and s["precision_low_margin"] == pytest.approx(1 / 3)
    assert s["precision_others"] == pytest.approx(1.0)
    # flagged and others together are the pooled precision
    assert (1 + 3) / (3 + 3) == pytest.approx(s["precision"])


def test_rows_without_flag_counts_or_without_flagged_parts():
    old = [{"kitchen": 0, "fitted": _score(1.0, 1.0, 1, 1, 1)}]
    assert "n_low_margin" not in summarise(old, "fitted") and "precision_others" not in summarise(old, "fitted")
    none = [{"kitchen": 0, "fitted": _score(1.0, 1.0, 1, 1, 1, {"low_margin": [0, 0], "others": [1, 1]})}]
    s = summarise(none, "fitted")
    assert s["n_low_margin"] == 0 and "precision_low_margin" not in s and s["precision_others"] == 1.0
    rows = [{"kitchen": 0, "fitted": none[0]["fitted"], "prior": old[0]["fitted"]}]
    m = split_metrics(rows)
    assert m["fitted_n_low_margin"] == 0 and "prior_n_low_margin" not in m
