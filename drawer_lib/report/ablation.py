"""The appearance ablation (paper Table 3): variants side by side, and test PSNR against time."""

import json
from pathlib import Path

import numpy as np

from drawer_lib.paths import LAYOUT, ScenePaths
from drawer_lib.report.geometry_table import read_curve
from drawer_lib.report.markdown import md_table
from drawer_lib.report.paper import PAPER


def collect(out: Path, scenes: list[str], variants: list[str]) -> dict:
    """{scene: {variant: {"metrics", "curve"}}} of the appearance variants that have run."""
    rows: dict = {}
    for s in scenes:
        for v in variants:
            d = ScenePaths(out, s).appearance_dir(v)
            if (d / LAYOUT["metrics"]).is_file():
                rows.setdefault(s, {})[v] = {"metrics": json.loads((d / LAYOUT["metrics"]).read_text()),
                                            "curve": read_curve(d / LAYOUT["curve"])}
    return rows


def table(rows: dict, variants: list[str]) -> tuple[str, dict]:
    head = ["scene", "variant", "PSNR ↑", "SSIM ↑", "LPIPS ↓", "Gaussians", "in bounds",
            "raw param at a bound (pos / tilt / any)", "steps", "training (s)", "paper PSNR/SSIM/LPIPS"]
    cells: list[list] = []
    js: dict = {}
    for s, vs in rows.items():
        for v in variants:
            if v not in vs:
                continue
            m = vs[v]["metrics"]
            paper = "/".join(f"{x:g}" for x in PAPER["appearance"][v]) if v in PAPER["appearance"] else "–"
            inb = {True: "yes", False: "no"}.get(m.get("within_face_bounds"), "–")
            act = ("–" if "at_bound_any" not in m else
                   " / ".join(f"{100 * m[f'at_bound_{k}']:.0f} %" for k in ("position", "tilt", "any")))
            cells.append([s, v, f"{m['psnr']:.2f}", f"{m['ssim']:.3f}", f"{m['lpips']:.3f}",
                          m.get("n_gaussians", "–"), inb, act, m.get("steps", "–"),
                          f"{m.get('train_s', float('nan')):.1f}", paper])
            js.setdefault(s, {})[v] = {k: m.get(k) for k in ("psnr", "ssim", "lpips", "n_gaussians", "steps",
                                                              "train_s", "within_budget", "within_face_bounds")}
            js[s][v].update({k: val for k, val in m.items() if k.startswith("at_bound_")})
    return md_table(head, cells), js


def plot(rows: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4))
    for s, vs in rows.items():
        for v, d in vs.items():
            pts = [c for c in d["curve"] if np.isfinite(c.get("test_psnr", np.nan))]
            if not pts:
                continue
            label = v if len(rows) == 1 else f"{s}: {v}"
            style = dict(marker="o", ms=3) if len(pts) > 1 else dict(marker="*", ms=12, ls="none")
            ax.plot([c["wall_s"] for c in pts], [c["test_psnr"] for c in pts], label=label, **style)
    ax.set(xlabel="training time (s)", ylabel="test PSNR (dB)", title="appearance ablation: test PSNR against time")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
