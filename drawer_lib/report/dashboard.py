"""The report: every tracked metric of the last ``dvc repro`` in one self-contained offline page
(``reports/index.html``: static figures inlined as data URIs, no script, no network) and one
markdown file (``reports/summary.md``).

Sections (each an ``<section id=...>`` the browser test looks for): ``headline``; ``geometry``
(Chamfer / F-score per config); ``appearance`` (the paper's Tab. 3 ablation); ``articulation``
(Tab. 4: precision / recall / EA-score); ``motion`` (Tab. 5: motion EMD, and the simulation's
own figures and interaction probes); ``opened`` (opened-state NVS); ``stability`` (heat map,
choice, the extremes it does not handle); ``time`` (every iterative stage's error against wall
time: SDF Chamfer, appearance PSNR, the stability matrix; and the swept grid's Pareto fronts
with the best setting per budget, when the ``pareto`` stage ran); ``stages`` (per-stage wall time and
peak memory); ``extremes`` (the numerical-extremes tests, run by the ``extremes`` stage); ``skipped`` (everything
skipped, with its reason).

:func:`collect` reads ``out/`` and ``reports/``; :func:`render` turns that into (html, md).
Missing inputs are reported as skips, never as zeros.
"""

import base64
import html
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drawer_lib.paths import LAYOUT, ScenePaths
from drawer_lib.report.geometry_table import read_curve
from drawer_lib.report.markdown import md_table
from drawer_lib.report.paper import PAPER
from drawer_lib.report.pareto import DIR as PARETO_DIR

SCENE_STAGES = ("capture", "sdf", "mesh", "decompose", "articulate", "evaluate", "complete", "twin", "stability",
                "simulate", "robot")
SECTIONS = (("headline", "Headline"), ("geometry", "Geometry"), ("appearance", "Appearance ablation (Tab. 3)"),
            ("articulation", "Articulation (Tab. 4)"), ("motion", "Motion and simulation (Tab. 5)"),
            ("opened", "Opened-state novel views"), ("stability", "Stability study"),
            ("time", "Error against run time"), ("stages", "Per-stage wall time and memory"),
            ("extremes", "Numerical extremes"), ("skipped", "Skipped"))


def _json(p: Path) -> dict | None:
    try:
        return json.loads(Path(p).read_text()) if Path(p).is_file() else None
    except ValueError:
        return None


@dataclass
class SceneData:
    name: str
    metrics: dict[str, dict]  # stage (or "sdf:<v>", "mesh:<v>", "appearance:<v>") -> metrics.json
    curves: dict[str, list[dict]]  # "sdf", "sdf:<v>", "appearance:<v>" -> curve rows
    stability_rows: list[dict]
    choice: dict | None
    heatmap: Path | None
    sheet: Path | None
    pareto: dict | None = None  # out/<scene>/pareto/table.json (the `pareto` experiment)
    pareto_plot: Path | None = None
    decisions: list[dict] = field(default_factory=list)  # articulate/decisions.json rows of typed fronts


@dataclass
class ReportData:
    scenes: list[SceneData]
    geometry: dict | None
    ablation: dict | None
    extremes: list[dict] | None
    skipped: list[tuple[str, str, str]] = field(default_factory=list)  # (where, what, why)


