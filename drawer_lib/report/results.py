"""The README's results table, written from the tracked metrics of one run (``make run``): the
default scene's geometry, appearance, articulation, twin, simulation and stability figures, the
benchmark's splits, the numerical-extremes tests and the run's wall time, with the commit and the
machine they came from. A figure read from many kitchens shows its spread (mean ± sd, worst);
figures of the one default scene are one seed on one machine and say so.

    python scripts/readme_results.py            # print the table
    python scripts/readme_results.py --write    # replace the README's results block

The seed spread: queue the default scene at other seeds first, e.g. ``dvc exp run --queue -n
seed-1 -S seed=1`` and ``dvc queue start``; their finished experiments of the current commit
are found through ``dvc exp show``.
"""

import dataclasses
import json
import os
import platform
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from drawer_lib.paths import LAYOUT, BenchPaths, ScenePaths, bench_name
from drawer_lib.report.markdown import md_table
from drawer_lib.report.paper import PAPER
from drawer_lib.schedule import SUMMARY

BEGIN, END = "<!-- results: begin (scripts/readme_results.py writes this block) -->", "<!-- results: end -->"


class MissingMetrics(Exception):
    """A metrics file the table needs is missing: the run has not made it."""


def _read(path: Path) -> dict:
    if not path.is_file():
        raise MissingMetrics(f"{path.name} of {path.parent.name}/ is missing (run `make run` first)")
    return json.loads(path.read_text())


@dataclass(frozen=True)
class Run:
    """Where one run's outputs are: the project ``root`` and its ``paths`` (params.yaml's);
    ``tracked``: the metrics files of a DVC experiment ({path relative to ``root``: data}) to
    read instead of the workspace's files (:func:`seed_runs`)."""

    root: Path
    out: Path
    reports: Path
    bench: Path
    scene: str
    tracked: dict | None = None

    @property
    def sp(self) -> ScenePaths:
        return ScenePaths(self.out, self.scene)

    def read(self, path: Path) -> dict:
        if self.tracked is None:
            return _read(path)
        rel = Path(path).relative_to(self.root).as_posix()
        if rel not in self.tracked:
            raise MissingMetrics(f"{rel} is not among the experiment's metrics")
        return self.tracked[rel]

    def metrics(self, stage: str) -> dict:
        return self.read(self.sp.metrics(stage))


def seed_runs(base: Run, params: dict) -> list[tuple[int, Run]]:
    """The finished DVC experiments of the current commit whose parameters differ from the
    workspace's ``params`` in ``seed`` only (e.g. ``dvc exp run --queue -S seed=1``), as (seed,
    run reading their tracked metrics), by seed (``dvc exp show --json``; none when DVC cannot
    tell)."""
    r = subprocess.run([sys.executable, "-m", "dvc", "exp", "show", "--json"], cwd=base.root, capture_output=True,
                       text=True, check=False)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=base.root, capture_output=True, text=True,
                          check=False).stdout.strip()
    try:
        return seed_experiments(json.loads(r.stdout), head, params, base)
    except ValueError:
        return []


def seed_experiments(revs: list[dict], head: str, params: dict, base: Run) -> list[tuple[int, Run]]:
    """:func:`seed_runs` from the parsed ``dvc exp show --json`` (``revs``), the commit
    ``head`` and the workspace's ``params``."""
    rest = {k: v for k, v in params.items() if k != "seed"}
    out = []
    for rev in revs:
        if rev.get("rev") != head:
            continue
        for exp in rev.get("experiments") or []:
            for x in exp.get("revs") or []:
                data = x.get("data") or {}
                p = ((data.get("params") or {}).get("params.yaml") or {}).get("data")
                if not p or x.get("error") or p.get("seed") == params.get("seed"):
                    continue
                if {k: v for k, v in p.items() if k != "seed"} != rest:
                    continue
                tracked = {path: m.get("data", {}) for path, m in (data.get("metrics") or {}).items()}
                out.append((int(p["seed"]), dataclasses.replace(base, tracked=tracked)))
    return sorted(out, key=lambda t: t[0])


