"""The geometry comparison: the selected ``sdf`` config and every ``geometry_variants`` config
side by side (accuracy of the final mesh, time), and their error-against-time curves in one plot."""

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drawer_lib.paths import LAYOUT, ScenePaths
from drawer_lib.report.markdown import md_table

COLUMNS = [("chamfer_l1", "Chamfer-L1 (mm)", 1000.0), ("fscore_1cm", "F@1cm", 1.0), ("fscore_2cm", "F@2cm", 1.0),
           ("normal_consistency", "NC", 1.0)]


@dataclass
class Row:
    scene: str
    name: str  # "<method> (selected)" or the variant name
    dir: Path  # holds sdf/ and mesh/
    sdf: dict
    mesh: dict
    curve: list[dict]
    skipped: str | None = None  # why the scene could not run this config


def _read_json(p: Path) -> dict:
    return json.loads(p.read_text()) if p.is_file() else {}


def read_curve(p: Path) -> list[dict]:
    if not p.is_file():
        return []
    with p.open() as f:
        return [{k: (float(v) if v not in ("", None) else np.nan) for k, v in r.items()} for r in csv.DictReader(f)]


def collect(out: Path, scenes: list[str], selected: str, variants: list[str]) -> list[Row]:
    """The sdf / mesh metrics and curves of the selected config and each variant, per scene
    (those whose mesh stage has run)."""
    rows = []
    for s in scenes:
        entries = [(f"{selected} (selected)", ScenePaths(out, s))] + [(v, ScenePaths(out, s, v)) for v in variants]
        for name, sp in entries:
            if not sp.metrics("mesh").is_file():
                continue
            sdf, mesh = _read_json(sp.metrics("sdf")), _read_json(sp.metrics("mesh"))
            why = (sdf.get("skipped") or {}).get("sdf")
            rows.append(Row(s, name, sp.stage_dir("mesh").parent, sdf, mesh,
                            read_curve(sp.stage_dir("sdf") / LAYOUT["curve"]), why))
    return rows


def _fmt(v, scale: float) -> str:
    return "–" if v is None or not np.isfinite(v) else f"{v * scale:.3f}" if scale == 1.0 else f"{v * scale:.2f}"


def table(rows: list[Row]) -> tuple[str, dict]:
    """Markdown table and the JSON of the same numbers."""
    head = ["scene", "config", "depth used", *(c[1] for c in COLUMNS), "sdf time (s)", "sdf stage (s)",
            "mesh stage (s)"]
    cells: list[list] = []
    js: dict = {}
    for r in rows:
        if r.skipped:
            cells.append([r.scene, r.name, f"skipped: {r.skipped}", *("–" for _ in COLUMNS), "–", "–", "–"])
            js.setdefault(r.scene, {})[r.name] = {"skipped": r.skipped}
            continue
        depth = r.sdf.get("depth_source", "sensor" if r.sdf.get("method") == "tsdf" else "?")
        vals = [r.mesh.get(c[0]) for c in COLUMNS]
        cells.append([r.scene, r.name, depth, *(_fmt(v, c[2]) for v, c in zip(vals, COLUMNS)),
                      f"{r.sdf.get('train_s', float('nan')):.1f}", f"{r.sdf.get('wall_s', float('nan')):.1f}",
                      f"{r.mesh.get('wall_s', float('nan')):.1f}"])
        js.setdefault(r.scene, {})[r.name] = {c[0]: r.mesh.get(c[0]) for c in COLUMNS} | {
            "depth_source": depth, "sdf_train_s": r.sdf.get("train_s"), "sdf_wall_s": r.sdf.get("wall_s"),
            "mesh_wall_s": r.mesh.get("wall_s")}
    return md_table(head, cells), js


def plot(rows: list[Row], path: Path) -> None:
    """Chamfer-L1 and F@2cm of the quick meshes against training time, one line per config
    (a single point for non-iterative methods such as the TSDF)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for r in rows:
        pts = [c for c in r.curve if np.isfinite(c.get("chamfer_l1", np.nan))]
        if not pts:
            continue
        t = [c["wall_s"] for c in pts]
        label = f"{r.scene}: {r.name}" if len({x.scene for x in rows}) > 1 else r.name
        label += f" ({r.sdf.get('depth_source', 'sensor')} depth)"
        style = dict(marker="o", ms=4) if len(pts) > 1 else dict(marker="*", ms=12, ls="none")
        axes[0].plot(t, [1000 * c["chamfer_l1"] for c in pts], label=label, **style)
        axes[1].plot(t, [c["fscore_2cm"] for c in pts], label=label, **style)
    axes[0].set(xlabel="training time (s)", ylabel="Chamfer-L1 (mm), quick mesh", yscale="log")
    axes[0].yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    axes[0].yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    axes[1].set(xlabel="training time (s)", ylabel="F-score @ 2 cm, quick mesh", ylim=(0, 1.01))
    for a in axes:
        a.grid(alpha=0.3)
    axes[1].legend(fontsize=8, loc="lower right")
    fig.suptitle("quick meshes (2 cm) during training vs gt/mesh.ply; a star = one-shot fusion", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
