"""Writing a report folder (a markdown table, its JSON, a plot) whole or not at all."""

import json
import shutil
from collections.abc import Callable
from pathlib import Path


def write_report(out: Path, md: str, js: dict, plot: Callable[[Path], None]) -> None:
    """``out/{table.md, table.json, curves.png}``: written into a temporary sibling and swapped
    in, so an interrupted run leaves the previous report, never a partial one."""
    out = Path(out)
    tmp = out.with_name(f".{out.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    (tmp / "table.md").write_text(md)
    (tmp / "table.json").write_text(json.dumps(js, indent=2))
    plot(tmp / "curves.png")
    shutil.rmtree(out, ignore_errors=True)
    tmp.rename(out)
