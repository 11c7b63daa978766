"""The parallel ``make run`` (drawer_lib/schedule.py): the plan from a stage graph, the runner's
order, concurrency and failure handling with real processes, and a tiny DVC project built by
``repro`` two stages at a time with the same ``dvc.lock`` as a plain ``dvc repro``."""

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drawer_lib.schedule import make_plan, run_plan, thread_env

#        a
#      /   \
#    b1     b2     d (independent)
#      \   /
#        c
DIAMOND = {"a": [], "b1": ["a"], "b2": ["a"], "c": ["b1", "b2"], "d": []}


def _valid(plan, deps):
    seen = set()
    for s in plan.stages:
        assert plan.needs[s] <= seen, (s, plan.stages)
        seen.add(s)


def test_plan_is_the_changed_stages_and_everything_downstream():
    plan = make_plan(DIAMOND, changed={"b1"})
    assert set(plan.stages) == {"b1", "c"}
    assert plan.needs["c"] == {"b1"} and plan.needs["b1"] == set()
    plan = make_plan(DIAMOND, changed={"a"})
    assert set(plan.stages) == {"a", "b1", "b2", "c"}
    _valid(plan, DIAMOND)
    assert make_plan(DIAMOND, changed=set()).stages == []


def test_targets_limit_the_plan_to_what_they_need():
    plan = make_plan(DIAMOND, changed={"a", "d"}, targets={"b2"})
    assert plan.stages == ["a", "b2"]
    plan = make_plan(DIAMOND, changed={"a", "d"}, targets={"d"})
    assert plan.stages == ["d"]
    # a foreach / matrix name stands for all its stages, as `dvc repro` reads it
    grouped = {"k@0": [], "k@1": [], "fit": ["k@0", "k@1"], "ev@train": ["fit", "k@0"], "ev@test": ["fit"], "x": []}
    plan = make_plan(grouped, changed=set(grouped), targets={"ev"})
    assert set(plan.stages) == {"k@0", "k@1", "fit", "ev@train", "ev@test"}
    with pytest.raises(ValueError, match="unknown target stage"):
        make_plan(grouped, changed=set(grouped), targets={"e"})


def test_the_longest_remaining_path_goes_first():
    cost = {"a": 1, "b1": 10, "b2": 100, "c": 1, "d": 50}
    plan = make_plan(DIAMOND, changed={"a", "d"}, cost=cost)
    assert plan.rank["a"] == 102 and plan.rank["b2"] == 101 and plan.rank["d"] == 50
    assert plan.stages == ["a", "b2", "d", "b1", "c"]
    _valid(plan, DIAMOND)


def test_bad_graphs_are_named():
    with pytest.raises(ValueError, match="unknown stage"):
        make_plan({"a": ["zzz"]}, changed={"a"})
    with pytest.raises(ValueError, match="unknown changed"):
        make_plan(DIAMOND, changed={"zzz"})
    with pytest.raises(ValueError, match="unknown target"):
        make_plan(DIAMOND, changed={"a"}, targets={"zzz"})
    with pytest.raises(ValueError, match="cycle"):
        make_plan({"a": ["b"], "b": ["a"]}, changed={"a"})


def _sleeper(log: Path, seconds: float, rc: int = 0):
    """A launcher whose stages append ``start``/``end`` stamps to ``log`` and exit with ``rc``
    (for the stages named in ``rc`` when it is a dict)."""
    code = ("import sys, time; n = sys.argv[1]; f = open(sys.argv[2], 'a'); "
            "f.write(f'{n} start {time.time()}\\n'); f.flush(); time.sleep(float(sys.argv[3])); "
            "f.write(f'{n} end {time.time()}\\n'); sys.exit(int(sys.argv[4]))")

    def launch(stage):
        code_rc = rc.get(stage, 0) if isinstance(rc, dict) else rc
        return subprocess.Popen([sys.executable, "-c", code, stage, str(log), str(seconds), str(code_rc)])
    return launch


def _intervals(log: Path) -> dict[str, list[float]]:
    iv: dict[str, list[float]] = {}
    for line in log.read_text().splitlines():
        name, what, t = line.split()
        iv.setdefault(name, [0.0, 0.0])[0 if what == "start" else 1] = float(t)
    return iv


def test_runner_respects_dependencies_and_the_job_limit(tmp_path):
    plan = make_plan(DIAMOND, changed={"a", "d"})
    log = tmp_path / "log"
    out = run_plan(plan, _sleeper(log, 0.4), jobs=2, report=lambda m: None, poll_s=0.02)
    assert all(o.rc == 0 for o in out)
    iv = _intervals(log)
    for s, needs in plan.needs.items():
        assert all(iv[n][1] <= iv[s][0] for n in needs), (s, iv)
    events = sorted([(t0, 1) for t0, _ in iv.values()] + [(t1, -1) for _, t1 in iv.values()])
    level = peak = 0
    for _, step in events:
        level += step
        peak = max(peak, level)
    assert peak == 2  # two at a time: b1 and b2 overlap, never three


