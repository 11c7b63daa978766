"""DVC stage ``geometry_table``: the selected geometry and the ``geometry_variants`` side by side
-> ``<paths.reports>/geometry/`` (``table.md``, ``table.json``, ``curves.png``).

    python -m stages.geometry_table -cn dvc_stage
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.errors import InputError
from drawer_lib.report.geometry_table import collect, plot, table
from drawer_lib.report.write import write_report
from drawer_lib.runner import main_guard


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    rows = collect(Path(cfg.paths.out), list(cfg.scenes), cfg.sdf.method, list(cfg.geometry_variants))
    if not rows:
        raise InputError(f"geometry_table: no mesh metrics under {cfg.paths.out}/ (run the sdf and mesh stages first)")
    md, js = table(rows)
    write_report(Path(cfg.paths.reports) / "geometry", md, js, lambda path: plot(rows, path))
    print(md)


if __name__ == "__main__":
    main()
