"""The error-against-run-time grid (drawer_lib/report/pareto.py): the front against a brute-force
reference, the budget picks, the multirun commands, and the stage for real on the tiny kitchen
(four jobs on the joblib launcher)."""

import json
import shutil

import numpy as np
import pytest
from helpers import ROOT, add_overlays, run_stage, scene_paths
from omegaconf import OmegaConf

from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError
from drawer_lib.paths import LAYOUT, capture_name
from drawer_lib.report.pareto import (AppearanceGrid, NeuralGrid, ParetoConfig, Point, multiruns, pareto_front, pick,
                                      table_md)


def _brute_front(pts, lower):
    """A point is on the front when no other point is at most as slow and at least as good
    with one of the two strictly better (the slow reference)."""
    s = 1 if lower else -1
    out = []
    for p in pts:
        dominated = any((q.wall_s <= p.wall_s and s * q.error <= s * p.error)
                        and (q.wall_s < p.wall_s or s * q.error < s * p.error) for q in pts)
        if not dominated:
            out.append(p)
    return out


@pytest.mark.parametrize("lower", [True, False])
@pytest.mark.parametrize("seed", range(5))
def test_front_matches_brute_force(seed, lower):
    rng = np.random.default_rng(seed)
    pts = [Point("geometry", "v", 1, 1.0, float(t), float(e))
           for t, e in zip(rng.integers(1, 20, 40), rng.integers(1, 20, 40))]  # integers: many ties
    got = pareto_front(pts, lower)
    want = _brute_front(pts, lower)
    assert sorted((p.wall_s, p.error) for p in got) == sorted(set((p.wall_s, p.error) for p in want))
    assert [p.wall_s for p in got] == sorted(p.wall_s for p in got)
    errs = [p.error for p in got]
    assert errs == (sorted(errs, reverse=True) if lower else sorted(errs))  # improving with time


def test_picks_and_table():
    pts = [Point("appearance", "a", 100, 1, 50.0, 30.0), Point("appearance", "a", 200, 1, 100.0, 33.0),
           Point("appearance", "b", 200, 2, 90.0, 29.0), Point("appearance", "a", 400, 1, 700.0, 34.0)]
    front = pareto_front(pts, lower_is_better=False)
    assert [p.wall_s for p in front] == [50.0, 100.0, 700.0]
    assert pick(front, 40.0) is None and pick(front, 120.0).error == 33.0 and pick(front, 1e4).error == 34.0
    md, m = table_md(pts, [40.0, 120.0, 3600.0])
    assert m["appearance_pick_120s_error"] == 33.0 and m["appearance_pick_40s_error"] is None
    assert m["appearance_front_size"] == 3 and "nothing fits" in md and md.count("**yes**") == 3


def test_commands_and_bad_axes(tmp_path):
    cfg = ParetoConfig(neural=NeuralGrid(steps=[10, 20], cell_fine=[0.05]), appearance=AppearanceGrid(steps=[]))
    cmds = multiruns(cfg, "kitchen_tiny", tmp_path, paths_out="o")
    assert set(cmds) == {"neural", "tsdf"}  # an empty axis drops its family
    assert "sdf.neural.steps=10,20" in cmds["neural"] and "-m" in cmds["neural"] and "paths.out=o" in cmds["neural"]
    assert "hydra/launcher=local" in cmds["tsdf"] and f"hydra.sweep.dir={tmp_path / 'tsdf'}" in cmds["tsdf"]
    with pytest.raises(ConfigError, match="neural.steps"):
        NeuralGrid(steps=[0])
    with pytest.raises(ConfigError, match="textured_mesh"):
        AppearanceGrid(variants=["textured_mesh"])
    conf = OmegaConf.to_container(OmegaConf.load(ROOT / "conf/pareto/default.yaml"))
    assert to_typed(ParetoConfig, conf, "pareto") == ParetoConfig()  # the file and the schema agree
    for key, sub, bad in (("appearance", "train_scale", [1.5]), ("appearance", "steps", [0]), (None, "budgets_s", [-1])):
        c = json.loads(json.dumps(conf))
        (c[key] if key else c)[sub] = bad
        with pytest.raises(ConfigError, match=sub):  # as the stage reads it
            to_typed(ParetoConfig, c, "pareto")


