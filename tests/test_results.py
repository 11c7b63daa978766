"""The README's results block (drawer_lib/report/results.py): written from a run's metrics files,
a missing one says so in its row, the spread of a benchmark figure, the block replaced in place."""

import json
import subprocess
from pathlib import Path

import pytest

from drawer_lib.paths import LAYOUT, BenchPaths, ScenePaths
from drawer_lib.report.results import (BEGIN, END, Run, provenance, replace_block, results_block, rows,
                                       run_time, seed_experiments, seed_spread)


def _put(path: Path, d: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(d))


@pytest.fixture()
def run(tmp_path) -> Run:
    r = Run(tmp_path, tmp_path / "out", tmp_path / "reports", tmp_path / "bench", "k")
    sp = ScenePaths(r.out, "k")
    geo = {"chamfer_l1": 0.00234, "fscore_1cm": 0.9612, "fscore_2cm": 0.9841}
    _put(sp.metrics("mesh"), geo)
    _put(ScenePaths(r.out, "k", "tsdf").metrics("mesh"), {**geo, "chamfer_l1": 0.00305})
    for v, psnr in (("textured_mesh", 31.83), ("movable_gs_ste", 43.02)):
        _put(sp.appearance_dir(v) / LAYOUT["metrics"], {"psnr": psnr, "ssim": 0.985, "lpips": 0.015})
    _put(sp.metrics("evaluate"), {"precision": 0.9, "recall": 0.9, "n_correct": 9, "n_pred": 11, "n_ignored": 1,
                                  "n_gt": 10, "ea_score": 0.99131, "emd": 5.95e-5, "n_emd": 9})
    for split, p in (("test", 0.95), ("train", 0.98)):
        _put(BenchPaths(r.bench).eval(split) / LAYOUT["metrics"],
             {"precision": p, "recall": 0.9, "ea_score": 0.8, "fitted_n_kitchens": 20, "fitted_precision_mean": 0.951,
              "fitted_precision_std": 0.04, "fitted_precision_worst": 0.85, "prior_precision": 0.7})
    return r


def test_rows_come_from_the_metrics_files(run):
    by = {r[0]: r[1] for r in rows(run, ["textured_mesh", "movable_gs_ste"], ["tsdf"])}
    assert by["geometry, neural SDF"] == "Chamfer-L1 2.34 mm, F@1cm 0.961, F@2cm 0.984"
    assert by["geometry, TSDF baseline (sensor depth, 2 cm)"].startswith("Chamfer-L1 3.05 mm")
    assert by["appearance ablation (textured_mesh → movable_gs_ste)"] == "31.83 → 43.02 dB"
    art = next(v for k, v in by.items() if k.startswith("articulation (simulated"))
    assert art == "precision 0.900 (9/10), recall 0.900 (9/10), EA-score 0.9913"
    test = next(v for k, v in by.items() if k.startswith("articulation benchmark, test split"))
    assert test.startswith("20 kitchens: precision 0.950, recall 0.900, EA-score 0.800 pooled")
    assert "per kitchen: precision 0.951 ± 0.040 (worst 0.850), recall –" in test and "prior weights: precision 0.700" in test
    # what this run did not make is said, not invented
    assert by["the twin (`complete` + `twin`)"] == "not measured: metrics.json of complete/ is missing (run `make run` first)"
    assert by["`make run`"].startswith("not measured: summary.json of repro/ is missing")


def test_the_block_names_the_run_and_what_was_simulated(run):
    block = results_block(run, ["movable_gs_ste"], [])
    assert block.startswith("Measured by one `make run` on commit `") and "**simulated from the renders**" in block
    assert "| result | figures | details |" in block


def test_the_readme_block_is_replaced_in_place():
    readme = f"# X\n\nbefore\n{BEGIN}\nold table\n{END}\nafter\n"
    new = replace_block(readme, "| a |\n")
    assert new == f"# X\n\nbefore\n{BEGIN}\n| a |\n{END}\nafter\n"
    assert replace_block(new, "| b |") == f"# X\n\nbefore\n{BEGIN}\n| b |\n{END}\nafter\n"
    with pytest.raises(ValueError, match="no results block"):
        replace_block("# X\n", "| a |")


