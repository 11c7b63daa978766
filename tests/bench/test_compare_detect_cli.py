"""scripts/compare_detect.py reads two bench_detect summaries of the same kitchens and prints
each one's pooled figures and the paired change; summaries of other kitchens are refused."""

import json
from pathlib import Path

from helpers import run_script


def _summary(path: Path, rows: list[tuple[int, int, int, int]]) -> Path:
    path.write_text(json.dumps({"rows": [{"kitchen": k, "builtin": {"n_correct": c, "n_pred": p, "n_gt": t, "ea_score": 0.5}}
                                         for k, c, p, t in rows]}))
    return path


def _run(*args):
    return run_script("compare_detect.py", *args)


def test_pooled_figures_and_the_paired_change(tmp_path):
    a = _summary(tmp_path / "a.json", [(16, 8, 10, 10), (17, 4, 5, 6)])
    b = _summary(tmp_path / "b.json", [(16, 9, 10, 10), (17, 5, 5, 6)])
    r = _run(a, b, a, b, "--json", tmp_path / "out.json", "--draws", "200")
    assert r.returncode == 0, r.stderr
    assert "0.800 / 0.750 (12 / 15), F1 0.774" in r.stdout and "0.933 / 0.875 (14 / 15)" in r.stdout
    out = json.loads((tmp_path / "out.json").read_text())
    assert out["pooled"]["kitchens"] == 4 and out["pooled"]["base"]["true"] == 32
    assert out["pooled"]["change"]["recall"] == 0.125 and out["pooled"]["change"]["interval"]["recall"][0] > 0


def test_other_kitchens_or_an_odd_count_are_refused(tmp_path):
    a = _summary(tmp_path / "a.json", [(16, 8, 10, 10)])
    b = _summary(tmp_path / "b.json", [(17, 8, 10, 10)])
    r = _run(a, b)
    assert r.returncode != 0 and "compare the same kitchens" in r.stderr
    r = _run(a)
    assert r.returncode != 0 and "pairs BASE OTHER" in r.stderr
    (tmp_path / "bad.json").write_text("{}")
    r = _run(a, tmp_path / "bad.json")
    assert r.returncode != 0 and "bad.json: not a bench_detect summary" in r.stderr


def test_settings_fitted_several_times(tmp_path):
    """--base / --other: each side pooled over its fits, each fit's figures beside it, the
    interval drawn over fits and kitchens; other kitchens, or a side alone, are refused."""
    d0 = _summary(tmp_path / "d0.json", [(0, 8, 10, 10), (1, 4, 5, 6)])
    d1 = _summary(tmp_path / "d1.json", [(0, 6, 10, 10), (1, 4, 5, 6)])
    c0 = _summary(tmp_path / "c0.json", [(0, 9, 10, 10), (1, 5, 5, 6)])
    r = _run("--base", d0, d1, "--other", c0, "--json", tmp_path / "out.json", "--draws", "300")
    assert r.returncode == 0, r.stderr
    out = json.loads((tmp_path / "out.json").read_text())
    assert out["fits"] == [2, 1] and out["kitchens"] == 2 and out["base"]["found"] == 22 and out["base"]["true"] == 32
    assert out["base"]["recall"] == 22 / 32 and [f["recall"] for f in out["base"]["fits"]] == [12 / 16, 10 / 16]
    assert out["change"]["recall"] == 14 / 16 - 22 / 32
    assert "| 2 against 1 | 16 |" in r.stdout and "fits 0.750 / F1" in r.stdout
    other = _summary(tmp_path / "x.json", [(0, 8, 10, 10), (2, 4, 5, 6)])
    r = _run("--base", d0, other, "--other", c0)
    assert r.returncode != 0 and "compare the same kitchens" in r.stderr
    r = _run("--base", d0)
    assert r.returncode != 0 and "--base and --other go together" in r.stderr
