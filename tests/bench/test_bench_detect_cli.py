"""scripts/bench_detect.py refuses a variant that would overwrite the default's outputs or vary a
stage it does not rerun, before it builds anything."""

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_detect.py"


@pytest.mark.parametrize("args, message", [
    (["--set", "decompose.missing_weight=0"], "--set needs a --tag"),
    (["--tag", "t", "--set", "sdf.method=tsdf"], "only detect.*, decompose.* and articulate.* keys vary here"),
    (["--tag", "t", "--set", "detect.model=none"], "the models are --detect's"),
    (["--split", "hand", "--kitchens", "2", "8"], "the hand split has kitchens 0 .. 7"),
    (["--layout", "module_width=[0.3]"], "not KEY=VALUE with KEY a layout field"),
    (["--layout", "module_widths"], "not KEY=VALUE with KEY a layout field"),
    (["--from-tag", "swa"], "--from-tag needs a --tag of its own"),
    (["--tag", "swa", "--from-tag", "swa"], "--from-tag needs a --tag of its own"),
    (["--tag", "t", "--from-tag", "swa", "--set", "decompose.missing_weight=0"], "with --from-tag only articulate.* keys vary"),
    (["--tag", "t", "--from-tag", "swa", "--decisions", "fitted"], "--from-tag reruns articulate with the prior weights"),
    (["--tag", "t", "--from-tag", "swa", "--split", "train", "--kitchens", "16", "--detect", "none"],
     "by_detector/none-swa/decompose/metrics.json: missing; run this split with --tag swa first"),
])
def test_bad_variants_are_refused(tmp_path, args, message):
    r = subprocess.run([sys.executable, str(SCRIPT), "--out", str(tmp_path), *args], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode != 0 and message in r.stderr
    assert not any(tmp_path.iterdir())  # nothing written


def test_a_kitchen_built_with_other_layout_keys_is_not_reused(tmp_path):
    """A stress variant (``--layout``) builds other kitchens: over a folder holding the split's
    own, it stops before any work, naming the kitchen; the kitchen's files stay as they were."""
    k = tmp_path / "train" / "kitchen_16"
    (k / "mesh").mkdir(parents=True)
    (k / "mesh" / "metrics.json").write_text("{}")
    r = subprocess.run([sys.executable, str(SCRIPT), "--out", str(tmp_path), "--split", "train", "--kitchens", "16",
                        "--detect", "none", "--layout", "module_widths=[0.3, 0.35]"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode != 0
    assert f"{k}: built with layout {{}}, not {{'module_widths': [0.3, 0.35]}}" in r.stderr
    assert sorted(p.name for p in k.rglob("*")) == ["mesh", "metrics.json"]


@pytest.mark.parametrize("layout", [None, {"module_widths": [0.3, 0.35]}])
def test_a_kitchen_not_built_yet_is_built(tmp_path, monkeypatch, layout):
    """A kitchen without a mesh is built (capture, SDF, mesh), with or without ``--layout``;
    ``layout.json`` is written only for a stress variant. The builders are replaced by
    recorders: what is checked is which run, not what they make."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_detect", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    calls = []
    monkeypatch.setattr(mod, "build_capture", lambda *a, **k: calls.append("capture"))
    monkeypatch.setattr(mod, "run_sdf", lambda *a, **k: calls.append("sdf") or {})
    monkeypatch.setattr(mod, "run_mesh", lambda *a, **k: calls.append("mesh") or {})
    monkeypatch.setattr(mod, "load_capture", lambda *a, **k: None)
    monkeypatch.setattr(mod, "load_field", lambda *a, **k: None)
    row = mod.kitchen("train", 16, [], tmp_path, tmp_path / "weights.pt", layout=layout)
    assert row == {"kitchen": 16} and calls == ["capture", "sdf", "mesh"]
    assert (tmp_path / "train" / "kitchen_16" / "layout.json").is_file() == bool(layout)


def test_another_draw_of_the_sensors_is_seeded_apart_and_not_mixed_with_the_first(tmp_path, monkeypatch):
    """``--draw N`` builds the same kitchen with its sensors seeded N x DRAW_STRIDE higher and
    records N beside it; over kitchens of another draw the script stops before any work."""
    import contextlib
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_detect", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    seeds = []
    real = mod.stage_run

    @contextlib.contextmanager
    def recording(name, path, seed, **kw):
        seeds.append((name, seed))
        with real(name, path, seed, **kw) as r:
            yield r

    monkeypatch.setattr(mod, "stage_run", recording)
    monkeypatch.setattr(mod, "build_capture", lambda *a, **k: None)
    monkeypatch.setattr(mod, "run_sdf", lambda *a, **k: {})
    monkeypatch.setattr(mod, "run_mesh", lambda *a, **k: {})
    monkeypatch.setattr(mod, "load_capture", lambda *a, **k: None)
    monkeypatch.setattr(mod, "load_field", lambda *a, **k: None)
    for out, draw in ((tmp_path / "d0", 0), (tmp_path / "d2", 2)):
        seeds.clear()
        mod.kitchen("train", 16, [], out, tmp_path / "weights.pt", draw=draw)
        assert seeds == [(st, 16 + mod.DRAW_STRIDE * draw) for st in ("capture", "sdf", "mesh")]
        assert (out / "train" / "kitchen_16" / "draw.json").is_file() == bool(draw)
    mod.check_built(tmp_path / "d2", "train", [16], {}, 2)
    with pytest.raises(SystemExit, match="built with --draw 2, not 0; use another --out"):
        mod.check_built(tmp_path / "d2", "train", [16], {}, 0)
    with pytest.raises(SystemExit, match="built with --draw 0, not 1"):
        mod.check_built(tmp_path / "d0", "train", [16], {}, 1)
    r = subprocess.run([sys.executable, str(SCRIPT), "--out", str(tmp_path / "d0"), "--split", "train", "--kitchens",
                        "16", "--detect", "none", "--draw", "-1"], capture_output=True, text=True, timeout=300)
    assert r.returncode != 0 and "--draw -1: 0 (the usual draw) or a positive number" in r.stderr


def test_from_tag_reruns_articulate_alone_on_the_tagged_runs_outputs(tmp_path, monkeypatch):
    """``--from-tag``: detect and decompose are not run; articulate reads the decomposition of
    ``by_detector/<model>-<from_tag>/`` and writes to the new tag's folder, which is scored."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_detect", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    k = tmp_path / "train" / "kitchen_16"
    for d in ("mesh", "by_detector/builtin-swa/decompose", "by_detector/builtin-swa/detect"):
        (k / d).mkdir(parents=True)
        (k / d / "metrics.json").write_text('{"source": "detections"}')
    calls = []
    monkeypatch.setattr(mod, "load_capture", lambda *a, **kw: None)
    monkeypatch.setattr(mod, "apply_overlay", lambda cap, index: calls.append(("overlay", index)))
    monkeypatch.setattr(mod, "run_detect", lambda *a, **kw: calls.append("detect") or {})
    monkeypatch.setattr(mod, "run_decompose", lambda *a, **kw: calls.append("decompose") or {})
    monkeypatch.setattr(mod, "run_articulate",
                        lambda ac, cap, dec, r, weights, recheck: calls.append(("articulate", dec, r.dir, recheck[1])) or {})
    monkeypatch.setattr(mod, "score_kitchen", lambda sp, parts: calls.append(("score", parts)) or {
        "precision": 1.0, "recall": 1.0, "n_pred": 1, "n_ignored": 0, "n_gt": 1, "n_correct": 1})
    row = mod.kitchen("train", 16, ["builtin"], tmp_path, [tmp_path / "w.pt"], tag="hm", from_tag="swa",
                      overrides=("articulate.types.hinged_min_height=null",))
    src, dst = k / "by_detector" / "builtin-swa", k / "by_detector" / "builtin-hm"
    assert "detect" not in calls and "decompose" not in calls
    assert calls[0] == ("overlay", src / "detect" / "detect.json")
    # written atomically; articulate.check, when on, would move the kitchen's own mesh
    assert calls[1] == ("articulate", src / "decompose", dst / ".articulate.tmp", k / "mesh" / "mesh.ply")
    assert calls[2] == ("score", dst / "articulate" / "parts.json")
    assert row["builtin"]["n_correct"] == 1 and row["builtin"]["source"] == "detections"


def test_a_rerun_from_a_tag_reads_that_runs_detections_or_the_untagged_ones(tmp_path):
    """--from-tag TAG: articulate reads TAG's decomposition, and TAG's own detections when it
    decoded some (a detect.* variant), else the model's untagged detections (TAG varied
    decompose or articulate only)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_detect", SCRIPT)
    bd = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bd)
    for folder, stage in (("builtin-cur", "decompose"), ("builtin", "detect"), ("builtin-me5", "decompose"),
                          ("builtin-me5", "detect")):
        (tmp_path / "by_detector" / folder / stage).mkdir(parents=True)
        (tmp_path / "by_detector" / folder / stage / "metrics.json").write_text("{}")
    d, src = bd.reused_run(tmp_path, "builtin", "cur")
    assert d.root.name == "builtin" and src.root.name == "builtin-cur"
    d, src = bd.reused_run(tmp_path, "builtin", "me5")
    assert d.root.name == "builtin-me5" and src.root.name == "builtin-me5"
    with pytest.raises(SystemExit, match="builtin-none/decompose/metrics.json: missing"):
        bd.reused_run(tmp_path, "builtin", "none")
