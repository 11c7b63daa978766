"""Writing a report folder (a markdown table, its JSON, a plot) whole or not at all."""

import shutil
from collections.abc import Callable
from pathlib import Path

from drawer_lib.io.images import write_json
from drawer_lib.paths import LAYOUT


def write_report(out: Path, md: str, js: dict, plot: Callable[[Path], None]) -> None:
    """``out/{table.md, table.json, curves.png}``: written into a temporary sibling and swapped
    in, so an interrupted run leaves the previous report, never a partial one."""
    out = Path(out)
    tmp = out.with_name(f".{out.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    (tmp / LAYOUT["report"]["table"]).write_text(md)
    write_json(tmp / LAYOUT["report"]["table_json"], js)
    plot(tmp / LAYOUT["report"]["plot"])
    shutil.rmtree(out, ignore_errors=True)
    tmp.rename(out)
