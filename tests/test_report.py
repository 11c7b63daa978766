"""The report (drawer_lib/report/dashboard.py, extremes.py, stages/report.py): what it collects
and skips, its tables, the numerical-extremes table's tests, and the page in a real headless
Chromium without network (every section present, every figure decoded, not blank)."""

import json
import math
import os
import re
import subprocess
import sys
from dataclasses import asdict

import pytest
from helpers import ROOT

from drawer_lib.paths import LAYOUT, ScenePaths
from drawer_lib.report.dashboard import SECTIONS, collect, render
from drawer_lib.report.pareto import DIR as PARETO_DIR
from drawer_lib.report.pareto import LOWER_IS_BETTER, Point, pareto_front
from drawer_lib.report.extremes import ROWS, _junit, run_extremes
from drawer_lib.stability.pipeline import heatmap, write_matrix
from drawer_lib.viewer.browser import HeadlessChromium, chromium_binary

SCENE = "tiny"


def _write(p, obj):
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(obj))


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """out/ and reports/ of one scene as the stages write them (metrics only; no stability run
    for the second scene, so its stages are listed as skipped)."""
    d = tmp_path_factory.mktemp("report")
    out, reports = d / "out", d / "reports"
    sp = ScenePaths(out, SCENE)
    m = {"capture": {"n_frames": 12}, "sdf": {"skipped": {"mono_depth_loss": "metric depth is used instead"}},
         "mesh": {"chamfer_l1": 0.0042, "fscore_2cm": 0.91}, "decompose": {}, "articulate": {},
         "evaluate": {"precision": 0.8, "recall": 0.75, "ea_score": 0.95, "n_pred": 5, "n_gt": 6, "n_correct": 4,
                      "emd": 2.5e-5, "emd_max": 9e-5, "n_emd": 4},
         "complete": {}, "twin": {"closed_psnr": 40.1, "open_psnr": 33.3, "open_region_psnr": 24.0},
         "simulate": {"integrator": "implicitfast", "timestep": 0.002, "kinematic_dev_max_m": 0.001,
                      "realtime_factor": 12.0, "cup_rides_along_passed": 2, "cup_rides_along_n": 2,
                      "cup_rides_along_error_max_m": 0.002},
         "stability": {"integrator": "implicitfast", "timestep": 0.002, "realtime_factor": 15.0}}
    for k, (st, v) in enumerate(m.items()):
        _write(sp.metrics(st), v | {"wall_s": 1.0 + k, "peak_rss_mb": 100.0 + k})
    curve = sp.stage_dir("sdf") / LAYOUT["curve"]
    curve.write_text("step,wall_s,chamfer_l1\n10,1.0,0.02\n20,2.0,0.01\n")
    rows = [{"case": c, "group": g, "integrator": i, "timestep": dt, "error": (math.inf if dv else e),
             "unit": "m", "reference": "rk4", "wall_per_sim_s": 0.01 / dt * 1e-3, "diverged": dv,
             "reason": "energy grew" if dv else None}
            for c, g in (("twin_parts/drawer_0", "nominal"), ("stiff_joint", "extreme"))
            for i in ("euler", "implicitfast") for dt, e, dv in ((1e-3, 2e-4, False), (2e-3, 4e-4, c == "stiff_joint"))]
    write_matrix(sp.file("stability", "matrix"), rows)
    heatmap(rows, 1e-3, sp.file("stability", "heatmap"), ("implicitfast", 2e-3))
    _write(sp.file("stability", "choice"),
           {"integrator": "implicitfast", "timestep": 2e-3, "source": "stability", "tolerance": 1e-3,
            "nominal_error": 4e-4, "realtime_factor": 15.0, "agrees_with_twin_default": True,
            "twin_default": {"integrator": "implicitfast", "timestep": 2e-3, "realtime_factor": 15.0},
            "outside": [{"case": "stiff_joint", "note": "w = 3162 rad/s", "diverged": True, "reason": "energy grew",
                         "error": None, "unit": "rad", "largest_stable_timestep": 1e-3,
                         "remedy": {"armature": 0.1, "damping": 10.0}}]})
    _write(reports / "geometry" / LAYOUT["report"]["table_json"],
           {SCENE: {"neural (selected)": {"chamfer_l1": 0.0042, "fscore_1cm": 0.8, "fscore_2cm": 0.91}}})
    pts = [Point("geometry", "neural", 325, 0.03, 80.0, 6.0), Point("geometry", "neural", 1300, 0.015, 300.0, 3.5),
           Point("appearance", "static_gs", 375, 2, 50.0, 35.0)]
    pdir = sp.root / PARETO_DIR
    pdir.mkdir()
    _write(pdir / LAYOUT["report"]["table_json"],
           {"points": [asdict(p) for p in pts], "config": {"budgets_s": [120.0, 600.0]},
            "fronts": {f: [asdict(p) for p in pareto_front([q for q in pts if q.family == f], LOWER_IS_BETTER[f])]
                       for f in LOWER_IS_BETTER}})
    _write(sp.file("articulate", "decisions"), {"estimator": "geometric", "segments": [
        {"segment": 1, "family": "flap", "hinge": "bottom", "part": "flap_0", "runner_up": "drawer", "margin": 0.59,
         "confidence": 0.63, "low_margin": True, "near_segment": [{"step": "score", "margin": 0.01}],
         "handle": {"a_u": 0.49, "a_v": 0.9, "orientation": "horizontal", "n_points": 9, "source": "images"}},
        {"segment": 2, "family": "drawer", "hinge": None, "part": "drawer_0", "runner_up": "flap_bottom",
         "margin": 4.1, "confidence": 0.98, "low_margin": False, "handle": None},
        {"segment": 3, "family": "fixed", "hinge": None, "runner_up": "drawer", "margin": 0.2, "confidence": 0.4,
         "low_margin": True, "handle": None},
        {"segment": 4, "family": "rigid", "reason": "not planar"},
        # written as null where a front has no part or no runner-up (a video's built-in detections)
        {"segment": 5, "family": "fixed", "hinge": None, "part": None, "runner_up": None, "margin": 0.3,
         "confidence": 0.5, "low_margin": True, "handle": None}]})
    extremes = [{"extreme": "SDF density at β = 1e-5", "expect": "finite", "test": ROWS[0][2], "outcome": "passed",
                 "seconds": 0.01, "message": None}]
    data = collect(out, reports, [SCENE, "never_ran"], [], ["static_gs"], extremes)
    return d, data


