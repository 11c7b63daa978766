"""Do the decisions hold when the mesh moves by its last bits? The reconstructed mesh of the same
capture differs between machines, SDF seeds and thread counts by fractions of a millimetre; a
kind or hinge side that changes under such a change had no margin. :func:`jitter_run` articulates
a scene again on its own decompose output with every mesh vertex moved by Gaussian noise of
``sigma`` metres (the faces, hence the segments, unchanged), and :func:`compare_parts` says which
parts kept their kind and hinge side (``scripts/decision_stability.py``). The stage's own check,
``articulate.check``, goes further back (:func:`drawer_lib.articulation.pipeline.mesh_check`):
decompose runs again on the mesh moved before it is simplified, so the segments may change too,
as they do on another machine."""

import shutil
import tempfile
from pathlib import Path

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.pipeline import run_articulate
from drawer_lib.io.capture import Capture
from drawer_lib.io.parts import PartsFile, read_parts
from drawer_lib.metrics.articulation import compare_parts
from drawer_lib.perturb import jitter_mesh
from drawer_lib.paths import stage_name
from drawer_lib.runner import stage_run


def stability_counts(ref: PartsFile, other: PartsFile, rows: list[dict] | None = None) -> dict:
    """How ``other``'s articulated parts differ from ``ref``'s, matched on their fronts as the
    articulation metrics match (:func:`compare_parts`): ``n_ref``, ``n_other``, ``kept`` (a part
    of ``other`` on the same front, of the same kind), ``retyped`` (on the same front, another
    kind), ``lost`` (no part of ``other`` on that front) and ``added`` (parts of ``other`` on no
    front of ``ref``); ``n_flagged`` of ``ref``'s parts are marked ``low_margin`` and
    ``moved_flagged`` of those were not kept (what the flag says of the parts that move).
    ``rows``: :func:`compare_parts` of the two, when the caller has them already."""
    rows = compare_parts(ref, other) if rows is None else rows
    n_other = sum(p.articulated for p in other.parts)
    matched = sum(r["now"] != "missed" for r in rows)
    flagged = {p.id for p in ref.parts if p.extra.get("low_margin")}
    return {"n_ref": len(rows), "n_other": n_other, "kept": sum(r["kept"] for r in rows),
            "retyped": sum(not r["kept"] and r["now"] != "missed" for r in rows),
            "lost": sum(r["now"] == "missed" for r in rows), "added": n_other - matched,
            "n_flagged": sum(r["part"] in flagged for r in rows),
            "moved_flagged": sum(not r["kept"] and r["part"] in flagged for r in rows)}


def jitter_run(cfg: ArticulateConfig, cap: Capture, seg_dir: Path, weights: dict, sigma: float, seed: int
               ) -> PartsFile:
    """The scene articulated again on a copy of ``seg_dir`` whose mesh is :func:`jitter_mesh`'d."""
    from drawer_lib.io.mesh import load_mesh

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp) / "decompose"
        shutil.copytree(seg_dir, d)
        mesh_p = d / stage_name("decompose", "mesh")
        jitter_mesh(load_mesh(mesh_p), sigma, seed).export(mesh_p)
        out = Path(tmp) / "articulate"
        with stage_run("articulate", out, seed=0) as r:
            run_articulate(cfg, cap, d, r, weights=weights)
        return read_parts(out / stage_name("articulate", "parts"))