# the figures whose spread over seeds the table shows: (row, what, figure of a run, number format, unit);
# each is read from metrics DVC tracks (the twin's are inside its output folder, so it has none)
SEED_FIGURES = (
    ("geometry, neural SDF", "Chamfer-L1", lambda r: 1000 * r.metrics("mesh")["chamfer_l1"], "{:.2f}", " mm"),
    ("appearance, the paper's method (`movable_gs_ste`)", "PSNR",
     lambda r: r.read(r.sp.appearance_dir("movable_gs_ste") / LAYOUT["metrics"])["psnr"], "{:.2f}", " dB"),
    ("articulation (", "precision / recall / EA-score",
     lambda r: tuple(r.metrics("evaluate").get(k, float("nan")) for k in ("precision", "recall", "ea_score")),
     "{:.3f}", ""),
    ("the simulated twin (", "motion EMD", lambda r: r.metrics("evaluate").get("emd", float("nan")), "{:.2e}", ""),
)


def _span(values: list, fmt: str) -> str:
    """``a–b`` of the values (each a number or a tuple of numbers formatted alike)."""
    if isinstance(values[0], tuple):
        return " / ".join(_span([v[i] for v in values], fmt) for i in range(len(values[0])))
    lo, hi = min(values), max(values)
    return fmt.format(lo) if lo == hi else f"{fmt.format(lo)}–{fmt.format(hi)}"


def seed_spread(table: list[list[str]], run: Run, seeds: list[tuple[int, Run]], seed0: int) -> list[list[str]]:
    """The rows with, for the figures of :data:`SEED_FIGURES`, their range over this run and
    the seed experiments appended."""
    if not seeds:
        return table
    runs = [(seed0, run), *seeds]
    names = ", ".join(str(s) for s, _ in sorted(runs, key=lambda t: t[0]))
    out = []
    for name, figures, details in table:
        for prefix, what, fn, fmt, unit in SEED_FIGURES:
            if name.startswith(prefix) and not figures.startswith("not measured"):
                try:
                    vals = [fn(r) for _, r in runs]
                except (MissingMetrics, KeyError):
                    continue
                figures += f" (seeds {names}: {what} {_span(vals, fmt)}{unit})"
        out.append([name, figures, details])
    return out


def provenance(root: Path) -> str:
    """The commit (and whether the tree differs from it), the machine and the date."""
    def git(*a: str) -> str:
        return subprocess.run(["git", *a], cwd=root, capture_output=True, text=True, check=False).stdout

    commit = git("rev-parse", "--short", "HEAD").strip() or "unknown"
    # a run rewrites dvc.lock and this script the README: neither makes the code differ from the
    # commit. Porcelain lines are "XY path": the leading blank of an unstaged change is kept
    dirty = [x for x in git("status", "--porcelain", "--untracked-files=no").splitlines()
             if x[3:] not in ("dvc.lock", "README.md")]
    try:
        mem = next(int(x.split()[1]) for x in Path("/proc/meminfo").read_text().splitlines() if x.startswith("MemTotal"))
        mem_s = f", {mem / 2**20:.0f} GiB"
    except (OSError, StopIteration, ValueError):
        mem_s = ""
    cpu = platform.processor() or platform.machine()
    return (f"commit `{commit}`{' (with uncommitted changes)' if dirty else ''}, {os.cpu_count()} cores "
            f"({cpu}){mem_s}, no GPU, Python {platform.python_version()}")


def _f(v, spec: str = ".3f") -> str:
    return "–" if v is None else format(v, spec)


def _spread(m: dict, key: str, spec: str = ".3f") -> str:
    """``mean ± sd`` (worst) of a per-kitchen figure of a benchmark split's metrics."""
    if f"fitted_{key}_mean" not in m:
        return "–"
    return (f"{_f(m[f'fitted_{key}_mean'], spec)} ± {_f(m[f'fitted_{key}_std'], spec)} "
            f"(worst {_f(m[f'fitted_{key}_worst'], spec)})")