def collect(out: Path, reports: Path, scenes: list[str], geometry_variants: list[str],
            appearance_variants: list[str], extremes: list[dict] | None, extremes_skip: str | None = None
            ) -> ReportData:
    """Everything the report shows (module doc)."""
    from drawer_lib.stability.pipeline import read_matrix

    data = ReportData([], _json(Path(reports) / "geometry" / LAYOUT["report"]["table_json"]),
                      _json(Path(reports) / "ablation" / LAYOUT["report"]["table_json"]), extremes)
    if extremes_skip:
        data.skipped.append(("report", "numerical extremes", extremes_skip))
    for s in scenes:
        sp = ScenePaths(Path(out), s)
        mets, curves = {}, {}
        for st in SCENE_STAGES:
            m = _json(sp.metrics(st))
            if m is None:
                data.skipped.append((s, st, "no metrics.json: the stage has not run"))
            else:
                mets[st] = m
        curves["sdf"] = read_curve(sp.stage_dir("sdf") / LAYOUT["curve"])
        for v in geometry_variants:
            vp = ScenePaths(Path(out), s, v)
            for st in ("sdf", "mesh"):
                m = _json(vp.metrics(st))
                if m is not None:
                    mets[f"{st}:{v}"] = m
            curves[f"sdf:{v}"] = read_curve(vp.stage_dir("sdf") / LAYOUT["curve"])
        for v in appearance_variants:
            d = sp.appearance_dir(v)
            m = _json(d / LAYOUT["metrics"])
            if m is not None:
                mets[f"appearance:{v}"] = m
                curves[f"appearance:{v}"] = read_curve(d / LAYOUT["curve"])
        for key, m in mets.items():
            for what, why in (m.get("skipped") or {}).items():
                data.skipped.append((s, f"{key}: {what}", why))
        mpath = sp.file("stability", "matrix")
        rows = read_matrix(mpath) if mpath.is_file() else []
        hm = sp.file("stability", "heatmap")
        sheet = sp.file("twin", "contact_sheet")
        pdir = sp.root / PARETO_DIR
        pplot = pdir / LAYOUT["report"]["plot"]
        dec = _json(sp.file("articulate", "decisions")) or {}
        typed = [r for r in dec.get("segments", []) if "margin" in r]
        data.scenes.append(SceneData(s, mets, curves, rows, _json(sp.file("stability", "choice")),
                                     hm if hm.is_file() else None, sheet if sheet.is_file() else None,
                                     _json(pdir / LAYOUT["report"]["table_json"]), pplot if pplot.is_file() else None,
                                     typed))
    return data


# ---------------------------------------------------------------- formatting


def _f(v, fmt: str = ".3g", scale: float = 1.0) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        return str(int(round(v * scale))) if fmt == "d" else format(v * scale, fmt)
    return str(v)


@dataclass
class Table:
    head: list[str]
    rows: list[list[str]]

    def md(self) -> str:
        return md_table(self.head, self.rows) if self.rows else "_nothing to show_\n"

    def html(self) -> str:
        if not self.rows:
            return "<p><em>nothing to show</em></p>"
        h = "".join(f"<th>{html.escape(c)}</th>" for c in self.head)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in self.rows)
        return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def _png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode()


def _file_png(path: Path, max_width: int = 1100) -> bytes:
    from PIL import Image

    im = Image.open(path)
    if im.width > max_width:
        im = im.resize((max_width, round(im.height * max_width / im.width)))
    buf = io.BytesIO()
    im.save(buf, "PNG", optimize=True)
    return buf.getvalue()


def _fig_bytes(fig) -> bytes:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return buf.getvalue()


def _mpl():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def time_figure(data: ReportData) -> bytes | None:
    """Error against wall time: SDF Chamfer (per config), appearance test PSNR (per variant),
    the stability matrix (the twin's worst part: error against wall per simulated second)."""
    plt = _mpl()
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.2))
    drawn = False
    for sc in data.scenes:
        for key, rows in sc.curves.items():
            if not rows:
                continue
            t = [r["wall_s"] for r in rows]
            if key.startswith("sdf") and "chamfer_l1" in rows[0]:
                axs[0].plot(t, [1000 * r["chamfer_l1"] for r in rows], marker=".", label=f"{sc.name} {key}")
                drawn = True
            elif key.startswith("appearance") and "test_psnr" in rows[0]:
                axs[1].plot(t, [r["test_psnr"] for r in rows], marker=".", label=f"{sc.name} {key.split(':')[1]}")
                drawn = True
        nominal = [r for r in sc.stability_rows if r["group"] == "nominal"]
        for integ in dict.fromkeys(r["integrator"] for r in nominal):
            pts = {}
            for r in nominal:
                if r["integrator"] == integ:
                    worst = math.inf if r["diverged"] else r["error"]
                    e, w = pts.get(r["timestep"], (0.0, r["wall_per_sim_s"]))
                    pts[r["timestep"]] = (max(e, worst), w)
            xs = [pts[k][1] for k in sorted(pts)]
            ys = [pts[k][0] for k in sorted(pts)]
            ok = [i for i, y in enumerate(ys) if math.isfinite(y)]
            axs[2].plot([xs[i] for i in ok], [ys[i] for i in ok], marker="o", label=f"{sc.name} {integ}")
            drawn = True
        if sc.choice:
            axs[2].axhline(sc.choice["tolerance"], c="k", ls="--", lw=0.8)
    axs[0].set(xlabel="wall time (s)", ylabel="Chamfer-L1 (mm)", yscale="log", title="SDF geometry")
    axs[1].set(xlabel="wall time (s)", ylabel="test PSNR (dB)", title="appearance")
    axs[2].set(xlabel="wall s per simulated s", ylabel="worst part error (m)", xscale="log", yscale="log",
               title="stability: the twin's parts (dashed: tolerance)")
    for ax in axs:
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return _fig_bytes(fig) if drawn else None


