"""Error against run time, swept: Hydra multiruns of the ``sdf`` and ``appearance`` stage apps
over iteration budget x resolution x variant on a launcher (``conf/hydra/launcher/``), and the
Pareto fronts of their error against wall time (the ``pareto@<scene>`` stage).

"Resolution" is what sets each method's cost:

- neural SDF: the hash grid's finest cell (``sdf.neural.encoding.cell_fine``), since a step's
  cost is set by its rays (``sampling.*``), not by the image size;
- TSDF: its voxel (``sdf.tsdf.voxel``; no iterations);
- appearance: the training images (``appearance.train_scale``: box-filtered by that factor;
  the test views stay full size, so every point is scored on the same pixels).

Errors: the SDF's Chamfer-L1 of its quick mesh (``quick_chamfer_l1``, m, against the GT mesh;
lower is better) and the appearance's test PSNR (dB, higher is better). Cost: each job's
``wall_s`` (the whole stage: loading, training, evaluation), with the threads the launcher
gives a job (joblib: cores // n_jobs, :class:`drawer_lib.report.sweep.CapThreads`).
"""

import io
import json
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

from drawer_lib.errors import ConfigError, InputError
from drawer_lib.report.markdown import md_table
from drawer_lib.report.sweep import collect_sweep

DIR = "pareto"  # the stage's folder: out/<scene>/pareto/
JOBS = "jobs"  # the multiruns' job folders, inside it while the stage runs


def _positive(name: str, values, integer: bool = False) -> tuple:
    vals = tuple(values)
    for v in vals:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0 or (integer and int(v) != v):
            raise ConfigError(f"pareto.{name} = {list(vals)}: every value must be a positive "
                              f"{'integer' if integer else 'number'}")
    return vals


@dataclass(frozen=True)
class NeuralGrid:
    """The neural SDF's axes: ``steps`` (the schedule's length) x ``cell_fine`` (m)."""

    steps: list[int] = field(default_factory=lambda: [325, 650, 1300])
    cell_fine: list[float] = field(default_factory=lambda: [0.03, 0.015])

    def __post_init__(self):
        _positive("neural.steps", self.steps, integer=True)
        _positive("neural.cell_fine", self.cell_fine)


@dataclass(frozen=True)
class TsdfGrid:
    voxel: list[float] = field(default_factory=lambda: [0.04, 0.02, 0.01])  # m

    def __post_init__(self):
        _positive("tsdf.voxel", self.voxel)


@dataclass(frozen=True)
class AppearanceGrid:
    """``variants`` (conf/appearance_variant/) x ``steps`` x ``train_scale``."""

    variants: list[str] = field(default_factory=lambda: ["static_gs", "movable_gs_ste"])
    steps: list[int] = field(default_factory=lambda: [375, 750, 1500])
    train_scale: list[int] = field(default_factory=lambda: [2, 1])

    def __post_init__(self):
        from drawer_lib.splat.config import VARIANTS

        bad = [v for v in self.variants if v not in VARIANTS or v == "textured_mesh"]
        if bad:
            raise ConfigError(f"pareto.appearance.variants: {bad} are not trained variants of {VARIANTS}")
        _positive("appearance.steps", self.steps, integer=True)
        _positive("appearance.train_scale", self.train_scale, integer=True)


@dataclass(frozen=True)
class ParetoConfig:
    """``scenes``: where ``dvc repro`` runs the grid (empty: nowhere; the ``pareto`` experiment
    sets it). ``launcher``: a ``conf/hydra/launcher/`` name. ``overrides``: Hydra overrides
    every job gets (the grid's axes come after them). ``budgets_s``: the wall-time budgets
    the table answers "what should I pick?" for. An empty axis drops that family."""

    scenes: list[str] = field(default_factory=list)
    launcher: str = "local"
    budgets_s: list[float] = field(default_factory=lambda: [120.0, 600.0, 3600.0])
    overrides: list[str] = field(default_factory=list)  # extra Hydra overrides of every job
    neural: NeuralGrid = field(default_factory=NeuralGrid)
    tsdf: TsdfGrid = field(default_factory=TsdfGrid)
    appearance: AppearanceGrid = field(default_factory=AppearanceGrid)

    def __post_init__(self):
        _positive("budgets_s", self.budgets_s)


