"""CI's metric dashboard: the headline numbers of a pipeline run (not the hundreds of keys `dvc
metrics show` prints), compared with a committed baseline, with a regression beyond a stated
tolerance failing the build.

:func:`headline` reads ``out/<scene>/...`` into flat ``{"<scene>/<what>:<key>": value}``;
:data:`GATES` says, per key suffix, which direction is better and how much worse is tolerated;
:func:`compare` returns the rows and the regressions; :func:`dashboard` the markdown.
"""

import json
import math
from dataclasses import dataclass
from pathlib import Path

from drawer_lib.paths import LAYOUT, ScenePaths
from drawer_lib.report.markdown import md_table

# (stage folder, key) pairs the dashboard shows for each scene
STAGE_KEYS = {
    "mesh": ("chamfer_l1", "fscore_2cm", "normal_consistency"),
    "evaluate": ("precision", "recall", "ea_score", "emd"),
    "twin": ("closed_psnr", "open_psnr", "open_region_psnr"),
    "stability": ("timestep", "nominal_error_m", "realtime_factor"),
    "simulate": ("kinematic_dev_max_m", "n_parts_not_opened", "pull_handle_passed", "pull_handle_n"),
}
VARIANT_KEYS = ("psnr", "ssim", "lpips")  # appearance/<variant>/metrics.json
GEOMETRY_KEYS = ("chamfer_l1", "fscore_2cm")  # geometry/<variant>/mesh/metrics.json


@dataclass(frozen=True)
class Gate:
    """``higher``: larger is better; a value worse than the baseline by more than ``abs_tol`` +
    ``rel_tol`` x |baseline| is a regression."""

    higher: bool
    abs_tol: float
    rel_tol: float = 0.0


GATES = {  # by the key after ":"; keys without a gate are shown, never gated (wall times, counts)
    "chamfer_l1": Gate(False, 2e-4, 0.2), "fscore_2cm": Gate(True, 0.03), "normal_consistency": Gate(True, 0.03),
    "precision": Gate(True, 0.1), "recall": Gate(True, 0.1), "ea_score": Gate(True, 0.05),
    "emd": Gate(False, 1e-4, 1.0), "closed_psnr": Gate(True, 1.0), "open_psnr": Gate(True, 1.0),
    "open_region_psnr": Gate(True, 1.5), "psnr": Gate(True, 1.0), "ssim": Gate(True, 0.02),
    "lpips": Gate(False, 0.03), "nominal_error_m": Gate(False, 2e-4, 0.5), "kinematic_dev_max_m": Gate(False, 1e-3),
    "n_parts_not_opened": Gate(False, 0.0),
}


def _read(p: Path) -> dict:
    try:
        return json.loads(p.read_text()) if p.is_file() else {}
    except ValueError:
        return {}


def headline(out: Path, scenes: list[str], appearance_variants: list[str], geometry_variants: list[str]) -> dict:
    """The dashboard's values of a run under ``out`` (absent metrics are left out)."""
    h: dict = {}
    for s in scenes:
        sp = ScenePaths(Path(out), s)
        for st, keys in STAGE_KEYS.items():
            m = _read(sp.metrics(st))
            h |= {f"{s}/{st}:{k}": m[k] for k in keys if isinstance(m.get(k), (int, float))}
            if isinstance(m.get("wall_s"), (int, float)):
                h[f"{s}/{st}:wall_s"] = m["wall_s"]
        for v in appearance_variants:
            m = _read(sp.appearance_dir(v) / LAYOUT["metrics"])
            h |= {f"{s}/appearance/{v}:{k}": m[k] for k in VARIANT_KEYS if isinstance(m.get(k), (int, float))}
        for v in geometry_variants:
            m = _read(ScenePaths(Path(out), s, v).metrics("mesh"))
            h |= {f"{s}/geometry/{v}:{k}": m[k] for k in GEOMETRY_KEYS if isinstance(m.get(k), (int, float))}
    return h


def compare(now: dict, base: dict) -> tuple[list[tuple], list[str]]:
    """Rows (key, baseline, now, change, verdict) and the regressions' messages. A gated key
    missing from ``now`` but in the baseline is a regression (a stage stopped reporting it)."""
    rows, bad = [], []
    for k in sorted(set(now) | set(base)):
        b, n = base.get(k), now.get(k)
        gate = GATES.get(k.rsplit(":", 1)[-1])
        verdict = ""
        if gate is not None and b is not None:
            if n is None or (isinstance(n, float) and not math.isfinite(n)):
                verdict = "missing"
                bad.append(f"{k}: in the baseline ({b:g}) but not in this run")
            else:
                worse = (b - n) if gate.higher else (n - b)
                tol = gate.abs_tol + gate.rel_tol * abs(b)
                if worse > tol:
                    verdict = "REGRESSION"
                    bad.append(f"{k}: {n:.6g} against {b:.6g} (worse by {worse:.3g}, tolerance {tol:.3g})")
                else:
                    verdict = "ok"
        change = (n - b) if isinstance(n, (int, float)) and isinstance(b, (int, float)) else None
        rows.append((k, b, n, change, verdict))
    return rows, bad


def _f(v) -> str:
    return "–" if v is None else (f"{v:.5g}" if isinstance(v, float) else str(v))


def dashboard(now: dict, base: dict, title: str) -> tuple[str, list[str]]:
    """The markdown dashboard and the regressions."""
    rows, bad = compare(now, base)
    lines = [f"## {title}", "", md_table(["metric", "baseline", "this run", "change", "gate"],
                                         ([k, _f(b), _f(n), _f(c), v] for k, b, n, c, v in rows))]
    lines += [f"**{len(bad)} regression(s)**" + (":" if bad else " beyond the tolerances of "
                                                   "`drawer_lib/report/ci.py` GATES.")]
    lines += [f"- {m}" for m in bad]
    return "\n".join(lines) + "\n", bad