def stages_figure(data: ReportData) -> bytes | None:
    plt = _mpl()
    rows = [(f"{sc.name}/{k}", m.get("wall_s"), m.get("peak_rss_mb")) for sc in data.scenes
            for k, m in sc.metrics.items() if isinstance(m.get("wall_s"), (int, float))]
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(9, 0.24 * len(rows) + 1.2))
    y = np.arange(len(rows))
    ax.barh(y, [r[1] for r in rows], color="tab:blue")
    for i, r in enumerate(rows):
        ax.text(r[1], i, f" {r[1]:.1f} s, {_f(r[2], '.0f')} MiB", va="center", fontsize=7)
    ax.set_yticks(y, [r[0] for r in rows], fontsize=7)
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlabel("wall time of the last run (s, log)")
    fig.tight_layout()
    return _fig_bytes(fig)


# ---------------------------------------------------------------- sections


def _geometry(data: ReportData) -> Table:
    t = Table(["scene", "config", "Chamfer-L1 (mm)", "F@1cm", "F@2cm", "normal consistency", "SDF wall (s)",
               "mesh wall (s)"], [])
    for s, cfgs in (data.geometry or {}).items():
        for name, m in cfgs.items():
            t.rows.append([s, name, _f(m.get("chamfer_l1"), ".2f", 1000), _f(m.get("fscore_1cm"), ".3f"),
                           _f(m.get("fscore_2cm"), ".3f"), _f(m.get("normal_consistency"), ".3f"),
                           _f(m.get("sdf_wall_s"), ".1f"), _f(m.get("mesh_wall_s"), ".1f")])
    return t


def _appearance(data: ReportData) -> Table:
    t = Table(["scene", "variant", "PSNR", "SSIM", "LPIPS", "Gaussians", "training (s)", "paper PSNR / SSIM / LPIPS"],
              [])
    for s, vs in (data.ablation or {}).items():
        for v, m in vs.items():
            paper = " / ".join(f"{x:g}" for x in PAPER["appearance"][v]) if v in PAPER["appearance"] else "–"
            t.rows.append([s, v, _f(m.get("psnr"), ".2f"), _f(m.get("ssim"), ".3f"), _f(m.get("lpips"), ".3f"),
                           _f(m.get("n_gaussians"), "d") if m.get("n_gaussians") is not None else "–",
                           _f(m.get("train_s"), ".1f"), paper])
    return t


def _articulation(data: ReportData) -> Table:
    t = Table(["scene", "predicted", "GT", "correct", "precision", "recall", "EA-score", "rigid P / R", "paper P / R"],
              [])
    for sc in data.scenes:
        m = sc.metrics.get("evaluate")
        if m is None:
            continue
        t.rows.append([sc.name, _f(m.get("n_pred"), "d"), _f(m.get("n_gt"), "d"), _f(m.get("n_correct"), "d"),
                       _f(m.get("precision"), ".3f"), _f(m.get("recall"), ".3f"), _f(m.get("ea_score"), ".3f"),
                       f"{_f(m.get('rigid_precision'), '.2f')} / {_f(m.get('rigid_recall'), '.2f')}",
                       f"{PAPER['articulation']['precision']:.3f} / {PAPER['articulation']['recall']:.3f}"])
    return t