def test_the_readme_has_the_block():
    text = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    assert text.count(BEGIN) == 1 and text.count(END) == 1 and text.index(BEGIN) < text.index(END)


def _exp(run: Run, seed: int, params: dict, chamfer: float, error=None) -> dict:
    rel = ScenePaths(run.out, "k").metrics("mesh").relative_to(run.root).as_posix()
    return {"rev": f"r{seed}", "name": f"seed-{seed}", "error": error,
            "data": {"params": {"params.yaml": {"data": {**params, "seed": seed}}},
                     "metrics": {rel: {"data": {"chamfer_l1": chamfer, "fscore_1cm": 0.9, "fscore_2cm": 0.98}}}}}


def test_the_seed_experiments_give_each_figure_its_range(run):
    params = {"seed": 0, "sdf": {"neural": {"steps": 1300}}}
    revs = [{"rev": "head", "experiments": [
        {"revs": [_exp(run, 2, params, 0.00251)]}, {"revs": [_exp(run, 1, params, 0.00219)]},
        {"revs": [_exp(run, 3, {**params, "sdf": {"neural": {"steps": 100}}}, 0.009)]},  # not a seed variant
        {"revs": [_exp(run, 4, params, 0.001, error={"msg": "failed"})]}]},  # failed
        {"rev": "other commit", "experiments": [{"revs": [_exp(run, 5, params, 0.001)]}]}]
    seeds = seed_experiments(revs, "head", params, run)
    assert [s for s, _ in seeds] == [1, 2]
    table = seed_spread(rows(run, ["movable_gs_ste"], []), run, seeds, 0)
    by = {r[0]: r[1] for r in table}
    assert by["geometry, neural SDF"].endswith("(seeds 0, 1, 2: Chamfer-L1 2.19–2.51 mm)")
    # a figure the experiments lack keeps its single value
    assert by["appearance, the paper's method (`movable_gs_ste`)"] == "PSNR 43.02 dB, SSIM 0.985, LPIPS 0.015"
    assert "seeds 0 to 2" in results_block(run, ["movable_gs_ste"], [], seeds, 0)


def test_the_run_time_says_whether_the_run_was_from_scratch():
    s = {"wall_s": 1719.6, "jobs": 2, "threads": 1, "force": True, "n_stages": 64, "n_stages_total": 64,
         "stage_wall_s": 3402.6}
    assert run_time(s) == "28.7 min (from scratch, 64 stages, 2 at a time, 1 thread each); stage walls sum to 56.7 min"
    part = run_time({**s, "force": False, "n_stages": 14, "wall_s": 447.8, "threads": 2, "stage_wall_s": 846.0})
    assert part.startswith("7.5 min (14 of 64 stages rerun, the rest from DVC's cache, 2 at a time, 2 threads each)")


def test_the_provenance_says_whether_the_code_differs_from_the_commit(tmp_path):
    """dvc.lock and README.md (which a run and this script rewrite) leave the tree the commit's,
    staged or not, whichever line git lists first; any other tracked change does not."""
    def git(*a):
        subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *a], cwd=tmp_path, check=True,
                       capture_output=True)

    git("init", "-q")
    for f in ("README.md", "dvc.lock", "code.py"):
        (tmp_path / f).write_text("0\n")
    git("add", ".")
    git("commit", "-qm", "c")
    assert "uncommitted" not in provenance(tmp_path)
    (tmp_path / "README.md").write_text("1\n")  # unstaged: git lists " M README.md" first
    (tmp_path / "dvc.lock").write_text("1\n")
    git("add", "dvc.lock")
    assert "uncommitted" not in provenance(tmp_path)
    (tmp_path / "code.py").write_text("1\n")
    assert "(with uncommitted changes)" in provenance(tmp_path)
