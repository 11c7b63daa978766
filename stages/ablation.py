"""DVC stage ``ablation``: the appearance variants side by side (paper Table 3) ->
``<paths.reports>/ablation/`` (``table.md``, ``table.json``, ``curves.png``).

    python -m stages.ablation -cn dvc_stage
"""

from pathlib import Path

import hydra
from omegaconf import DictConfig

from drawer_lib.errors import InputError
from drawer_lib.report.ablation import collect, plot, table
from drawer_lib.report.write import write_report
from drawer_lib.runner import main_guard


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard
def main(cfg: DictConfig) -> None:
    variants = list(cfg.appearance_variants)
    rows = collect(Path(cfg.paths.out), list(cfg.scenes), variants)
    if not rows:
        raise InputError(f"ablation: no appearance metrics under {cfg.paths.out}/ (run the appearance stages first)")
    md, js = table(rows, variants)
    write_report(Path(cfg.paths.reports) / "ablation", md, js, lambda path: plot(rows, path))
    print(md)


if __name__ == "__main__":
    main()