def _low_margin(data: ReportData) -> Table:
    """Every typed front whose decision margin is below ``articulate.types.low_margin``: the
    decisions a small change of the evidence may flip (docs/formats.md, decisions.json)."""
    t = Table(["scene", "segment", "part", "decided", "runner-up", "margin (log-odds)", "confidence", "handle",
               "near a bound"], [])
    for sc in data.scenes:
        for r in sorted((r for r in sc.decisions if r.get("low_margin")), key=lambda r: r.get("margin") or 0.0):
            kind = r["family"] + (f" ({r['hinge']})" if r.get("hinge") else "")
            h = r.get("handle")
            t.rows.append([sc.name, str(r["segment"]), r.get("part") or "– (fixed)", kind, r.get("runner_up") or "–",
                           _f(r["margin"], ".2f"), _f(r.get("confidence"), ".2f"),
                           "none" if h is None else f"{h['orientation']} at ({h['a_u']:.2f}, {h['a_v']:.2f})",
                           near_steps(r)])
    return t


NEAR_STEPS = (("near_segment", "the segment's selection"), ("near_cuts", "a cut"),
              ("near_handle", "a second pull"), ("near_colour", "the pull read off its colours"),
              ("near_track", "the track test"), ("near_mesh", "the mesh moved by its last bits"),
              ("glazed_near", "the glazed rules"))


def near_steps(row: dict) -> str:
    """The steps before the type's score that a ``decisions.json`` row was decided near a bound at
    (docs/formats.md); "–" when only the score's margin is low.

    >>> near_steps({"near_cuts": [{"cut": "gap_line"}], "pair": {"near": True}})
    'a cut, the pair of doors'
    """
    out = [label for key, label in NEAR_STEPS if row.get(key)]
    return ", ".join(out + (["the pair of doors"] if (row.get("pair") or {}).get("near") else [])) or "–"


def _robot(data: ReportData) -> Table:
    t = Table(["scene", "opened in the twin", "closed in the twin", "opened after transfer", "failures after transfer",
               "block placed in a drawer (twin / transfer)", "episodes, frames", "wall s"], [])
    for sc in data.scenes:
        m = sc.metrics.get("robot")
        if not m or not m.get("robot_parts"):
            continue
        n = m["robot_parts"]
        fails = ", ".join(f"{k.removeprefix('robot_transfer_fail_').replace('_', ' ')} {v}" for k, v in m.items()
                          if k.startswith("robot_transfer_fail_"))
        tr = f"{round(m['robot_transfer_success'] * n)}/{n}" if "robot_transfer_success" in m else "–"
        k = m.get("robot_pick_place_n", 0)
        pick = "–" if not k else f"{round(m['robot_pick_place_success'] * k)}/{k} / " + (
            f"{round(m['robot_pick_place_transfer_success'] * k)}/{k}" if "robot_pick_place_transfer_success" in m else "–")
        t.rows.append([sc.name, f"{round(m['robot_open_success'] * n)}/{n}", f"{round(m['robot_close_success'] * n)}/{n}",
                       tr, fails or "–", pick, f"{m.get('dataset_episodes', 0)}, {m.get('dataset_frames', 0)}",
                       _f(m.get("wall_s"), ".0f")])
    return t


def _motion(data: ReportData) -> tuple[Table, Table]:
    t = Table(["scene", "motion EMD (mean)", "worst part", "parts scored", "paper EMD", "kinematic deviation (mm)",
               "integrator, timestep", "real-time factor"], [])
    p = Table(["scene", "cup rides along", "pull handle (peak N)", "drop on counter (rest gap mm)",
               "parts not opened", "diverged"], [])
    for sc in data.scenes:
        ev, sm = sc.metrics.get("evaluate") or {}, sc.metrics.get("simulate")
        if sm is None:
            continue
        t.rows.append([sc.name, _f(ev.get("emd"), ".3g"), _f(ev.get("emd_max"), ".3g"), _f(ev.get("n_emd"), "d")
                       if ev.get("n_emd") is not None else "–", f"{PAPER['motion_emd']:g}",
                       _f(sm.get("kinematic_dev_max_m"), ".2f", 1000),
                       f"{sm.get('integrator')}, {_f(sm.get('timestep'), 'g')} s", _f(sm.get("realtime_factor"), ".1f")])

        def probe(name, key, fmt, scale=1.0):
            if f"{name}_n" not in sm:
                return "–"
            return f"{sm[f'{name}_passed']}/{sm[f'{name}_n']} ({_f(sm.get(f'{name}_{key}'), fmt, scale)})"

        p.rows.append([sc.name, probe("cup_rides_along", "error_max_m", ".1f", 1000) + " mm",
                       probe("pull_handle", "peak_force_max_n", ".1f"),
                       probe("drop_on_counter", "rest_gap_max_m", ".1f", 1000), _f(sm.get("n_parts_not_opened"), "d")
                       if sm.get("n_parts_not_opened") is not None else "–",
                       _f(sm.get("n_parts_diverged"), "d") if sm.get("n_parts_diverged") is not None else "–"])
    return t, p


