"""Markdown (GitHub-flavoured) tables: the one builder every report and benchmark script uses.

>>> print(md_table(["a", "b"], [[1, "x|y"]], align="lr"), end="")
| a | b |
|:---|---:|
| 1 | x\\|y |
"""

from collections.abc import Iterable, Sequence

_RULE = {"": "---", "-": "---", "l": ":---", "r": "---:", "c": ":---:"}


def md_cell(v) -> str:
    """A cell's text: ``str(v)`` with ``|`` escaped and line breaks as spaces, so that no value
    can split its row."""
    return str(v).replace("|", "\\|").replace("\r\n", " ").replace("\n", " ")


def md_row(cells: Iterable) -> str:
    """One table row: ``| a | b |``."""
    return "| " + " | ".join(md_cell(c) for c in cells) + " |"


def md_table(header: Sequence, rows: Iterable[Iterable], align: str | Sequence[str] | None = None) -> str:
    """A markdown table: the header row, the alignment row, one row per element of ``rows``
    (none: the header alone), each line ending in a newline.

    ``align``: None (``---`` under every column); one letter for every column; or a letter per
    column (a string as long as ``header`` or a list): ``l`` ``:---``, ``r`` ``---:``, ``c``
    ``:---:``, ``-`` ``---``."""
    n = len(header)
    if align is None:
        align = "-"
    if len(align) == 1:
        align = list(align) * n
    if len(align) != n or any(a not in _RULE for a in align):
        raise ValueError(f"md_table: align {align!r} for {n} columns (one of l r c - per column)")
    lines = [md_row(header), "|" + "".join(_RULE[a] + "|" for a in align)]
    lines += [md_row(r) for r in rows]
    return "\n".join(lines) + "\n"