def rows(run: Run, variants: list[str], geometry_variants: list[str]) -> list[list[str]]:
    """[result, figures, details] rows (see the module doc)."""
    out = []

    def row(name: str, fn: Callable[[], str], details: str) -> None:
        try:
            out.append([name, fn(), details])
        except MissingMetrics as e:
            out.append([name, f"not measured: {e}", details])

    sp = run.sp
    geo_names = {"tsdf": "TSDF baseline (sensor depth, 2 cm)", "neural_mono": "RGB + monocular priors (DRAWER's setting)"}

    def geo(m: dict) -> str:
        return (f"Chamfer-L1 {1000 * m['chamfer_l1']:.2f} mm, F@1cm {m['fscore_1cm']:.3f}, "
                f"F@2cm {m['fscore_2cm']:.3f}")

    row("geometry, neural SDF", lambda: geo(run.metrics("mesh")), "[docs/geometry.md](docs/geometry.md)")
    for v in geometry_variants:
        row(f"geometry, {geo_names.get(v, v)}", lambda v=v: geo(run.read(ScenePaths(run.out, run.scene, v).metrics("mesh"))),
            "[docs/geometry.md](docs/geometry.md)")

    def app(v: str) -> dict:
        return run.read(sp.appearance_dir(v) / LAYOUT["metrics"])

    if "movable_gs_ste" in variants:
        row("appearance, the paper's method (`movable_gs_ste`)",
            lambda: (lambda m: f"PSNR {m['psnr']:.2f} dB, SSIM {m['ssim']:.3f}, LPIPS {m['lpips']:.3f}")(app("movable_gs_ste")),
            "[docs/appearance.md](docs/appearance.md)")
    row("appearance ablation (" + " → ".join(variants) + ")",
        lambda: " → ".join(f"{app(v)['psnr']:.2f}" for v in variants) + " dB",
        "[docs/appearance.md](docs/appearance.md)")

    def art() -> str:
        m = run.metrics("evaluate")
        s = (f"precision {_f(m.get('precision'))} ({m['n_correct']}/{m['n_pred'] - m['n_ignored']}), recall "
             f"{_f(m.get('recall'))} ({m['n_correct']}/{m['n_gt']}), EA-score {_f(m.get('ea_score'), '.4f')}")
        if "rigid_recall" in m:
            s += f"; rigid objects {m['n_rigid_matched']}/{m['n_rigid_gt']} found, precision {_f(m.get('rigid_precision'), '.2f')}"
        dp = sp.file("articulate", "decisions")
        dec = _read(dp).get("segments", []) if dp.is_file() else []
        typed = [r for r in dec if r.get("margin") is not None]
        if typed:
            low = [r for r in typed if r.get("low_margin")]
            s += (f"; {len(low)} of {len(typed)} typed fronts decided with a low margin (the report lists them), "
                  f"smallest margin {min(r['margin'] for r in typed):.2f}")
        return s

    row("articulation (simulated detections whose failures persist across views, generic labels; decision weights "
        "fitted on the benchmark's train split)", art,
        "[docs/perception.md](docs/perception.md)")

    def twin() -> str:
        c, t = run.metrics("complete"), run.metrics("twin")
        n_fail = t.get("n_check_failures", 0)
        checks = ("the physical checks did not run (twin.check: false)" if not sp.file("twin", "checks").is_file()
                  else "every physical check passes on this scene (the file loads passive: a person's pull opens "
                  "each part; the benchmark kitchens' twins are not built by the pipeline)" if not n_fail
                  else f"{n_fail} physical check(s) fail on {t.get('n_parts_failing_checks')} part(s), reported in "
                  f"the twin's {sp.file('twin', 'checks').name} (the twin is written all the same)")
        return (f"{c['wall_s']:.0f} s + {t['wall_s']:.0f} s; {checks}; {t['sim_sim_steps_per_s']:.0f} steps/s; "
                f"closed PSNR {t['closed_psnr']:.2f} dB, "
                f"opened at half range {t['open_psnr']:.2f} dB (part region {t['open_region_psnr']:.2f}); interior "
                f"depth error {100 * c['interior_depth_error']:.1f} cm (DRAWER's rule "
                f"{100 * c['interior_depth_error_drawer_rule']:.1f} cm)")

    row("the twin (`complete` + `twin`)", twin, "[docs/twin.md](docs/twin.md)")

    def sim() -> str:
        e, s = run.metrics("evaluate"), run.metrics("simulate")
        return (f"motion EMD {_f(e.get('emd'), '.2e')} over {e.get('n_emd', 0)} parts (the paper "
                f"{PAPER['motion_emd']:.2e}); cups ride along in {s['cup_rides_along_passed']}/{s['cup_rides_along_n']} "
                f"closing drawers, {s['pull_handle_passed']}/{s['pull_handle_n']} parts pulled open at ≤ "
                f"{s['pull_handle_peak_force_max_n']:.1f} N, a dropped block rests on the counter: "
                f"{s['drop_on_counter_passed']}/{s['drop_on_counter_n']}")

    row("the simulated twin (`simulate`, `evaluate`)", sim, "[docs/twin.md](docs/twin.md)")

    def robot() -> str:
        m = run.metrics("robot")
        n = m["robot_parts"]
        kinds = sorted({k.removeprefix("robot_").removesuffix("_n") for k in m if k.startswith("robot_")
                        and k.endswith("_n") and f"{k[:-2]}_opened" in m})
        per = ", ".join(f"{k} {m[f'robot_{k}_opened']}/{m[f'robot_{k}_n']}" for k in kinds)
        s = (f"a Panda opened {round(m['robot_open_success'] * n)}/{n} parts and closed "
             f"{round(m['robot_close_success'] * n)}/{n} in the twin as it loads ({per})")
        if "robot_transfer_success" in m:
            fails = ", ".join(f"{k.removeprefix('robot_transfer_fail_').replace('_', ' ')} {v}" for k, v in m.items()
                              if k.startswith("robot_transfer_fail_"))
            s += (f"; replayed in the scene's own kitchen, {round(m['robot_transfer_success'] * n)}/{n} opened "
                  f"({fails or 'no failure'})")
        k = m.get("robot_pick_place_n", 0)
        if k:
            s += f"; a block from the counter placed in an opened drawer {round(m['robot_pick_place_success'] * k)}/{k}"
            if "robot_pick_place_transfer_success" in m:
                s += f" ({round(m['robot_pick_place_transfer_success'] * k)}/{k} after transfer)"
        return s + (f"; {m.get('dataset_episodes', 0)} LeRobot episodes, {m.get('dataset_frames', 0)} frames, "
                    f"{m.get('dataset_bytes', 0) / 1e6:.1f} MB; {m['wall_s']:.0f} s")

    row("the robot (`robot`)", robot, "[docs/twin.md](docs/twin.md#the-robot-stage)")

    def stab() -> str:
        m, c = run.metrics("stability"), _read(sp.file("stability", "choice"))
        return (f"{m['n_cells']} cells ({m['n_cells_diverged']} diverged): {c['integrator']} at {1000 * c['timestep']:g} ms "
                f"keeps every part within {1000 * c['nominal_error']:.2f} mm of the reference (real-time factor "
                f"{c['realtime_factor']:.1f}); {m['n_extremes_outside']} extreme cases need the remedies it lists")

    row("the stability study (`stability`)", stab, "[docs/twin.md](docs/twin.md)")

    def bench(split: str) -> Callable[[], str]:
        def fn() -> str:
            m = _read(BenchPaths(run.bench).eval(split) / LAYOUT["metrics"])
            return (f"{m['fitted_n_kitchens']} kitchens: precision {_f(m.get('precision'))}, recall {_f(m.get('recall'))}, "
                    f"EA-score {_f(m.get('ea_score'))} pooled; per kitchen: precision {_spread(m, 'precision')}, recall "
                    f"{_spread(m, 'recall')}, EA {_spread(m, 'ea_score')}; the hand-set prior weights: precision "
                    f"{_f(m.get('prior_precision'))}, recall {_f(m.get('prior_recall'))}, EA "
                    f"{_f(m.get('prior_ea_score'))}; motion EMD (each prediction moved by its own joint) "
                    f"{_f(m.get('emd'), '.2e')} pooled, worst kitchen {_f(m.get('fitted_emd_worst'), '.2e')}")
        return fn

    row("articulation benchmark, test split (never tuned on; simulated generic detections whose failures persist "
        "across views, TSDF meshes)", bench("test"),
        "[docs/perception.md](docs/perception.md)")
    row("articulation benchmark, train split (the decision weights are fitted on it)", bench("train"),
        "[docs/perception.md](docs/perception.md)")
    row("articulation benchmark, hand split (kitchens written by hand in combinations neither split draws; never "
        "tuned on; the same sensors)", bench("hand"), "[docs/perception.md](docs/perception.md)")

    def fit() -> str:
        m = _read(BenchPaths(run.bench).fit / LAYOUT["metrics"])
        return (f"{m['n_fronts']} labelled fronts of {m['n_kitchens']} kitchens, leave-kitchens-out accuracy "
                f"{m['cv_accuracy']:.3f} (λ = {m['lambda']:g}); hand-built hard cases passed: {m['cases_passed']} of "
                f"{m['cases_total']} (`{bench_name('cases')}`)")

    row("the decision weights (`fit_decisions`)", fit, "[docs/perception.md](docs/perception.md)")

    def extremes() -> str:
        m = _read(run.reports / LAYOUT["report"]["extremes"])
        return f"{m['extremes_passed']} / {m['extremes_n']} numerical-extremes tests pass"

    row("the report (`report`, `extremes`)", extremes, "`reports/index.html`")

    def wall() -> str:
        return run_time(_read(run.root / "logs" / "repro" / SUMMARY))

    row("`make run`", wall, "[docs/speed.md](docs/speed.md)")
    return out


