"""Files of the twin exports: OBJ meshes and atomic folder writes."""

from pathlib import Path
from collections.abc import Callable, Sequence

import numpy as np
from jaxtyping import Float, Int

from drawer_lib.io.atomic import atomic_folder


def shortest(v: float) -> str:
    """The shortest decimal that reads back as exactly ``v`` (Python's float repr, "1" not "1.0")."""
    r = repr(float(v))
    return r[:-2] if r.endswith(".0") else r


def obj_bytes(vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]) -> bytes:
    """Wavefront OBJ of a triangle mesh (``v`` lines with 9 significant digits, 1-based ``f``
    lines), formatted in one C-level pass per block."""
    v = np.asarray(vertices, np.float64).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3) + 1
    text = ("v %.9g %.9g %.9g\n" * len(v)) % tuple(v.ravel().tolist())
    text += ("f %d %d %d\n" * len(f)) % tuple(f.ravel().tolist())
    return text.encode()


def write_entries_atomic(folder: Path, entries: Sequence[str], build: Callable[[Path], None]) -> None:
    """Write the top-level ``entries`` (file or folder names) of ``folder`` all-or-nothing.

    ``build(root)`` writes them under a fresh temporary folder ``root`` (on the same file
    system) and may verify them there; only when it returns are they moved into ``folder``
    (a whole temporary folder renamed when ``folder`` does not exist yet; otherwise each entry,
    in the given order, replaces its old version by a rename). On any error nothing of
    ``folder`` changes and the temporary folder is removed (:func:`drawer_lib.io.atomic.atomic_folder`).
    """
    with atomic_folder(folder, entries) as tmp:
        build(tmp)
