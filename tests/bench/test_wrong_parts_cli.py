"""scripts/wrong_parts.py reads what a bench_detect run left and counts why its wrong parts are
wrong; a folder without that run's outputs is a clear error."""

import dataclasses
import json

from helpers import door_part, run_script

from drawer_lib.io.parts import PartsFile, write_parts


def _run(*args):
    return run_script("wrong_parts.py", *args)


def test_counts_per_split_and_the_commonest_confusion(tmp_path):
    split = tmp_path / "train"
    flagged = dataclasses.replace(door_part("a", 0.0), extra={"low_margin": True})  # right, and flagged
    for k, pred in ((16, [door_part("a", 0.0, "prismatic"), door_part("b", 3.0)]), (17, [flagged])):
        root = split / f"kitchen_{k}"
        (root / "capture" / "gt").mkdir(parents=True)
        write_parts(root / "capture" / "gt" / "parts.json", PartsFile((door_part("d0", 0.0),), ()))
        (root / "by_detector" / "builtin-t" / "articulate").mkdir(parents=True)
        write_parts(root / "by_detector" / "builtin-t" / "articulate" / "parts.json", PartsFile(tuple(pred), ()))
    r = _run(split, "--tag", "t", "--json", tmp_path / "wrong.json")
    assert r.returncode == 0, r.stderr
    assert "2 wrong: wrong_kind 1, off_front 0, merged 0, no_front 1" in r.stdout
    assert "1  revolute -> prismatic" in r.stdout
    assert "flagged low_margin 1/1 right (1.000); the others 0/2 right (0.000)" in r.stdout
    rows = json.loads((tmp_path / "wrong.json").read_text())
    assert [(x["kitchen"], x["why"]) for x in rows] == [("kitchen_16", "wrong_kind"), ("kitchen_16", "no_front")]
    r = _run(split)  # no untagged run there
    assert r.returncode != 0 and "by_detector/builtin/articulate/parts.json: missing" in r.stderr
    r = _run(tmp_path / "nothing")
    assert r.returncode != 0 and "no kitchen_* folders" in r.stderr


def test_decisions_list_each_wrongly_typed_part_with_its_record(tmp_path):
    """--decisions joins each wrongly typed part to its front's entry in decisions.json (by part
    id); a kitchen with a wrong type and no decisions.json is a clear error."""
    split = tmp_path / "train"
    root = split / "kitchen_16"
    (root / "capture" / "gt").mkdir(parents=True)
    write_parts(root / "capture" / "gt" / "parts.json", PartsFile((door_part("d0", 0.0),), ()))
    art = root / "by_detector" / "builtin-t" / "articulate"
    art.mkdir(parents=True)
    write_parts(art / "parts.json", PartsFile((door_part("drawer_0", 0.0, "prismatic"), door_part("door_9", 3.0)), ()))
    r = _run(split, "--tag", "t", "--decisions")
    assert r.returncode != 0 and "decisions.json: missing" in r.stderr
    seg = {"segment": 4, "part": "drawer_0", "size": [0.5, 0.7], "margin": 0.25, "runner_up": "door_left",
           "handle": {"orientation": "horizontal"}, "excluded": {"sliding": "no track"}, "reason": "score 2.0 (next best door_left 1.75)"}
    (art / "decisions.json").write_text(json.dumps({"estimator": "geometric", "segments": [{"segment": 1, "family": "none"}, seg]}))
    r = _run(split, "--tag", "t", "--decisions", "--json", tmp_path / "wrong.json")
    assert r.returncode == 0, r.stderr
    assert ("revolute -> prismatic  " in r.stdout and "kitchen_16 drawer_0: 0.50 x 0.70 m, margin 0.25 over door_left, "
            "handle horizontal, excluded sliding; score 2.0 (next best door_left 1.75)" in r.stdout)
    typed, nowhere = json.loads((tmp_path / "wrong.json").read_text())
    assert typed["part"] == "drawer_0" and typed["margin"] == 0.25 and typed["excluded"] == ["sliding"]
    assert nowhere["why"] == "no_front" and nowhere["part"] == "door_9" and "margin" not in nowhere
    (art / "decisions.json").write_text(json.dumps({"segments": [{"segment": 1, "family": "none"}]}))
    r = _run(split, "--tag", "t", "--decisions")
    assert r.returncode == 0 and "kitchen_16 drawer_0: no decision recorded" in r.stdout


def test_missed_counts_why_each_true_part_was_not_found(tmp_path):
    """--missed adds the true parts recall counts as not found, each with why, to the summary
    and to --json (marked ``missed``)."""
    split = tmp_path / "train"
    root = split / "kitchen_16"
    (root / "capture" / "gt").mkdir(parents=True)
    write_parts(root / "capture" / "gt" / "parts.json", PartsFile((door_part("d0", 0.0), door_part("d1", 1.0), door_part("d2", 2.0)), ()))
    (root / "by_detector" / "builtin-t" / "articulate").mkdir(parents=True)
    write_parts(root / "by_detector" / "builtin-t" / "articulate" / "parts.json",
                PartsFile((door_part("a", 0.0), door_part("b", 1.0, "prismatic")), ()))
    r = _run(split, "--tag", "t", "--missed", "--json", tmp_path / "wrong.json")
    assert r.returncode == 0, r.stderr
    assert "2 true parts not found: wrong_kind 1, off_front 0, merged 0, no_part 1" in r.stdout
    assert "1  revolute: no_part" in r.stdout
    rows = json.loads((tmp_path / "wrong.json").read_text())
    assert [(x["part"], x["why"], x.get("missed", False)) for x in rows] == [
        ("b", "wrong_kind", False), ("d1", "wrong_kind", True), ("d2", "no_part", True)]