def test_collect_reads_the_metrics_and_lists_every_skip(outputs):
    _, data = outputs
    sc = data.scenes[0]
    assert sc.metrics["evaluate"]["emd"] == 2.5e-5 and sc.choice["integrator"] == "implicitfast"
    assert len(sc.stability_rows) == 8 and sc.heatmap is not None
    why = {(s, w): r for s, w, r in data.skipped}
    assert why[(SCENE, "sdf: mono_depth_loss")] == "metric depth is used instead"
    assert all((("never_ran", st) in why) for st in ("capture", "twin", "stability"))
    assert data.ablation is None  # no ablation table: a skip, not zeros


def test_render_has_every_section_and_the_paper_columns(outputs):
    _, data = outputs
    page, md = render(data)
    for key, title in SECTIONS:
        assert f'<section id="{key}">' in page and f"## {title}" in md
    assert "| tiny | 5 | 6 | 4 | 0.800 | 0.750 | 0.950 |" in md  # Tab. 4 row
    assert "2.5e-05" in md and "1.41e-05" in md  # our EMD next to the paper's
    # the extreme outside the choice, with its largest stable timestep and its remedy (armature, damping)
    assert "| stiff_joint | w = 3162 rad/s | diverged: energy grew | 0.001 | 0.1 | 10 |" in md.splitlines()
    assert "skipped: reports/ablation/table.json is missing" in md
    # the swept grid: with 2 min the 325-step SDF (80 s), with 10 min the 1300-step one
    assert "| geometry | 2 min | neural 325 steps, 30 mm | 80.0 | 6 Chamfer-L1 (mm) |" in md
    assert "| geometry | 10 min | neural 1300 steps, 15 mm | 300.0 | 3.5 Chamfer-L1 (mm) |" in md
    assert "never_ran: no swept grid" in md
    assert "http://" not in page and "https://" not in page and "<script" not in page  # nothing to fetch
    # the low-margin decisions, lowest first, a fixed front among them; the confident one not listed
    assert "Low-margin decisions: 3 of 4 typed fronts" in md
    lines = md.splitlines()
    fixed = lines.index("| tiny | 3 | – (fixed) | fixed | drawer | 0.20 | 0.40 | none | – |")
    assert lines[fixed + 1] == "| tiny | 5 | – (fixed) | fixed | – | 0.30 | 0.50 | none | – |"
    assert lines[fixed + 2] == ("| tiny | 1 | flap_0 | flap (bottom) | drawer | 0.59 | 0.63 | horizontal at (0.49, 0.90) "
                                "| the segment's selection |")
    assert "| tiny | 2 | drawer_0 |" not in md


