"""DVC stage ``extremes``: the numerical-extremes tests (drawer_lib/report/extremes.py ``ROWS``),
run from the project root -> ``<paths.reports>/extremes/table.json`` (each test's outcome), which
the ``report`` stage tables. It depends on the code and the tests only, so it runs next to the
pipeline's first stages and not again when only metrics change.

    python -m stages.extremes -cn dvc_stage
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.report.extremes import extremes_stage
from drawer_lib.runner import main_guard

ROOT = Path(__file__).resolve().parent.parent


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    m = extremes_stage(ROOT, Path(cfg.paths.reports), bool(cfg.report.extremes), float(cfg.report.extremes_timeout))
    why = (m.get("skipped") or {}).get("extremes")
    print(f"extremes: {m['extremes_passed']}/{m['extremes_n']} passed in {m['wall_s']:.0f} s" + (f" (skipped: {why})" if why else ""))


if __name__ == "__main__":
    main()