def run_time(s: dict) -> str:
    """The ``make run`` row from the scheduler's ``summary.json``: a run that reran only part of
    the pipeline says so (its time is not the pipeline's)."""
    scratch = s["force"] or s["n_stages"] >= s["n_stages_total"]
    what = (f"from scratch, {s['n_stages']} stages" if scratch
            else f"{s['n_stages']} of {s['n_stages_total']} stages rerun, the rest from DVC's cache")
    threads = f"{s['threads']} thread{'' if s['threads'] == 1 else 's'} each"
    return (f"{s['wall_s'] / 60:.1f} min ({what}, {s['jobs']} at a time, {threads}); stage walls sum to "
            f"{s['stage_wall_s'] / 60:.1f} min")


def results_block(run: Run, variants: list[str], geometry_variants: list[str],
                  seeds: list[tuple[int, Run]] | None = None, seed0: int = 0) -> str:
    """The README block: provenance, what was simulated, the table (with the spread over the
    ``seeds`` experiments of the default scene's main figures, when there are any)."""
    spread = (f"the default scene's main figures show their range over seeds {seed0} to {max(s for s, _ in seeds)} "
              f"(`dvc exp run -S seed=<s>`, the rest of the table is seed {seed0})" if seeds
              else "figures of the default scene are one seed")
    head = (f"Measured by one `make run` on {provenance(run.root)}. The default scene is procedural: its depth, "
            "monocular priors and 2D detections are **simulated from the renders** (generic labels; misses, merges "
            "and false masks that persist across views as well as per-frame ones), as are the benchmark kitchens'. "
            f"One machine; {spread}; a benchmark figure over many kitchens shows its spread across them (mean ± sd, worst "
            "kitchen).\n\n")
    table = seed_spread(rows(run, variants, geometry_variants), run, seeds or [], seed0)
    return head + md_table(["result", "figures", "details"], table)


def replace_block(readme: str, block: str) -> str:
    """``readme`` with the text between the results markers replaced by ``block``."""
    if BEGIN not in readme or END not in readme:
        raise ValueError(f"README: no results block (the lines {BEGIN!r} and {END!r})")
    a, rest = readme.split(BEGIN, 1)
    _, b = rest.split(END, 1)
    return f"{a}{BEGIN}\n{block.rstrip()}\n{END}{b}"