def _opened(data: ReportData) -> Table:
    t = Table(["scene", "closed PSNR / SSIM / LPIPS", "opened PSNR / SSIM / LPIPS", "opened part-region PSNR",
               "parts scored"], [])
    for sc in data.scenes:
        m = sc.metrics.get("twin")
        if m is None:
            continue
        t.rows.append([sc.name, f"{_f(m.get('closed_psnr'), '.2f')} / {_f(m.get('closed_ssim'), '.3f')} / "
                       f"{_f(m.get('closed_lpips'), '.3f')}",
                       f"{_f(m.get('open_psnr'), '.2f')} / {_f(m.get('open_ssim'), '.3f')} / "
                       f"{_f(m.get('open_lpips'), '.3f')}", _f(m.get("open_region_psnr"), ".2f"),
                       _f(m.get("n_parts_scored_open"), "d") if m.get("n_parts_scored_open") is not None else "–"])
    return t


def _stability(sc: SceneData) -> tuple[str, Table]:
    ch = sc.choice
    if ch is None:
        return f"{sc.name}: the stability stage has not run.", Table([], [])
    d = ch["twin_default"]
    text = (f"{sc.name}: chosen {ch['integrator']} at {ch['timestep']:g} s ({ch['source']}); the twin's parts stay "
            f"within {_f(ch.get('nominal_error'), '.3g')} m of the RK4 1e-5 s reference (tolerance "
            f"{ch['tolerance']:g} m); full twin real-time factor {ch['realtime_factor']:.1f} "
            f"(the twin config's {d['integrator']} at {d['timestep']:g} s: {d['realtime_factor']:.1f}; "
            f"{'agrees' if ch['agrees_with_twin_default'] else 'differs'}).")
    t = Table(["extreme case", "what", "at the choice", "largest stable timestep there", "armature that fixes it",
               "damping that fixes it"], [])
    for o in ch.get("outside", []):
        r = o["remedy"]
        at = (f"diverged: {o['reason']}" if o["diverged"] else f"error {_f(o['error'], '.3g')} {o['unit']}")
        t.rows.append([o["case"], o.get("note") or "", at, _f(o.get("largest_stable_timestep"), "g"),
                       _f(r.get("armature"), "g") if r.get("armature") is not None else (r.get("note") or "none"),
                       _f(r.get("damping"), "g") if r.get("damping") is not None else "none"])
    return text, t


def _pareto(sc: SceneData) -> Table:
    """The swept grid's answer: per family and budget, the best setting that fits."""
    from drawer_lib.report.pareto import ERROR_NAME, Point, pick

    t = Table(["family", "budget", "pick", "wall (s)", "error"], [])
    cfg = sc.pareto["config"]
    for fam, front in sc.pareto["fronts"].items():
        pts = [Point(**p) for p in front]
        for b in cfg["budgets_s"]:
            p = pick(pts, b)
            t.rows.append([fam, f"{b / 60:g} min", p.label if p else "nothing fits", _f(p and p.wall_s, ".1f"),
                           f"{_f(p and p.error, '.4g')} {ERROR_NAME[fam]}"])
    return t


def _stages(data: ReportData) -> Table:
    t = Table(["scene", "stage", "wall (s)", "peak memory (MiB)", "threads"], [])
    for sc in data.scenes:
        for k, m in sc.metrics.items():
            t.rows.append([sc.name, k, _f(m.get("wall_s"), ".1f"), _f(m.get("peak_rss_mb"), ".0f"),
                           str(m["threads"]) if "threads" in m else "-"])
    return t


