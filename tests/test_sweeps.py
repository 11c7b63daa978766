"""Hydra multiruns on real launchers (conf/hydra/launcher/): the configs compose to their plugins,
a joblib sweep of a stage writes every job's metrics into one table (the CollectSweep callback),
and — `pytest -m slow` — the same sweep on a one-node SLURM cluster (scripts/slurm_local.sh)."""

import json
import os
import shutil
import subprocess
import sys

import pytest
from helpers import CONF, ROOT
from hydra import compose, initialize_config_dir

from drawer_lib.report.sweep import _overrides, collect_sweep, sweep_markdown, varying, write_sweep

LAUNCHERS = {"local": "joblib_launcher.JoblibLauncher", "submitit_jobs": "submitit_launcher.LocalLauncher",
             "slurm": "submitit_launcher.SlurmLauncher"}


@pytest.mark.parametrize("name", sorted(p.stem for p in (CONF / "hydra" / "launcher").glob("*.yaml")))
def test_launcher_configs_compose_to_their_plugins(name):
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("config", overrides=[f"hydra/launcher={name}", "scene=kitchen_tiny"], return_hydra_config=True)
    assert cfg.hydra.launcher._target_.endswith(LAUNCHERS[name]), cfg.hydra.launcher._target_
    assert cfg.hydra.callbacks.collect_sweep._target_ == "drawer_lib.report.sweep.CollectSweep"


def test_overrides_of_a_job_folder_keep_lists_whole():
    assert _overrides("a=1,b.c=x") == {"a": "1", "b.c": "x"}
    assert _overrides("l=[1,2],scene=k") == {"l": "[1,2]", "scene": "k"}


def test_collect_reads_every_job_and_keeps_what_varies(tmp_path):
    for te, n in ((3, 4), (6, 2)):
        job = tmp_path / f"capture.split.test_every={te},scene=s"
        (job / "s" / "capture").mkdir(parents=True)
        (job / "s" / "capture" / "metrics.json").write_text(json.dumps(
            {"n_test": n, "n_frames": 12, "wall_s": 1.5, "peak_rss_mb": 100.0, "skipped": {"x": "y"}}))
    (tmp_path / "no_metrics_job").mkdir()
    rows = collect_sweep(tmp_path)
    assert [r["metrics"]["s/capture:n_test"] for r in rows] == [4, 2]
    ok, mk = varying(rows)
    assert ok == ["capture.split.test_every"] and mk == ["s/capture:n_test"]  # n_frames and wall_s are equal
    md = sweep_markdown(rows)
    assert "| 0 | 3 | 4 |" in md and "| 1 | 6 | 2 |" in md
    write_sweep(tmp_path)
    assert (tmp_path / "sweep.png").stat().st_size > 1000 and json.loads((tmp_path / "sweep.json").read_text()) == rows


def _multirun(tmp_path, *overrides, env=None):
    cmd = [sys.executable, "-m", "stages.capture", "-m", "scene=kitchen_tiny", "capture.split.test_every=3,6",
           f"hydra.sweep.dir={tmp_path / 'sweep'}", f"paths.out={tmp_path / 'out'}", *overrides]
    r = subprocess.run(cmd, cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT), **(env or {})),
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = collect_sweep(tmp_path / "sweep")
    assert sorted(r["metrics"]["kitchen_tiny/capture:n_test"] for r in rows) == [2, 4]  # 12 frames, every 3rd / 6th
    assert (tmp_path / "sweep" / "sweep.md").read_text() == sweep_markdown(rows)  # written by the callback
    assert not (tmp_path / "out").exists()  # a multirun never writes over DVC's outputs
    return r


def test_joblib_multirun_writes_one_table(tmp_path):
    _multirun(tmp_path, "hydra/launcher=local")


@pytest.mark.slow
def test_slurm_multirun_on_a_one_node_cluster(tmp_path):
    if os.geteuid() != 0 or shutil.which("apt-get") is None:
        pytest.skip("the one-node cluster needs root and apt-get (scripts/slurm_local.sh)")
    cluster = tmp_path / "cluster"
    up = subprocess.run(["bash", str(ROOT / "scripts" / "slurm_local.sh"), "up", str(cluster)], capture_output=True,
                        text=True, timeout=600)
    assert up.returncode == 0, up.stdout + up.stderr
    try:
        env = {"SLURM_CONF": str(cluster / "slurm.conf")}
        _multirun(tmp_path, "hydra/launcher=slurm", "hydra.launcher.partition=local", "hydra.launcher.cpus_per_task=1",
                  "hydra.launcher.mem_gb=4", env=env)
        assert any((tmp_path / "sweep" / ".submitit").iterdir())  # the jobs went through sbatch
    finally:
        subprocess.run(["bash", str(ROOT / "scripts" / "slurm_local.sh"), "down", str(cluster)], timeout=60)