def _csv(values) -> str:
    return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in values)


def multiruns(cfg: ParetoConfig, scene: str, jobs_dir: Path, config_name: str = "dvc_stage",
              paths_out: str | None = None, python: str = sys.executable) -> dict[str, list[str]]:
    """The Hydra multirun command of each family (``neural``, ``tsdf``, ``appearance``; a family
    with an empty axis is left out): the stage app over the primary config ``config_name``
    (``dvc_stage``: ``params.yaml``), reading inputs from ``paths_out``, its jobs in
    ``jobs_dir/<family>/<overrides>/``, threads capped per job, a sweep table per family."""
    # a job folder is named by the grid's axes only (not by what every job shares)
    fixed = ["paths.out", "paths.reports", "paths.data", "scene", *(o.split("=", 1)[0].lstrip("+~") for o in cfg.overrides)]

    def base(stage: str, family: str) -> list[str]:
        return [python, "-m", f"stages.{stage}", "-cn", config_name, "-m", f"scene={scene}",
                *([f"paths.out={paths_out}"] if paths_out is not None else []),
                f"hydra/launcher={cfg.launcher}", f"hydra.sweep.dir={Path(jobs_dir) / family}",
                "hydra.sweep.subdir=${hydra.job.override_dirname}",
                f"hydra.job.config.override_dirname.exclude_keys=[{','.join(fixed)}]",
                "++hydra.callbacks.cap_threads._target_=drawer_lib.report.sweep.CapThreads",
                "++hydra.callbacks.collect_sweep._target_=drawer_lib.report.sweep.CollectSweep", *cfg.overrides]

    cmds = {}
    if cfg.neural.steps and cfg.neural.cell_fine:
        cmds["neural"] = base("sdf", "neural") + ["sdf=neural", f"sdf.neural.steps={_csv(cfg.neural.steps)}",
                                                  f"sdf.neural.encoding.cell_fine={_csv(cfg.neural.cell_fine)}"]
    if cfg.tsdf.voxel:
        cmds["tsdf"] = base("sdf", "tsdf") + ["sdf=tsdf", f"sdf.tsdf.voxel={_csv(cfg.tsdf.voxel)}"]
    a = cfg.appearance
    if a.variants and a.steps and a.train_scale:
        cmds["appearance"] = base("appearance", "appearance") + [
            f"appearance_variant={_csv(a.variants)}", f"appearance.steps={_csv(a.steps)}",
            f"appearance.train_scale={_csv(a.train_scale)}"]
    return cmds


@dataclass(frozen=True)
class Point:
    """One job: its family (``geometry`` | ``appearance``), variant, iteration budget (None for
    the TSDF), resolution (cell / voxel in m, or the train-image factor), wall time (s) and error
    (Chamfer-L1 in mm, or test PSNR in dB), plus secondary figures."""

    family: str
    variant: str
    steps: int | None
    resolution: float
    wall_s: float
    error: float
    extra: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        res = f"x{self.resolution:g}" if self.family == "appearance" else f"{1000 * self.resolution:g} mm"
        return f"{self.variant} {'' if self.steps is None else f'{self.steps} steps, '}{res}"


LOWER_IS_BETTER = {"geometry": True, "appearance": False}
ERROR_NAME = {"geometry": "Chamfer-L1 (mm)", "appearance": "test PSNR (dB)"}


def sweep_rows(jobs_dir: Path) -> dict[str, list[dict]]:
    """Each family folder under ``jobs_dir`` -> its jobs' rows (:func:`collect_sweep`)."""
    return {d.name: collect_sweep(d) for d in sorted(Path(jobs_dir).iterdir()) if d.is_dir()}