def _extremes(data: ReportData) -> Table:
    t = Table(["extreme", "must hold", "test", "result", "time (s)"], [])
    for r in data.extremes or []:
        res = r["outcome"] + (f": {r['message']}" if r.get("message") else "")
        t.rows.append([r["extreme"], r["expect"], r["test"], res, _f(r.get("seconds"), ".2f")])
    return t


def _headline(data: ReportData) -> Table:
    t = Table(["scene", "figure", "value"], [])
    for sc in data.scenes:
        m = sc.metrics
        for label, stage, key, fmt, scale in (
                ("mesh Chamfer-L1 (mm)", "mesh", "chamfer_l1", ".2f", 1000), ("mesh F@2cm", "mesh", "fscore_2cm", ".3f", 1),
                ("articulation precision", "evaluate", "precision", ".3f", 1),
                ("articulation recall", "evaluate", "recall", ".3f", 1), ("EA-score", "evaluate", "ea_score", ".3f", 1),
                ("motion EMD", "evaluate", "emd", ".3g", 1), ("closed PSNR (dB)", "twin", "closed_psnr", ".2f", 1),
                ("opened PSNR (dB)", "twin", "open_psnr", ".2f", 1),
                ("simulation integrator", "stability", "integrator", "", 1),
                ("simulation timestep (s)", "stability", "timestep", "g", 1),
                ("simulation real-time factor", "stability", "realtime_factor", ".1f", 1)):
            if stage in m and key in m[stage]:
                t.rows.append([sc.name, label, _f(m[stage][key], fmt, scale)])
        walls = [v.get("wall_s") for v in m.values() if isinstance(v.get("wall_s"), (int, float))]
        t.rows.append([sc.name, "sum of stage wall times (s)", _f(sum(walls), ".0f")])
    return t


_CSS = """body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1200px;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:13px}td,th{border:1px solid #ccc;padding:3px 8px;
text-align:left}th{background:#f2f2f2}section{margin-bottom:2em}img{max-width:100%;border:1px solid #ddd;display:block}
nav a{margin-right:1em}.note{color:#555;font-size:13px}"""


