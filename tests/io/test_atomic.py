"""Whole-or-nothing writes (drawer_lib/io/atomic.py): the content lands, no temporary is left,
a failure mid-write leaves the old version and no temporary, str and Path both work."""

import json
import os
from contextlib import ExitStack

import numpy as np
import pytest

from drawer_lib.io.atomic import (atomic_folder, atomic_open, atomic_write_bytes, atomic_write_text, replace_path,
                                  temp_sibling)
from drawer_lib.io.images import write_json


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


@pytest.mark.parametrize("as_str", [False, True])
def test_bytes_and_text_land_whole_with_no_temporary_left(tmp_path, as_str):
    b, t = tmp_path / "sub" / "a.bin", tmp_path / "sub" / "b.txt"
    atomic_write_bytes(str(b) if as_str else b, b"\x00\x01")
    atomic_write_text(str(t) if as_str else t, "héllo\n")
    assert b.read_bytes() == b"\x00\x01" and t.read_text(encoding="utf-8") == "héllo\n"
    atomic_write_text(t, "second")  # over an existing file
    assert t.read_text() == "second"
    assert _names(tmp_path / "sub") == ["a.bin", "b.txt"]


class Boom(Exception):
    pass


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    p = tmp_path / "f.txt"
    p.write_text("old")
    with pytest.raises(Boom):
        with atomic_open(str(p), "w") as f:
            f.write("half of the new")
            f.flush()
            assert len(_names(tmp_path)) == 2  # the new content goes to a sibling, not to p
            raise Boom
    assert p.read_text() == "old" and _names(tmp_path) == ["f.txt"]
    with pytest.raises(ValueError):  # NaN is refused by write_json before anything lands
        write_json(p, {"x": float("nan")})
    assert p.read_text() == "old" and _names(tmp_path) == ["f.txt"]


def test_write_json_takes_numpy_scalars_and_still_refuses_their_nan(tmp_path):
    """A decision's flag computed from a numpy margin (``margin >= 0``) is ``np.bool_``, which
    the json module refuses; written as plain JSON, and a numpy NaN is still refused."""
    p = tmp_path / "d.json"
    write_json(p, {"made": np.float64(-0.2) >= 0, "n": np.int64(3), "m": np.float32(0.25), "l": [np.True_]})
    assert json.loads(p.read_text()) == {"made": False, "n": 3, "m": 0.25, "l": [True]}
    with pytest.raises(ValueError):
        write_json(p, {"x": np.float32("nan")})


def test_files_written_together_land_together(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    with pytest.raises(Boom):
        with ExitStack() as both:
            both.enter_context(atomic_open(a, "w")).write("A")
            both.enter_context(atomic_open(b, "w")).write("B")
            raise Boom
    assert _names(tmp_path) == []
    with ExitStack() as both:
        both.enter_context(atomic_open(a, "w")).write("A")
        both.enter_context(atomic_open(b, "w")).write("B")
    assert (a.read_text(), b.read_text()) == ("A", "B") and _names(tmp_path) == ["a", "b"]


def test_temporary_names_are_unique_and_carry_the_pid(tmp_path):
    names = {temp_sibling(tmp_path / "x.json") for _ in range(3)}
    assert len(names) == 3
    assert all(n.parent == tmp_path and f".x.json.{os.getpid()}." in n.name and not n.name.endswith(".tmp")
               for n in names)  # .tmp is the stage runner's (clean_stale removes those of dead writers)


def test_atomic_folder_replaces_the_whole_folder_or_nothing(tmp_path):
    out = tmp_path / "report"
    with atomic_folder(str(out)) as tmp:
        (tmp / "t.md").write_text("v1")
    assert _names(out) == ["t.md"]
    with pytest.raises(Boom):
        with atomic_folder(out) as tmp:
            (tmp / "t.md").write_text("v2")
            raise Boom
    assert (out / "t.md").read_text() == "v1" and _names(tmp_path) == ["report"]
    with atomic_folder(out) as tmp:
        (tmp / "u.md").write_text("v3")
    assert _names(out) == ["u.md"] and _names(tmp_path) == ["report"]


def test_atomic_folder_entries_keep_the_rest_of_the_folder(tmp_path):
    f = tmp_path / "twin"
    f.mkdir()
    (f / "keep.txt").write_text("k")
    (f / "meshes").mkdir()
    (f / "meshes" / "old.obj").write_text("o")
    with atomic_folder(f, ["meshes", "scene.xml"]) as tmp:
        (tmp / "meshes").mkdir()
        (tmp / "meshes" / "new.obj").write_text("n")
        (tmp / "scene.xml").write_text("<x/>")
    assert _names(f) == ["keep.txt", "meshes", "scene.xml"] and _names(f / "meshes") == ["new.obj"]
    with pytest.raises(RuntimeError, match="scene.xml"):  # an entry not written: nothing moves
        with atomic_folder(f, ["meshes", "scene.xml"]) as tmp:
            (tmp / "meshes").mkdir()
    assert _names(f) == ["keep.txt", "meshes", "scene.xml"] and _names(f / "meshes") == ["new.obj"]


def test_replace_path_puts_a_folder_over_a_file_and_back(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    dst.write_text("file")
    src.mkdir()
    (src / "x").write_text("x")
    replace_path(src, dst, aside=tmp_path / ".dst.old")
    assert dst.is_dir() and _names(tmp_path) == ["dst"]
    src.write_text("file again")
    replace_path(src, dst)
    assert dst.read_text() == "file again" and _names(tmp_path) == ["dst"]
