"""DVC stage ``report``: every tracked metric of the last ``dvc repro`` -> ``<paths.reports>/``
``index.html`` (one self-contained offline page), ``summary.md`` and ``extremes.json`` (the
report's metrics: the numerical-extremes tests' count from the ``extremes`` stage, the page's
size, its own wall time); see drawer_lib/report/dashboard.py.

    python -m stages.report -cn dvc_stage
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.paths import LAYOUT
from drawer_lib.report.dashboard import run_report
from drawer_lib.runner import main_guard


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    m = run_report(Path(cfg.paths.out), Path(cfg.paths.reports), list(cfg.scenes), list(cfg.geometry_variants),
                   list(cfg.appearance_variants))
    print(f"report: {Path(cfg.paths.reports) / LAYOUT['report']['index']} ({m['page_kb']:.0f} KiB), extremes "
          f"{m['extremes_passed']}/{m['extremes_n']} passed, {m['n_skipped']} skips listed")


if __name__ == "__main__":
    main()
