"""The one markdown-table builder (drawer_lib/report/markdown.py)."""

import pytest

from drawer_lib.report.markdown import md_cell, md_row, md_table


def test_header_rule_and_rows():
    assert md_table(["a", "b"], [[1, 2.5], ["x", None]]) == "| a | b |\n|---|---|\n| 1 | 2.5 |\n| x | None |\n"


def test_alignment_per_column_or_for_all():
    assert md_table(["a", "b", "c", "d"], [], align="lrc-").splitlines()[1] == "|:---|---:|:---:|---|"
    assert md_table(["a", "b"], [], align=["r", "l"]).splitlines()[1] == "|---:|:---|"
    assert md_table(["a", "b", "c"], [], align="r").splitlines()[1] == "|---:|---:|---:|"
    with pytest.raises(ValueError):
        md_table(["a", "b", "c"], [], align="lr")
    with pytest.raises(ValueError):
        md_table(["a"], [], align="x")


def test_a_pipe_or_a_line_break_cannot_split_a_row():
    assert md_cell("a|b") == "a\\|b" and md_cell("two\nlines") == "two lines"
    t = md_table(["k|ey", "v"], [["x|y", "1\n2"]])
    assert t == "| k\\|ey | v |\n|---|---|\n| x\\|y | 1 2 |\n"
    # every line has exactly as many unescaped separators as the header
    assert {line.replace("\\|", "").count("|") for line in t.splitlines()} == {3}


def test_empty_rows_give_the_header_alone():
    assert md_table(["only"], []) == "| only |\n|---|\n"
    assert md_table(["a", "b"], iter(())) == "| a | b |\n|---|---|\n"
    assert md_row([]) == "|  |"
