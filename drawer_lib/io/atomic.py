"""Writing files and folders whole or not at all: the one home of "write to a temporary sibling,
then rename it into place".

A reader (another stage, DVC hashing an output, a browser) sees the old version or the new one,
never a half-written file; a failed or interrupted write removes its temporary and leaves the
old version untouched.

* :func:`atomic_open` / :func:`atomic_write_bytes` / :func:`atomic_write_text`: one file.
  Several files that must land together: :func:`atomic_open` each inside one
  ``contextlib.ExitStack`` (all are written before the first is renamed).
* :func:`atomic_folder`: a folder (or some entries of one) built in a temporary folder and
  moved into place by :func:`replace_path`.

Temporary names are ``.<name>.<pid>.<n>.partial`` next to the target (same file system, so the
rename is atomic; the pid and a per-process counter keep two writers, processes or threads,
from ever sharing one). They do not end in ``.tmp``, so :func:`drawer_lib.runner.clean_stale`,
which removes the stage folders of dead writers, never takes a live writer's file.
"""

import itertools
import os
import shutil
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO

_SEQ = itertools.count()


def temp_sibling(path: Path | str, kind: str = "partial") -> Path:
    """A fresh name ``.<name>.<pid>.<n>.<kind>`` next to ``path`` (nothing is created)."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}.{next(_SEQ)}.{kind}")


def remove_path(p: Path | str) -> None:
    """Remove a file, a link (not what it points to) or a folder tree; nothing if absent."""
    p = Path(p)
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p)
    elif p.exists() or p.is_symlink():
        p.unlink()


@contextmanager
def atomic_open(path: Path | str, mode: str = "wb") -> Iterator[IO]:
    """``with atomic_open(path, "w") as f: f.write(...)``: ``f`` writes a temporary sibling that
    replaces ``path`` (``os.replace``) when the block ends without error; on an error the
    temporary is removed and ``path`` is untouched. Missing parent folders are created.
    ``mode``: ``"wb"`` or ``"w"`` (text, UTF-8)."""
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_open: mode must be 'wb' or 'w', got {mode!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_sibling(path)
    try:
        with open(tmp, mode.replace("w", "x"), **({} if "b" in mode else {"encoding": "utf-8"})) as f:
            yield f
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def atomic_write_bytes(path: Path | str, data: bytes) -> None:
    """``path`` holds ``data``, written whole or not at all (:func:`atomic_open`)."""
    with atomic_open(path, "wb") as f:
        f.write(data)


def atomic_write_text(path: Path | str, text: str) -> None:
    """``path`` holds ``text`` (UTF-8), written whole or not at all (:func:`atomic_open`)."""
    with atomic_open(path, "w") as f:
        f.write(text)


def replace_path(src: Path | str, dst: Path | str, aside: Path | str | None = None) -> None:
    """Move ``src`` onto ``dst``. A file onto a file (or onto nothing) is one atomic
    ``os.replace``. Where either is a folder, ``dst`` is first renamed to ``aside`` (default: a
    fresh :func:`temp_sibling`), then ``src`` renamed to ``dst`` and ``aside`` removed: a crash
    between the two renames leaves the old version at ``aside`` (a caller that names it can put
    it back, as the stage runner's ``clean_stale`` does)."""
    src, dst = Path(src), Path(dst)
    if not src.is_dir() and not (dst.is_dir() and not dst.is_symlink()):
        os.replace(src, dst)
        return
    if not (dst.exists() or dst.is_symlink()):
        src.rename(dst)
        return
    aside = Path(aside) if aside is not None else temp_sibling(dst, "aside")
    remove_path(aside)
    dst.rename(aside)
    src.rename(dst)
    remove_path(aside)


@contextmanager
def atomic_folder(folder: Path | str, entries: Sequence[str] | None = None) -> Iterator[Path]:
    """``with atomic_folder(folder) as tmp:`` write into the fresh temporary folder ``tmp``; when
    the block ends without error, ``tmp`` replaces ``folder`` (:func:`replace_path`). On an error
    ``folder`` is untouched and ``tmp`` is removed.

    With ``entries`` (top-level file or folder names) only those are replaced, each in the given
    order, and everything else in ``folder`` stays; ``tmp`` then lies inside ``folder`` when it
    exists, and the block must have written every entry (``RuntimeError`` otherwise)."""
    folder = Path(folder)
    inside = entries is not None and folder.is_dir()
    tmp = temp_sibling(folder / folder.name if inside else folder)
    tmp.parent.mkdir(parents=True, exist_ok=True)
    tmp.mkdir()
    try:
        yield tmp
        if entries is not None:
            missing = [e for e in entries if not (tmp / e).exists()]
            if missing:
                raise RuntimeError(f"atomic_folder: {folder}: nothing was written for {missing}")
        if not inside:
            replace_path(tmp, folder)
        else:
            for name in entries:
                replace_path(tmp / name, folder / name)
    finally:
        remove_path(tmp)