TINY = ["pareto.neural.steps=[6,12]", "pareto.neural.cell_fine=[0.06]", "pareto.tsdf.voxel=[0.08]",
        "pareto.appearance.variants=[movable_gs_ste]", "pareto.appearance.steps=[6]", "pareto.appearance.train_scale=[2]",
        "pareto.budgets_s=[1,100000]",
        "pareto.overrides=[" + ",".join(f"'{o}'" for o in (
            "sdf.neural.eval_every=6", "sdf.neural.eval_cell=0.05", "sdf.neural.monocal.refine_steps=5",
            "appearance.max_faces=3000", "appearance.eval_every=6", "appearance.strategy.refine_start=2",
            "appearance.strategy.refine_every=2", "appearance.strategy.refine_stop=4")) + "]"]


def test_stage_runs_the_grid_on_joblib(tmp_path, exact_capture):
    """The stage runs three multiruns (4 jobs, 2 at a time, 1 thread each), collects them and
    writes the table, the figure and the picks; every job's stage metrics are where the sweep
    table says."""
    sp = scene_paths(tmp_path)
    shutil.copytree(exact_capture[0], sp.capture)
    sp.mesh.parent.mkdir(parents=True)
    shutil.copy(sp.capture / capture_name("gt_mesh"), sp.mesh)
    add_overlays(tmp_path, detect=False)
    r = run_stage("pareto", tmp_path, *TINY)
    assert r.returncode == 0, r.stderr[-4000:]
    d = tmp_path / "out" / "kitchen_tiny" / "pareto"
    m = json.loads((d / LAYOUT["metrics"]).read_text())
    assert m["n_points"] == 4 and m["wall_s"] > 0
    assert m["geometry_pick_1s_error"] is None  # nothing fits in 1 s
    assert m["geometry_pick_100000s_error"] is not None and m["appearance_pick_100000s_error"] is not None
    t = json.loads((d / LAYOUT["report"]["table_json"]).read_text())
    fams = sorted((p["family"], p["variant"]) for p in t["points"])
    assert fams == [("appearance", "movable_gs_ste"), ("geometry", "neural"), ("geometry", "neural"),
                    ("geometry", "tsdf")]
    assert all(np.isfinite(p["error"]) and p["wall_s"] > 0 for p in t["points"])
    assert (d / LAYOUT["report"]["plot"]).stat().st_size > 10_000
    assert "Pareto" in (d / LAYOUT["report"]["table"]).read_text()
    sweep = t["jobs"]["neural"]  # each family's sweep rows: overrides and metrics of every job
    assert sorted(row["overrides"]["sdf.neural.steps"] for row in sweep) == ["12", "6"]
    assert all("appearance.max_faces" not in row["job"] for row in sweep)  # folders named by the axes only
    assert sorted(p.name for p in d.iterdir()) == sorted([LAYOUT["metrics"], *(LAYOUT["report"][k] for k in (
        "table", "table_json", "plot"))])  # the jobs' folders are gone: only the declared outputs remain


def test_sweep_threads():
    from drawer_lib.report.sweep import sweep_threads

    assert sweep_threads({"n_jobs": 2}, cpu_count=2) == 1 and sweep_threads({"n_jobs": 2}, cpu_count=8) == 4
    assert sweep_threads({"n_jobs": 4}, cpu_count=2) == 1  # never 0
    assert sweep_threads({"partition": "local"}, cpu_count=2) is None and sweep_threads(None) is None
    assert sweep_threads({"n_jobs": True}) is None and sweep_threads({"n_jobs": -1}) is None


def test_stage_names_a_failed_multirun(tmp_path):
    r = run_stage("pareto", tmp_path, *TINY)  # no capture
    assert r.returncode != 0
    assert "multirun failed" in r.stderr and not (tmp_path / "out" / "kitchen_tiny" / "pareto").exists()
