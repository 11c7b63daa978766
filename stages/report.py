"""DVC stage ``report``: every tracked metric of the last ``dvc repro`` -> ``<paths.reports>/``
``index.html`` (one self-contained offline page), ``summary.md`` and ``extremes.json`` (the
numerical-extremes tests, run now, and the report's own wall time).

    python -m stages.report -cn dvc_stage
"""

import tempfile
import time
from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.errors import InputError
from drawer_lib.io.images import write_json
from drawer_lib.paths import LAYOUT
from drawer_lib.report.dashboard import collect, render, write_text_atomic
from drawer_lib.report.extremes import as_dicts, run_extremes
from drawer_lib.runner import main_guard, peak_rss_mb

ROOT = Path(__file__).resolve().parent.parent


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    t0 = time.perf_counter()
    reports, out = Path(cfg.paths.reports), Path(cfg.paths.out)
    why = None if cfg.report.extremes else "report.extremes = false"
    data = collect(out, reports, list(cfg.scenes), list(cfg.geometry_variants), list(cfg.appearance_variants), None,
                   why)
    if not any(sc.metrics for sc in data.scenes):
        raise InputError(f"report: no stage metrics under {out}/ for scenes {list(cfg.scenes)} (run dvc repro first)")
    if cfg.report.extremes:
        with tempfile.TemporaryDirectory() as scratch:
            data.extremes = as_dicts(run_extremes(ROOT, Path(scratch), float(cfg.report.extremes_timeout)))
    extremes = data.extremes
    page, md = render(data)
    n_ok = sum(r["outcome"] == "passed" for r in extremes or [])
    write_text_atomic({reports / LAYOUT["report"]["index"]: page, reports / LAYOUT["report"]["summary"]: md})
    write_json(reports / LAYOUT["report"]["extremes"],
               {"extremes_passed": n_ok, "extremes_n": len(extremes or []), "n_skipped": len(data.skipped),
                "page_kb": round(len(page.encode()) / 1024, 1), "wall_s": round(time.perf_counter() - t0, 3),
                "peak_rss_mb": round(peak_rss_mb(), 1), "rows": extremes or [],
                **({"skipped": {"extremes": why}} if why else {})})
    print(f"report: {reports / LAYOUT['report']['index']} ({len(page) // 1024} KiB), extremes {n_ok}/"
          f"{len(extremes or [])} passed, {len(data.skipped)} skips listed")


if __name__ == "__main__":
    main()