def test_after_a_failure_nothing_new_starts_and_running_stages_finish(tmp_path):
    plan = make_plan(DIAMOND, changed={"a"})
    log = tmp_path / "log"
    out = {o.stage: o for o in run_plan(plan, _sleeper(log, 0.3, rc={"b1": 3}), jobs=2,
                                        report=lambda m: None, poll_s=0.02)}
    assert out["b1"].rc == 3
    assert out["b2"].rc == 0  # it was running: it finished
    assert out["c"].rc is None  # never started
    assert "c" not in _intervals(log)


def test_thread_env_caps_every_pool():
    env = thread_env(1, base={"PATH": "/bin", "OMP_NUM_THREADS": "8"})
    assert env["PATH"] == "/bin"
    assert {env[k] for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")} == {"1"}
    with pytest.raises(ValueError):
        thread_env(0)


TINY_DVC = """
stages:
  a:
    cmd: python stage.py a - 0.5
    deps: [stage.py]
    outs: [a.json]
  b1:
    cmd: python stage.py b1 a.json 1.5
    deps: [stage.py, a.json]
    outs: [b1.json]
  b2:
    cmd: python stage.py b2 a.json 1.5
    deps: [stage.py, a.json]
    outs: [b2.json]
  c:
    cmd: python stage.py c b1.json,b2.json 0.2
    deps: [stage.py, b1.json, b2.json]
    outs: [c.json]
"""
TINY_STAGE = """import json, os, sys, time
name, inputs, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
t0 = time.time()
total = sum(json.load(open(p))["value"] for p in inputs.split(",") if p != "-")
time.sleep(seconds)
json.dump({"value": total + len(name), "threads": os.environ.get("OMP_NUM_THREADS"),
           "t0": t0, "t1": time.time()}, open(f"{name}.json", "w"))
"""


@pytest.mark.dvc
def test_repro_builds_a_dvc_project_two_stages_at_a_time(tmp_path):
    from drawer_lib.schedule import repro

    d = tmp_path / "proj"
    d.mkdir()
    (d / "dvc.yaml").write_text(TINY_DVC)
    (d / "stage.py").write_text(TINY_STAGE)
    env = {**os.environ, "DVC_NO_ANALYTICS": "1", "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}"}

    def run(*cmd, cwd=d):
        return subprocess.run(cmd, cwd=cwd, env=env, check=True, capture_output=True, text=True)

    run("git", "init", "-q")
    run(sys.executable, "-m", "dvc", "init", "-q")
    run("git", "add", "-A")
    run("git", "-c", "user.email=t@t", "-c", "user.name=t", "commit", "-qm", "init")
    msgs = []
    assert repro(d, jobs=2, threads=1, report=msgs.append) == 0, "\n".join(msgs)
    out = {s: json.loads((d / f"{s}.json").read_text()) for s in ("a", "b1", "b2", "c")}
    assert out["c"]["value"] == (1 + 2) * 2 + 1
    assert {o["threads"] for o in out.values()} == {"1"}
    assert out["b1"]["t0"] < out["b2"]["t1"] and out["b2"]["t0"] < out["b1"]["t1"]  # side by side
    assert max(out["b1"]["t1"], out["b2"]["t1"]) <= out["c"]["t0"]
    summary = json.loads((d / "logs" / "repro" / "summary.json").read_text())
    assert summary["n_stages"] == summary["n_stages_total"] == 4 and summary["n_failed"] == 0
    assert set(summary["stages"]) == {"a", "b1", "b2", "c"} and summary["stage_wall_s"] >= 0.5 + 1.5 + 1.5 + 0.2
    assert summary["wall_s"] < summary["stage_wall_s"]  # b1 and b2 side by side
    # DVC agrees that everything is built and recorded, and a second run does nothing
    assert "up to date" in run(sys.executable, "-m", "dvc", "status").stdout
    msgs.clear()
    assert repro(d, jobs=2, report=msgs.append) == 0 and "up to date" in msgs[-1]
    # --force reruns everything (no run-cache restore); a launcher runs each stage's dvc command
    # (srun on a cluster; here a wrapper that notes what it ran)
    t_a = (d / "a.json").stat().st_mtime_ns
    msgs.clear()
    wrapper = tmp_path / "launch.py"
    wrapper.write_text("import subprocess, sys\nopen(sys.argv[0] + '.log', 'a').write(sys.argv[-1] + '\\n')\n"
                       "sys.exit(subprocess.call(sys.argv[1:]))\n")
    assert repro(d, jobs=2, force=True, report=msgs.append, launcher=[sys.executable, str(wrapper)]) == 0
    assert sorted((tmp_path / "launch.py.log").read_text().split()) == ["a", "b1", "b2", "c"]
    assert any("4 stage(s) to run" in m for m in msgs) and (d / "a.json").stat().st_mtime_ns != t_a
    # the lock file is the one a plain `dvc repro` writes
    lock = (d / "dvc.lock").read_text()
    clone = tmp_path / "plain"
    shutil.copytree(d, clone, ignore=shutil.ignore_patterns("*.json", "dvc.lock"))
    run(sys.executable, "-m", "dvc", "repro", cwd=clone)

    def entries(text):
        import yaml
        stages = yaml.safe_load(text)["stages"]
        return {s: ({k: v for k, v in e.items() if k != "outs"}, [o["path"] for o in e["outs"]]) for s, e in stages.items()}
    assert entries((clone / "dvc.lock").read_text()) == entries(lock)
    # a change reruns exactly the changed stage and what depends on it
    dvc_yaml = (d / "dvc.yaml").read_text().replace("python stage.py b2 a.json 1.5", "python stage.py b2 a.json 0.1")
    (d / "dvc.yaml").write_text(dvc_yaml)
    t_a = (d / "a.json").stat().st_mtime_ns
    msgs.clear()
    assert repro(d, jobs=2, report=msgs.append) == 0
    assert any("2 stage(s) to run" in m for m in msgs), msgs
    assert (d / "a.json").stat().st_mtime_ns == t_a
    # a failing stage: non-zero exit, its log named, what finished is recorded
    (d / "dvc.yaml").write_text(dvc_yaml.replace("python stage.py b1 a.json 1.5", "python -c 'import sys; sys.exit(7)'"))
    msgs.clear()
    t0 = time.perf_counter()
    assert repro(d, jobs=2, report=msgs.append) == 1
    text = "\n".join(msgs)
    assert "b1" in text and "failed" in text and "not started" in text and "c" in text.split("not started")[-1]
    assert time.perf_counter() - t0 < 60


def test_typical_walls_by_family_and_variant():
    from drawer_lib.schedule import typical_wall_s

    assert typical_wall_s("geometry@kitchen_small-tsdf") < typical_wall_s("geometry@kitchen_small-neural_mono")
    assert typical_wall_s("appearance@my-kitchen-textured_mesh") < typical_wall_s("appearance@kitchen_small-free_gs")
    assert typical_wall_s("sdf@kitchen_small") == typical_wall_s("dvc.yaml:sdf@other")
    assert typical_wall_s("unknown_stage", default=7.0) == 7.0


def test_an_interrupt_stops_the_running_stages_and_propagates(tmp_path):
    plan = make_plan(DIAMOND, changed={"a", "d"})
    procs = []

    # one stage takes SIGINT, the other ignores it (as a process started in the background does)
    codes = ["import signal, time; signal.signal(signal.SIGINT, signal.default_int_handler); time.sleep(60)",
             "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); time.sleep(60)"]

    def launch(stage):  # each stage in its own session, as repro() starts them
        procs.append(subprocess.Popen([sys.executable, "-c", codes[len(procs) % 2]], start_new_session=True))
        return procs[-1]

    def report(msg):
        if msg.startswith("[2/"):
            time.sleep(1.0)  # both have started their sleep
            raise KeyboardInterrupt

    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        run_plan(plan, launch, jobs=2, report=report, poll_s=0.02, grace_s=2.0)
    assert len(procs) == 2 and all(p.poll() is not None for p in procs)
    assert procs[0].returncode != -15  # stopped by SIGINT
    assert procs[1].returncode == -15  # ignored SIGINT, stopped by SIGTERM
    assert time.perf_counter() - t0 < 30


def test_the_yaml_memo_parses_each_text_once_and_hands_out_copies():
    import dvc.utils.serialize._yaml as dvc_yaml

    from drawer_lib.schedule import yaml_parse_memo

    original = dvc_yaml.parse_yaml
    with yaml_parse_memo() as cache:
        a = dvc_yaml.parse_yaml("x: {y: [1, 2]}\n", "params.yaml")
        a["x"]["y"].append(3)  # a caller that edits its copy
        b = dvc_yaml.parse_yaml("x: {y: [1, 2]}\n", "params.yaml")
        c = dvc_yaml.parse_yaml("x: {y: [1, 5]}\n", "params.yaml")  # the file changed: parsed anew
        assert len(cache) == 2
    assert b == {"x": {"y": [1, 2]}} and c == {"x": {"y": [1, 5]}}
    assert dvc_yaml.parse_yaml is original


@pytest.mark.dvc
def test_a_parameter_change_is_planned_with_the_yaml_memo(tmp_path):
    from drawer_lib.schedule import dvc_graph

    d = tmp_path / "proj"
    d.mkdir()
    (d / "params.yaml").write_text("p: {a: 1, b: 2}\nq: 3\n")
    (d / "dvc.yaml").write_text("stages:\n" + "".join(
        f"  s{k}:\n    cmd: python -c \"open('s{k}.txt', 'w').write('{k}')\"\n    params: [{key}]\n    outs: [s{k}.txt]\n"
        for k, key in enumerate(["p.a", "p.b", "q", "p.a"])))
    env = {**os.environ, "DVC_NO_ANALYTICS": "1"}
    for cmd in (["git", "init", "-q"], [sys.executable, "-m", "dvc", "init", "-q"], [sys.executable, "-m", "dvc", "repro", "-q"]):
        subprocess.run(cmd, cwd=d, env=env, check=True, capture_output=True)
    assert dvc_graph(d)[1] == set()
    (d / "params.yaml").write_text("p: {a: 1, b: 7}\nq: 3\n")
    assert dvc_graph(d)[1] == {"s1"}
