import json
import math
import os
import signal

import pytest

from drawer_lib.errors import InputError, NonFiniteError
from drawer_lib.io.manifest import Manifest
from drawer_lib.runner import deferred_interrupts, main_guard, stage_run, thread_cap


def test_outputs_appear_atomically_with_metrics(tmp_path):
    out = tmp_path / "scene" / "stage"
    with stage_run("stage", out, seed=3) as run:
        (run.dir / "a.txt").write_text("x")
        assert not out.exists()  # nothing visible before success
        c = run.curve(["err"])
        c.log(0, err=1.0)
        c.log(10, err=0.5)
        run.metrics["err"] = 0.5
        run.skip("ea_score", "no revolute parts")
        a = run.rng.random()
    m = json.loads((out / "metrics.json").read_text())
    assert m["err"] == 0.5 and m["wall_s"] >= 0 and m["peak_rss_mb"] > 10
    assert m["threads"] == thread_cap() >= 1
    assert m["skipped"] == {"ea_score": "no revolute parts"}
    rows = (out / "curve.csv").read_text().splitlines()
    assert rows[0] == "step,wall_s,err" and rows[2].startswith("10,")
    assert [p.name for p in out.parent.iterdir()] == ["stage"]  # no temporary left behind
    with stage_run("stage", tmp_path / "other", seed=3) as run:
        assert run.rng.random() == a  # seeded


def test_failure_keeps_previous_output(tmp_path):
    out = tmp_path / "s" / "stage"
    with stage_run("stage", out, seed=0) as run:
        (run.dir / "good.txt").write_text("good")
    with pytest.raises(RuntimeError):
        with stage_run("stage", out, seed=0) as run:
            (run.dir / "partial.txt").write_text("half")
            raise RuntimeError("boom")
    assert (out / "good.txt").read_text() == "good" and not (out / "partial.txt").exists()
    assert sorted(p.name for p in out.parent.iterdir()) == ["stage"]


def test_non_finite_metric_is_an_error(tmp_path):
    out = tmp_path / "s" / "stage"
    with pytest.raises(NonFiniteError, match="psnr"):
        with stage_run("stage", out, seed=0) as run:
            run.metrics["psnr"] = math.nan
    assert not out.exists()
    with pytest.raises(NonFiniteError, match="loss"):
        with stage_run("stage", out, seed=0) as run:
            run.curve(["loss"]).log(1, loss=float("inf"))


def test_needs_records_skips(tmp_path):
    m = Manifest("s", "synth", 2, 1, 1, 4, 4,
                 has={"rgb": True, "depth": False, "mono_depth": True, "mono_normal": True, "detections": True,
                      "sparse_points": False, "gt": True},
                 lacks={"depth": "disabled", "sparse_points": "synthetic"}, gt_part_kinds={"revolute": 0, "prismatic": 2, "rigid": 0})
    with stage_run("evaluate", tmp_path / "e", seed=0) as run:
        assert run.needs(m, "depth_loss", "depth") is False
        assert run.needs(m, "ea_score", "gt", "gt:revolute") is False
        assert run.needs(m, "recall", "gt") is True
    sk = json.loads((tmp_path / "e" / "metrics.json").read_text())["skipped"]
    assert sk == {"depth_loss": "capture has no depth: disabled", "ea_score": "ground truth has no revolute parts"}


def test_main_guard_exit_code(capsys):
    @main_guard
    def bad():
        raise InputError("transforms.json: frame 3 is broken")

    with pytest.raises(SystemExit) as e:
        bad()
    assert e.value.code == 2
    assert "error: transforms.json: frame 3 is broken" in capsys.readouterr().err


def test_leftovers_of_interrupted_stages_are_cleaned_and_half_swaps_restored(tmp_path):
    import os
    import subprocess

    from drawer_lib.runner import clean_stale

    scene = tmp_path / "scene"
    dead = subprocess.Popen(["true"])
    dead.wait()  # a pid that no longer runs
    (scene / ".sdf.tmp").mkdir(parents=True)
    (scene / ".sdf.tmp" / ".owner").write_text(str(dead.pid))
    (scene / ".decompose.tmp").mkdir()  # died before it wrote its owner
    (scene / ".appearance.tmp").mkdir()
    (scene / ".appearance.tmp" / ".owner").write_text(str(os.getppid()))  # a live writer elsewhere
    (scene / ".mesh.old").mkdir()  # died between the two renames of a successful run
    (scene / ".mesh.old" / "mesh.ply").write_text("ply")
    with stage_run("articulate", scene / "articulate", seed=0) as run:
        (run.dir / "parts.json").write_text("{}")
    left = sorted(p.name for p in scene.iterdir())
    assert left == [".appearance.tmp", "articulate", "mesh"], left
    assert (scene / "mesh" / "mesh.ply").read_text() == "ply"
    assert clean_stale(tmp_path / "nowhere") == []


def test_a_terminated_stage_removes_its_temporary_folder(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    code = (f"from drawer_lib.runner import stage_run\nimport time\n"
            f"with stage_run('sdf', {str(tmp_path / 's' / 'sdf')!r}, seed=0) as run:\n"
            f"    (run.dir / 'field.pt').write_text('half')\n    print('ready', flush=True)\n    time.sleep(60)\n")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "ready"
    assert (tmp_path / "s" / ".sdf.tmp").is_dir()
    p.send_signal(signal.SIGTERM)
    p.wait(timeout=30)
    t = time.perf_counter()
    assert p.returncode != 0 and time.perf_counter() - t < 30
    assert sorted(x.name for x in (tmp_path / "s").iterdir()) == []


def test_thread_cap_reads_the_environment(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    assert thread_cap() == 3
    monkeypatch.setenv("OMP_NUM_THREADS", "junk")
    assert thread_cap() == (os.cpu_count() or 1)
    monkeypatch.delenv("OMP_NUM_THREADS")
    assert thread_cap() == (os.cpu_count() or 1)


def test_peak_memory_is_the_stages_own_not_its_parents():
    """A stage started by a large process (a benchmark script that rendered first) reports its
    own peak: ru_maxrss would carry the parent's over the fork."""
    import subprocess
    import sys

    import numpy as np

    big = np.ones(400 * 2**20 // 8)  # 400 MiB resident in this process
    code = "from drawer_lib.runner import peak_rss_mb; print(peak_rss_mb())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert float(out) < 300 and big.sum() > 0


def test_deferred_interrupts_hold_the_first_signal_and_yield_to_a_second():
    """Inside, the first Ctrl-C / SIGTERM is only recorded; a second one raises at once; on the
    way out the handlers are the ones before."""
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    with deferred_interrupts() as pending:
        os.kill(os.getpid(), signal.SIGTERM)
        assert pending == [signal.SIGTERM]
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
    assert {s: signal.getsignal(s) for s in before} == before
