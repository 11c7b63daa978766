"""Triangle mesh files (PLY): read and validate in one place."""

from pathlib import Path

import numpy as np
import trimesh

from drawer_lib.errors import InputError


def load_mesh(path: Path, hint: str = "") -> trimesh.Trimesh:
    """The triangle mesh at ``path`` as stored (no merging or reordering of vertices). Raises
    :class:`InputError` naming the file when it is missing, unreadable, not a triangle mesh,
    has no faces or non-finite vertices; ``hint`` is added to the missing-file message (e.g.
    "run the mesh stage first")."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: mesh is missing" + (f" ({hint})" if hint else ""))
    try:
        m = trimesh.load(path, process=False)
    except Exception as e:  # trimesh raises many kinds on a broken file
        raise InputError(f"{path}: unreadable mesh ({type(e).__name__}: {e})") from e
    if not isinstance(m, trimesh.Trimesh) or len(m.faces) == 0:
        raise InputError(f"{path}: not a triangle mesh with faces")
    if not np.all(np.isfinite(m.vertices)):
        raise InputError(f"{path}: non-finite vertex coordinates")
    return m
