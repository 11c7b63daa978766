"""Run the pipeline's out-of-date stages in parallel on the machine's cores (``make run``).

``dvc repro`` runs stages one after the other, and a stage on 2 threads rarely uses 2 cores:
the appearance training scales ~1.3x from 1 to 2 threads, the twin, simulation and report
stages hardly at all. Independent stages (the two geometry trainings, the four trained
appearance variants, perception next to appearance, the twin's chain next to the last variants)
can share the cores instead. This module plans that and runs it with DVC itself:

1. one ``dvc status`` (in-process) finds the stages that changed; with everything that depends
   on them, they are the *plan*. DVC parses ``params.yaml`` again for every stage that has
   parameter dependencies (43 times for the default scene); here each distinct text is parsed
   once (:func:`yaml_parse_memo`), which takes ~0.4 s off a no-op ``make run``;
2. every planned stage runs as its own ``dvc --wait-for-lock repro --single-item <stage>``
   process (on this machine, or through a ``launcher`` such as SLURM's ``srun``) once the
   planned stages it depends on have finished. DVC releases the repository's
   lock while a stage's command runs and updates ``dvc.lock`` under it, so several of these
   processes share one workspace (``unlocked_repo`` in DVC's ``dvc/stage/run.py``). A stage whose inputs
   came out unchanged is skipped by DVC, and the run-cache restores instead of running as usual.

Threads are part of a result: the thread count changes the order of float sums in torch's and
numba's parallel reductions (docs/sweeps.md, "the ablation three ways"). So a stage's thread
count never depends on timing or on what else happens to run: every stage gets
``threads_per_stage`` threads (default ``cores // jobs``), set through ``OMP_NUM_THREADS``,
``MKL_NUM_THREADS`` and ``NUMBA_NUM_THREADS``. ``OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 dvc repro``
gives the same bits as ``make run`` with 2 jobs on any machine.

Among the ready stages, the one on the longest remaining path runs first (its cost: the
``wall_s`` of its last ``metrics.json``, else a typical wall of its family), so the long chain (capture -> sdf -> mesh ->
appearance -> complete -> twin -> stability) is never starved. The order changes when stages
finish, never what they compute.

On a failure no new stage starts, the running ones finish (nothing computed is lost), the
failed stage's log tail is printed and the exit code is 1. Every stage's output goes to
``<log_dir>/<stage>.log``.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

SUMMARY = "summary.json"  # in the log folder: the last run's wall time and each stage's (the README's `make run` row)
THREAD_ENV = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")

# Typical stage walls (s) on kitchen_small at 1 thread, by stage family (the name before "@") or
# family-variant (a matrix stage's last name part): the cost of a stage that has no metrics.json
# yet (a fresh clone). They only order the stages.
TYPICAL_WALL_S = {"capture": 15, "sdf": 450, "geometry": 500, "geometry-tsdf": 30, "mesh": 35, "decompose": 20,
                  "articulate": 5, "evaluate": 5, "appearance": 260, "appearance-textured_mesh": 35,
                  "complete": 20, "twin": 35, "stability": 55, "simulate": 20, "ablation": 5,
                  "geometry_table": 5, "report": 45, "pareto": 1500, "bench_kitchen": 50, "fit_decisions": 15,
                  "bench_eval": 80}


def typical_wall_s(stage: str, default: float = 30.0) -> float:
    """:data:`TYPICAL_WALL_S` for a stage name (``family@item``, a matrix item ``scene-variant``)."""
    family, _, item = stage.split(":")[-1].partition("@")
    variant = item.rsplit("-", 1)[-1] if "-" in item else None
    return float(TYPICAL_WALL_S.get(f"{family}-{variant}", TYPICAL_WALL_S.get(family, default)))


@dataclass(frozen=True)
class Plan:
    """The stages to run and what each one waits for.

    ``stages``: stage names in a valid run order (every stage after the planned stages it
    depends on), by priority; ``needs[s]``: the planned stages ``s`` depends on (directly or
    through unplanned stages); ``rank[s]``: the cost of the longest path from ``s`` to the end
    of the plan, ``s`` included (seconds when costs are walls).
    """

    stages: list[str]
    needs: dict[str, frozenset[str]]
    rank: dict[str, float] = field(default_factory=dict)


def make_plan(deps: Mapping[str, Iterable[str]], changed: Iterable[str],
              cost: Mapping[str, float] | None = None, targets: Iterable[str] | None = None) -> Plan:
    """The plan from a stage graph.

    ``deps[s]``: the stages whose outputs ``s`` uses (every stage is a key); ``changed``: the
    stages DVC reports as changed; ``cost[s]``: an estimate of ``s``'s run time (default 1);
    ``targets``: when given, only these stages and what they depend on are considered (a
    ``foreach`` / ``matrix`` name stands for all its stages, ``bench_eval`` for
    ``bench_eval@train`` and ``bench_eval@test``, as ``dvc repro`` reads it). The plan is the
    changed stages and everything downstream of them. Raises ``ValueError`` on an unknown stage
    name or a cycle.
    """
    deps = {s: frozenset(d) for s, d in deps.items()}
    for s, d in deps.items():
        unknown = d - deps.keys()
        if unknown:
            raise ValueError(f"stage {s!r} depends on unknown stage(s) {sorted(unknown)}")
    changed = set(changed)
    if changed - deps.keys():
        raise ValueError(f"unknown changed stage(s) {sorted(changed - deps.keys())}")
    order = _topological(deps)
    dependents: dict[str, set[str]] = {s: set() for s in deps}
    for s, d in deps.items():
        for u in d:
            dependents[u].add(s)

    scope = set(deps)
    if targets is not None:
        targets = {s for t in targets for s in ([t] if t in deps else [k for k in deps if k.startswith(t + "@")] or [t])}
        if targets - deps.keys():
            raise ValueError(f"unknown target stage(s) {sorted(targets - deps.keys())}; "
                             f"stages are: {', '.join(order)}")
        scope = set()
        for s in reversed(order):           # downstream first: a stage is in scope if a target needs it
            if s in targets or dependents[s] & scope:
                scope.add(s)

    planned = set()
    for s in order:                          # upstream first: changed, or downstream of a planned stage
        if s in scope and (s in changed or deps[s] & planned):
            planned.add(s)

    # what each planned stage waits for: planned stages reachable upstream (through unplanned ones)
    needs: dict[str, frozenset[str]] = {}
    upstream_planned: dict[str, frozenset[str]] = {}
    for s in order:
        acc: set[str] = set()
        for u in deps[s]:
            acc |= upstream_planned[u]
            if u in planned:
                acc.add(u)
        upstream_planned[s] = frozenset(acc)
        if s in planned:
            needs[s] = upstream_planned[s]

    cost = cost or {}
    rank: dict[str, float] = {}
    for s in reversed(order):
        if s in planned:
            after = [rank[d] for d in dependents[s] if d in planned]
            rank[s] = max(float(cost.get(s, 1.0)), 0.0) + max(after, default=0.0)
    position = {s: i for i, s in enumerate(order)}
    stages = sorted(planned, key=lambda s: (-rank[s], position[s]))
    # a valid order by priority: repeatedly take the highest-ranked stage whose needs are taken
    ordered: list[str] = []
    done: set[str] = set()
    while len(ordered) < len(stages):
        s = next(s for s in stages if s not in done and needs[s] <= done)
        ordered.append(s)
        done.add(s)
    return Plan(ordered, needs, rank)


def _topological(deps: Mapping[str, frozenset[str]]) -> list[str]:
    """Stages upstream first, ties by name (deterministic); ``ValueError`` on a cycle."""
    remaining = {s: set(d) for s, d in deps.items()}
    order: list[str] = []
    while remaining:
        ready = sorted(s for s, d in remaining.items() if not d)
        if not ready:
            raise ValueError(f"the stage graph has a cycle among {sorted(remaining)}")
        for s in ready:
            del remaining[s]
        for d in remaining.values():
            d.difference_update(ready)
        order.extend(ready)
    return order


@dataclass
class Outcome:
    """What happened to one planned stage: ``rc`` None when it never started."""

    stage: str
    rc: int | None = None
    wall_s: float = 0.0
    log: Path | None = None


def run_plan(plan: Plan, launch: Callable[[str], subprocess.Popen], jobs: int,
             report: Callable[[str], None] = print, poll_s: float = 0.2,
             heartbeat: Callable[[list[str]], None] | None = None, heartbeat_s: float = 30.0,
             grace_s: float = 20.0) -> list[Outcome]:
    """Run ``plan`` with at most ``jobs`` stages at once; ``launch(stage)`` starts one and
    returns its process. After a failure nothing new starts and the running stages finish.
    On KeyboardInterrupt the running stages get SIGINT (DVC then removes their partial
    outputs), SIGTERM after ``grace_s`` seconds and SIGKILL after twice that, and are waited for. ``heartbeat(running stages)`` is called every
    ``heartbeat_s`` seconds. Returns one outcome per planned stage, in plan order."""
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    outcomes = {s: Outcome(s) for s in plan.stages}
    running: dict[str, tuple[subprocess.Popen, float]] = {}
    done: set[str] = set()
    failed = False
    n = len(plan.stages)
    beat = time.perf_counter()
    try:
        while True:
            if not failed:
                for s in plan.stages:
                    if len(running) >= jobs:
                        break
                    if s in done or s in running or not plan.needs[s] <= done:
                        continue
                    running[s] = (launch(s), time.perf_counter())
                    report(f"[{len(done) + len(running)}/{n}] start {s}")
            if not running:
                break
            time.sleep(poll_s)
            if heartbeat is not None and time.perf_counter() - beat >= heartbeat_s:
                beat = time.perf_counter()
                heartbeat(list(running))
            for s, (proc, t0) in list(running.items()):
                rc = proc.poll()
                if rc is None:
                    continue
                del running[s]
                o = outcomes[s]
                o.rc, o.wall_s = rc, time.perf_counter() - t0
                done.add(s)
                if rc == 0:
                    report(f"      done  {s} in {o.wall_s:.1f} s")
                else:
                    failed = True
                    report(f"      FAILED {s} (exit {rc}) after {o.wall_s:.1f} s"
                           + ("; no new stage starts, waiting for the running ones" if running else ""))
    except KeyboardInterrupt:
        report(f"interrupted: stopping {', '.join(running) or 'nothing'}")
        procs = [proc for proc, _ in running.values()]
        # SIGINT first (a stage cleans up as on Ctrl-C); SIGTERM after grace_s, for processes that
        # ignore SIGINT (started in the background: a shell's `&` ignores it for its children)
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            for proc in procs:
                _signal(proc, sig)
            deadline = time.perf_counter() + grace_s
            while any(p.poll() is None for p in procs) and time.perf_counter() < deadline:
                time.sleep(0.05)
            if all(p.poll() is not None for p in procs):
                break
        for s, (proc, t0) in running.items():
            outcomes[s].rc, outcomes[s].wall_s = proc.wait(), time.perf_counter() - t0
        raise
    return [outcomes[s] for s in plan.stages]


def _signal(proc: subprocess.Popen, sig: int) -> None:
    """``sig`` to ``proc``, and to its whole process group when it leads one (a stage launched in
    its own session: DVC ignores SIGINT while its stage command runs, as a terminal's Ctrl-C
    reaches the command directly)."""
    if proc.poll() is not None:
        return
    try:
        if os.getpgid(proc.pid) == proc.pid:
            os.killpg(proc.pid, sig)
            return
    except OSError:
        pass
    try:
        proc.send_signal(sig)
    except OSError:
        pass


def thread_env(threads: int, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """``base`` (default: this process's environment) with every thread pool capped to ``threads``."""
    if threads < 1:
        raise ValueError(f"threads must be at least 1, got {threads}")
    env = dict(os.environ if base is None else base)
    env.update({k: str(threads) for k in THREAD_ENV})
    return env


@contextlib.contextmanager
def yaml_parse_memo():
    """Within the block, DVC's YAML parser (``dvc.utils.serialize._yaml.parse_yaml``) parses each
    distinct (text, path, type) once and hands out deep copies of that parse, so a caller that
    edits what it got cannot change what the next one gets. Keyed on the text itself, never on
    a file's time stamp. The original parser is restored on exit."""
    import copy

    import dvc.utils.serialize._yaml as dvc_yaml

    original, cache = dvc_yaml.parse_yaml, {}

    def parse_yaml(text, path, typ="safe"):
        key = (text, str(path), typ)
        if key not in cache:
            cache[key] = original(text, path, typ)
        return copy.deepcopy(cache[key])

    dvc_yaml.parse_yaml = parse_yaml
    try:
        yield cache
    finally:
        dvc_yaml.parse_yaml = original


def dvc_graph(root: Path) -> tuple[dict[str, frozenset[str]], set[str], dict[str, float]]:
    """The pipeline of the DVC project at ``root``: ``deps`` (stage -> the stages it uses),
    the changed stages (one in-process ``dvc status``) and each stage's cost (the sum of the
    ``wall_s`` of its metrics files as they are now, else :data:`TYPICAL_WALL_S` of its family). Stages without a
    command (``.dvc`` files) are left out; frozen stages keep no upstream edges, as in DVC."""
    from dvc.repo import Repo
    from dvc.repo.reproduce import get_active_graph

    # stage names (``addressing``) are relative to the working directory, as on the command line
    with contextlib.chdir(root), yaml_parse_memo(), Repo(str(root)) as repo:
        graph = get_active_graph(repo.index.graph)
        names = {st: st.addressing for st in graph if getattr(st, "cmd", None)}
        deps = {names[st]: frozenset(names[d] for d in graph.successors(st) if d in names) for st in names}
        status = repo.status()
        changed = {name for name in status if name in deps}
        cost = {}
        for st, name in names.items():
            walls = []
            for out in st.outs:
                if out.metric and str(out.fs_path).endswith(".json"):
                    try:
                        walls.append(float(json.loads(Path(out.fs_path).read_text())["wall_s"]))
                    except (OSError, ValueError, KeyError, TypeError):
                        pass
            cost[name] = sum(walls) if walls else typical_wall_s(name)
    return deps, changed, cost


def repro(root: Path, jobs: int = 2, threads: int | None = None, targets: list[str] | None = None,
          log_dir: Path | None = None, dry: bool = False, force: bool = False,
          report: Callable[[str], None] = print, launcher: list[str] | None = None) -> int:
    """Plan and run the project at ``root`` (see the module docstring); the exit code. ``force``:
    every stage (of ``targets``) runs, none is restored from the run-cache (``dvc repro -f``).
    ``launcher``: a command that runs each stage's ``dvc repro --single-item`` elsewhere and
    returns when it is done, e.g. ``["srun", "--partition=cpu", "--cpus-per-task=1"]`` (a SLURM
    cluster whose nodes share this workspace: DVC's lock lets the stages update ``dvc.lock``
    from any node). Writes ``<log_dir>/summary.json`` (the run's and each stage's wall time)."""
    cores = os.cpu_count() or 1
    threads = threads or max(1, cores // jobs)
    log_dir = log_dir or root / "logs" / "repro"
    t0 = time.perf_counter()
    deps, changed, cost = dvc_graph(root)
    plan = make_plan(deps, set(deps) if force else changed, cost, targets)
    if not plan.stages:
        report(f"Data and pipelines are up to date ({time.perf_counter() - t0:.1f} s).")
        return 0
    report(f"{len(plan.stages)} stage(s) to run, {jobs} at a time, {threads} thread(s) each "
           f"(the longest remaining path first); logs in {log_dir}")
    if dry:
        for s in plan.stages:   # the nearest stages it waits for (the rest follows from theirs)
            near = {n for n in plan.needs[s] if not any(n in plan.needs[m] for m in plan.needs[s])}
            report(f"  {s:<48} ~{plan.rank[s]:5.0f} s to the end; after {', '.join(sorted(near)) or '-'}")
        return 0
    log_dir.mkdir(parents=True, exist_ok=True)
    env = thread_env(threads)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"   # the stages' `python`
    dvc = [sys.executable, "-m", "dvc", "--wait-for-lock", "repro", "--single-item", *(["--force"] if force else [])]
    logs: dict[str, Path] = {}

    def launch(stage: str) -> subprocess.Popen:
        logs[stage] = log_dir / f"{stage.replace('/', '_')}.log"
        with logs[stage].open("w") as f:
            return subprocess.Popen([*(launcher or []), *dvc, stage], cwd=root, env=env, stdout=f, stderr=subprocess.STDOUT,
                                    start_new_session=True)   # Ctrl-C reaches the scheduler, which stops each stage once

    def heartbeat(running: list[str]) -> None:
        for s in running:
            report(f"      ... {s}: {_last_progress(logs[s])}")

    def terminate(signum, frame):   # a cluster's or a timeout's SIGTERM stops the stages as Ctrl-C does
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        outcomes = run_plan(plan, launch, jobs, report, heartbeat=heartbeat)
    finally:
        signal.signal(signal.SIGTERM, previous)
    wall = time.perf_counter() - t0
    ran = [o for o in outcomes if o.rc is not None]
    report(f"\n{'stage':<48} {'wall_s':>8}  result")
    for o in ran:
        report(f"{o.stage:<48} {o.wall_s:8.1f}  {'ok' if o.rc == 0 else f'exit {o.rc}'}")
    bad = [o for o in ran if o.rc != 0]
    never = [o.stage for o in outcomes if o.rc is None]
    report(f"{'total':<48} {wall:8.1f}  {len(ran) - len(bad)} ok, {len(bad)} failed, {len(never)} not started")
    (log_dir / SUMMARY).write_text(json.dumps({  # a log like the stages' (not an output: no atomic write)
        "wall_s": round(wall, 1), "jobs": jobs, "threads": threads, "force": force, "n_stages": len(ran),
        "n_stages_total": len(deps), "n_failed": len(bad), "stage_wall_s": round(sum(o.wall_s for o in ran), 1),
        "stages": {o.stage: {"wall_s": round(o.wall_s, 1), "rc": o.rc} for o in ran}}, indent=1))
    for o in bad:
        tail = logs[o.stage].read_text(errors="replace").splitlines()[-30:]
        report(f"\n--- {o.stage} failed; the end of {logs[o.stage]}:\n" + "\n".join(tail))
    if never:
        report(f"not started (after the failure): {', '.join(never)}")
    return 1 if bad else 0


def _last_progress(log: Path, tail_bytes: int = 4096) -> str:
    """The last line or progress-bar state a stage wrote to ``log`` (tqdm rewrites with \\r)."""
    try:
        with log.open("rb") as f:
            f.seek(max(0, log.stat().st_size - tail_bytes))
            text = f.read().decode(errors="replace")
    except OSError:
        return ""
    parts = [p.strip() for p in text.replace("\r", "\n").split("\n") if p.strip()]
    return parts[-1][:120] if parts else "(no output yet)"