def points(rows: dict[str, list[dict]], scene: str) -> list[Point]:
    """Every finished job of :func:`sweep_rows` as a :class:`Point` (a job without the metrics
    it needs is left out)."""
    pts = []
    for fam, fam_rows in rows.items():
        for row in fam_rows:
            o, m = row["overrides"], row["metrics"]
            if fam in ("neural", "tsdf"):
                key = f"{scene}/sdf:"
                if key + "quick_chamfer_l1" not in m:
                    continue
                res = float(o.get("sdf.neural.encoding.cell_fine" if fam == "neural" else "sdf.tsdf.voxel"))
                pts.append(Point("geometry", fam, int(o["sdf.neural.steps"]) if fam == "neural" else None, res,
                                 float(m[key + "wall_s"]), 1000 * float(m[key + "quick_chamfer_l1"]),
                                 {"fscore_2cm": m.get(key + "quick_fscore_2cm"), "train_s": m.get(key + "train_s")}))
            else:
                v = o["appearance_variant"]
                key = f"{scene}/appearance/{v}:"
                if key + "psnr" not in m:
                    continue
                pts.append(Point("appearance", v, int(o["appearance.steps"]), float(o["appearance.train_scale"]),
                                 float(m[key + "wall_s"]), float(m[key + "psnr"]),
                                 {"ssim": m.get(key + "ssim"), "lpips": m.get(key + "lpips"),
                                  "train_s": m.get(key + "train_s"), "n_gaussians": m.get(key + "n_gaussians")}))
    return pts


def pareto_front(pts: list[Point], lower_is_better: bool) -> list[Point]:
    """The points no other point beats on both wall time and error (ties on both: the first),
    by increasing wall time. O(n log n): sorted by time, a point is on the front when its error
    is strictly better than every cheaper point's."""
    sign = 1.0 if lower_is_better else -1.0
    front, best = [], float("inf")
    for p in sorted(pts, key=lambda p: (p.wall_s, sign * p.error)):
        if sign * p.error < best:
            front.append(p)
            best = sign * p.error
    return front


def pick(front: list[Point], budget_s: float) -> Point | None:
    """The best point of a front that fits in ``budget_s`` (None: none does). On a front, error
    improves with time, so that is the most expensive point within the budget."""
    fit = [p for p in front if p.wall_s <= budget_s]
    return fit[-1] if fit else None


def table_md(pts: list[Point], budgets_s: list[float]) -> tuple[str, dict]:
    """(markdown: every point, marked when on its family's front, then the pick per budget;
    metrics: the picks)."""
    out = io.StringIO()
    metrics: dict = {"n_points": len(pts)}
    for fam in ("geometry", "appearance"):
        fp = [p for p in pts if p.family == fam]
        if not fp:
            continue
        front = pareto_front(fp, LOWER_IS_BETTER[fam])
        on = {id(p) for p in front}
        out.write(f"### {fam}: {ERROR_NAME[fam]} against wall time\n\n")
        out.write(md_table(["setting", "wall (s)", ERROR_NAME[fam], "secondary", "Pareto"],
                           ([p.label, f"{p.wall_s:.1f}", f"{p.error:.3f}",
                             ", ".join(f"{k} {v:.4g}" for k, v in p.extra.items() if isinstance(v, (int, float))),
                             "**yes**" if id(p) in on else ""] for p in sorted(fp, key=lambda p: p.wall_s))))
        picks = [(b, pick(front, b)) for b in budgets_s]
        out.write("\n" + md_table(["budget", f"pick ({fam})", "wall (s)", ERROR_NAME[fam]],
                                  ([f"{b:g} s", p.label if p else "nothing fits", _n(p and p.wall_s), _n(p and p.error)]
                                   for b, p in picks)))
        for b, p in picks:
            metrics[f"{fam}_pick_{b:g}s_error"] = None if p is None else round(p.error, 4)
            metrics[f"{fam}_pick_{b:g}s_wall_s"] = None if p is None else round(p.wall_s, 2)
        metrics[f"{fam}_front_size"] = len(front)
        out.write("\n")
    return out.getvalue(), metrics