def test_junit_parsing_and_a_stale_test_id(tmp_path):
    xml = tmp_path / "j.xml"
    xml.write_text('<testsuites><testsuite><testcase classname="tests.sdf.test_x" name="test_a[1e-05]" time="0.5"/>'
                   '<testcase classname="tests.test_y" name="test_b" time="1"><failure message="boom&#10;x"/>'
                   "</testcase></testsuite></testsuites>")
    got = _junit(xml)
    assert got["tests/sdf/test_x.py::test_a[1e-05]"] == ("passed", 0.5, None)
    assert got["tests/test_y.py::test_b"] == ("failed", 1.0, "boom")


def test_every_extremes_row_names_a_collected_test():
    ids = [r[2] for r in ROWS]
    r = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", *ids],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    collected = set(re.findall(r"^(tests/\S+::\S+)$", r.stdout, re.M))
    assert set(ids) <= collected, set(ids) - collected


def test_run_extremes_reports_each_tests_outcome(tmp_path, monkeypatch):
    import drawer_lib.report.extremes as ex

    rows = (ROWS[0], ("a test that does not exist", "-", "tests/test_report.py::test_no_such_test"))
    monkeypatch.setattr(ex, "ROWS", rows)
    res = run_extremes(ROOT, tmp_path)
    assert [r.outcome for r in res] == ["passed", "not run"]
    assert "stale" in res[1].message


def test_extremes_stage_table_and_what_the_report_reads(tmp_path, monkeypatch):
    import drawer_lib.report.extremes as ex

    reports = tmp_path / "reports"
    assert ex.read_extremes(reports)[0] is None and "has not run" in ex.read_extremes(reports)[1]
    m = ex.extremes_stage(ROOT, reports, enabled=False)
    assert m["extremes_n"] == 0 and m["skipped"] == {"extremes": "report.extremes = false"}
    assert ex.read_extremes(reports) == (None, "report.extremes = false")
    monkeypatch.setattr(ex, "ROWS", (ROWS[0],))
    m = ex.extremes_stage(ROOT, reports, enabled=True)
    assert (m["extremes_passed"], m["extremes_n"]) == (1, 1) and "skipped" not in m
    rows, why = ex.read_extremes(reports)
    assert why is None and [r["outcome"] for r in rows] == ["passed"] and rows[0]["test"] == ROWS[0][2]
    assert [p.name for p in (reports / "extremes").iterdir()] == ["table.json"]  # no temporary file left


def test_page_opens_offline_in_headless_chromium(outputs, tmp_path):
    if chromium_binary() is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed (scripts/install_system_deps.sh installs it)")
        pytest.skip("chromium is not installed (make setup installs it)")
    _, data = outputs
    page, _ = render(data)
    index = tmp_path / "index.html"
    index.write_text(page)
    # offline: the proxy refuses every request, so anything fetched from a network would fail
    with HeadlessChromium(index.as_uri(), size=(1280, 2400), extra_flags=["--proxy-server=127.0.0.1:9",
                                                                          "--disable-extensions"]) as b:
        b.wait_until(lambda: b.evaluate("document.readyState") == "complete", 60, "the page loads")
        ids = b.evaluate("[...document.querySelectorAll('section')].map(s => s.id)")
        assert ids == [key for key, _ in SECTIONS], ids
        images = b.evaluate("[...document.images].map(i => i.complete && i.naturalWidth > 0)")
        assert len(images) >= 3 and all(images), images  # heat map, time and stage figures, all decoded
        im = b.screenshot(tmp_path / "shot.png").mean(axis=2)
    assert im.shape == (2400, 1280)
    assert im.std() > 20 and (im < 128).mean() > 0.01  # text, tables and figures, not a blank page