def render(data: ReportData) -> tuple[str, str]:
    """(index.html, summary.md) of ``data``."""
    parts_html: dict[str, list[str]] = {k: [] for k, _ in SECTIONS}
    parts_md: dict[str, list[str]] = {k: [] for k, _ in SECTIONS}

    def add(sec: str, t: Table | None = None, text: str | None = None, img: bytes | None = None, alt: str = "",
            width: str = "100%"):
        if text:
            parts_html[sec].append(f"<p>{html.escape(text)}</p>")
            parts_md[sec].append(text + "\n")
        if t is not None and (t.head or t.rows):
            parts_html[sec].append(t.html())
            parts_md[sec].append(t.md())
        if img is not None:
            parts_html[sec].append(f'<img alt="{html.escape(alt)}" style="width:{width}" src="{_png_uri(img)}">')
            parts_md[sec].append(f"_{alt}: see index.html_\n")

    add("headline", _headline(data))
    table = LAYOUT["report"]["table_json"]
    add("geometry", _geometry(data), None if data.geometry else f"skipped: reports/geometry/{table} is missing")
    add("appearance", _appearance(data), None if data.ablation else f"skipped: reports/ablation/{table} is missing")
    add("articulation", _articulation(data), "Precision = correct / predicted, recall = correct / GT (docs/formats.md); "
        "EA-score over correct revolute parts.")
    low = _low_margin(data)
    n_typed = sum(len(sc.decisions) for sc in data.scenes)
    add("articulation", low if low.rows else None,
        f"Low-margin decisions: {len(low.rows)} of {n_typed} typed fronts decided by less than "
        "articulate.types.low_margin over the runner-up (check these first; the viewer marks them).")
    tm, tp = _motion(data)
    add("motion", tm, "Motion EMD (docs/formats.md): each part driven open in the twin against its GT joint; mean over "
        "correct parts. Kinematic deviation: the simulation against the part's own joint.")
    add("motion", tp, "Interaction probes (passed / run, worst value).")
    tr = _robot(data)
    add("motion", tr if tr.rows else None, "The robot stage: a Panda opens (to 80 % of the range) and closes each "
        "part in the twin as it loads; transfer: the same actions replayed in the scene's own kitchen "
        f"({LAYOUT['robot']['attempts']} has each part's reason).")
    add("opened", _opened(data), "Each part opened to half its range, rendered against the GT at the same opening.")
    for sc in data.scenes:
        if sc.sheet is not None:
            add("opened", img=_file_png(sc.sheet, 500), alt=f"{sc.name}: opened parts, GT | twin", width="40%")
    for sc in data.scenes:
        text, t = _stability(sc)
        add("stability", t, text)
        if sc.heatmap is not None:
            add("stability", img=_file_png(sc.heatmap), alt=f"{sc.name}: stability heat map")
    tf = time_figure(data)
    add("time", text=None if tf else "skipped: no curve or stability matrix found", img=tf,
        alt="error against wall time")
    for sc in data.scenes:
        if sc.pareto is None:
            add("time", text=f"{sc.name}: no swept grid (dvc exp run -S experiment=pareto runs it)")
            continue
        add("time", _pareto(sc), f"{sc.name}: the swept grid (iterations x resolution x variant, "
            f"{len(sc.pareto['points'])} jobs); the best setting on each Pareto front within each budget.")
        if sc.pareto_plot is not None:
            add("time", img=_file_png(sc.pareto_plot), alt=f"{sc.name}: error against wall time, swept")
    add("stages", _stages(data), img=stages_figure(data), alt="per-stage wall time")
    add("extremes", _extremes(data), None if data.extremes is not None else "skipped: see below")
    add("skipped", Table(["scene", "what", "why"], [list(r) for r in data.skipped]))
    nav = "".join(f'<a href="#{k}">{html.escape(t)}</a>' for k, t in SECTIONS)
    body = "".join(f'<section id="{k}"><h2>{html.escape(t)}</h2>{"".join(parts_html[k])}</section>'
                   for k, t in SECTIONS)
    page = (f'<!doctype html><html lang="en"><head><meta charset="utf-8"><title>DRAWER report</title>'
            f"<style>{_CSS}</style></head><body><h1>DRAWER: the last <code>dvc repro</code></h1>"
            f'<p class="note">Scenes: {html.escape(", ".join(s.name for s in data.scenes))}. Every number below is '
            f"read from a tracked metrics file; this page loads nothing from the network.</p><nav>{nav}</nav>"
            f"{body}</body></html>")
    md = "# DRAWER: the last `dvc repro`\n\n" + "".join(f"## {t}\n\n" + "\n".join(parts_md[k]) + "\n"
                                                        for k, t in SECTIONS)
    return page, md


def run_report(out: Path, reports: Path, scenes: list[str], geometry_variants: list[str],
               appearance_variants: list[str]) -> dict:
    """The ``report`` stage: collect (the numerical-extremes tests' outcomes from the ``extremes``
    stage's table), write ``index.html``, ``summary.md`` and ``extremes.json`` (the report's
    metrics) into ``reports``; returns those metrics."""
    import time
    from contextlib import ExitStack

    from drawer_lib.errors import InputError
    from drawer_lib.io.atomic import atomic_open
    from drawer_lib.io.images import write_json
    from drawer_lib.report.extremes import read_extremes
    from drawer_lib.runner import peak_rss_mb

    t0 = time.perf_counter()
    reports, out = Path(reports), Path(out)
    extremes, why = read_extremes(reports)
    data = collect(out, reports, scenes, geometry_variants, appearance_variants, extremes, why)
    if not any(sc.metrics for sc in data.scenes):
        raise InputError(f"report: no stage metrics under {out}/ for scenes {scenes} (run dvc repro first)")
    rows = data.extremes or []
    page, md = render(data)
    with ExitStack() as both:  # both written before either is renamed into place
        for name, text in (("index", page), ("summary", md)):
            both.enter_context(atomic_open(reports / LAYOUT["report"][name], "w")).write(text)
    metrics = {"extremes_passed": sum(r["outcome"] == "passed" for r in rows), "extremes_n": len(rows),
               "n_skipped": len(data.skipped), "page_kb": round(len(page.encode()) / 1024, 1),
               "wall_s": round(time.perf_counter() - t0, 3), "peak_rss_mb": round(peak_rss_mb(), 1)}
    write_json(reports / LAYOUT["report"]["extremes"],
               metrics | ({"skipped": {"extremes": why}} if why else {}))
    return metrics