def _n(v) -> str:
    return "–" if v is None else f"{v:.3g}" if abs(v) < 100 else f"{v:.1f}"


def plot(pts: list[Point], budgets_s: list[float], path: Path) -> None:
    """Error against wall time, one panel per family: every job (marker: variant; label:
    steps / resolution), the front as a step line, the budgets as dashed lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fams = [f for f in ("geometry", "appearance") if any(p.family == f for p in pts)]
    fig, axs = plt.subplots(1, max(len(fams), 1), figsize=(6.2 * max(len(fams), 1), 4.4), squeeze=False)
    markers = "osD^v<>"
    for ax, fam in zip(axs[0], fams):
        fp = [p for p in pts if p.family == fam]
        for i, v in enumerate(dict.fromkeys(p.variant for p in fp)):
            vp = [p for p in fp if p.variant == v]
            ax.scatter([p.wall_s for p in vp], [p.error for p in vp], marker=markers[i % len(markers)], s=40,
                       label=v, alpha=0.85)
            for p in vp:
                ax.annotate(f"{'' if p.steps is None else p.steps}"
                            f"{'' if p.steps is None else '/'}{p.resolution:g}", (p.wall_s, p.error),
                            fontsize=6, xytext=(3, 3), textcoords="offset points")
        front = pareto_front(fp, LOWER_IS_BETTER[fam])
        ax.step([p.wall_s for p in front], [p.error for p in front], where="post", c="k", lw=1, label="Pareto front")
        for b in budgets_s:
            ax.axvline(b, c="grey", ls="--", lw=0.7)
            ax.text(b, 1.0, f" {b / 60:g} min", transform=ax.get_xaxis_transform(), fontsize=7, va="top")
        ax.set(xscale="log", xlabel="wall time of the job (s, log)", ylabel=ERROR_NAME[fam],
               title=f"{fam}: labels steps/resolution")
        if LOWER_IS_BETTER[fam]:
            ax.set_yscale("log")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_grid(cfg: ParetoConfig, scene: str, out_dir: Path, config_name: str = "dvc_stage",
             paths_out: str | None = None, log=print) -> dict:
    """The ``pareto`` stage: run each family's multirun into ``out_dir/jobs/`` (removed at the
    end: the jobs' models and renders are not kept), then write ``table.md``, ``table.json``
    (every job's overrides and metrics, every point and front) and ``curves.png`` into
    ``out_dir``; returns the metrics (the pick per budget). A failed multirun raises with its
    last lines."""
    import shutil

    from drawer_lib.paths import LAYOUT

    jobs = Path(out_dir) / JOBS
    for fam, cmd in multiruns(cfg, scene, jobs, config_name, paths_out).items():
        log(f"{fam}: {' '.join(cmd[1:])}")
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise InputError(f"pareto: the {fam} multirun failed (exit {r.returncode}):\n{r.stderr[-3000:]}")
    rows = sweep_rows(jobs)
    pts = points(rows, scene)
    if not pts:
        raise InputError(f"pareto: no job under {jobs} wrote the metrics it needs")
    md, metrics = table_md(pts, cfg.budgets_s)
    rep = LAYOUT["report"]
    (Path(out_dir) / rep["table"]).write_text(f"# Error against wall time, {scene}\n\n{md}")
    fronts = {f: [asdict(p) for p in pareto_front([p for p in pts if p.family == f], LOWER_IS_BETTER[f])]
              for f in LOWER_IS_BETTER}
    (Path(out_dir) / rep["table_json"]).write_text(json.dumps({"points": [asdict(p) for p in pts], "fronts": fronts,
                                                               "jobs": rows, "config": asdict(cfg)}, indent=1))
    plot(pts, cfg.budgets_s, Path(out_dir) / rep["plot"])
    shutil.rmtree(jobs)
    return metrics
