"""Writing a report folder (a markdown table, its JSON, a plot) whole or not at all."""

from collections.abc import Callable
from pathlib import Path

from drawer_lib.io.atomic import atomic_folder
from drawer_lib.io.images import write_json
from drawer_lib.paths import LAYOUT


def write_report(out: Path, md: str, js: dict, plot: Callable[[Path], None]) -> None:
    """``out/{table.md, table.json, curves.png}``: written into a temporary sibling and swapped
    in, so an interrupted run leaves the previous report, never a partial one."""
    with atomic_folder(out) as tmp:
        (tmp / LAYOUT["report"]["table"]).write_text(md)
        write_json(tmp / LAYOUT["report"]["table_json"], js)
        plot(tmp / LAYOUT["report"]["plot"])
