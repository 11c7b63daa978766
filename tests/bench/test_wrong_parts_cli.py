"""scripts/wrong_parts.py reads what a bench_detect run left and counts why its wrong parts are
wrong; a folder without that run's outputs is a clear error."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from drawer_lib.io.parts import Axis, Front, Part, PartsFile, write_parts

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "wrong_parts.py"


def _door(pid: str, cx: float, kind: str = "revolute") -> Part:
    fr = Front((cx, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.5, 0.7))
    edge = np.asarray(fr.center) - np.asarray(fr.u) * 0.25
    return Part(pid, kind, Axis(tuple(edge), (0.0, 0.0, -1.0)), (0.0, 1.57), fr)


def _run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True, timeout=120)


def test_counts_per_split_and_the_commonest_confusion(tmp_path):
    split = tmp_path / "train"
    for k, pred in ((16, [_door("a", 0.0, "prismatic"), _door("b", 3.0)]), (17, [_door("a", 0.0)])):
        root = split / f"kitchen_{k}"
        (root / "capture" / "gt").mkdir(parents=True)
        write_parts(root / "capture" / "gt" / "parts.json", PartsFile((_door("d0", 0.0),), ()))
        (root / "by_detector" / "builtin-t" / "articulate").mkdir(parents=True)
        write_parts(root / "by_detector" / "builtin-t" / "articulate" / "parts.json", PartsFile(tuple(pred), ()))
    r = _run(split, "--tag", "t", "--json", tmp_path / "wrong.json")
    assert r.returncode == 0, r.stderr
    assert "2 wrong: wrong_kind 1, off_front 0, merged 0, no_front 1" in r.stdout
    assert "1  revolute -> prismatic" in r.stdout
    rows = json.loads((tmp_path / "wrong.json").read_text())
    assert [(x["kitchen"], x["why"]) for x in rows] == [("kitchen_16", "wrong_kind"), ("kitchen_16", "no_front")]
    r = _run(split)  # no untagged run there
    assert r.returncode != 0 and "by_detector/builtin/articulate/parts.json: missing" in r.stderr
    r = _run(tmp_path / "nothing")
    assert r.returncode != 0 and "no kitchen_* folders" in r.stderr
