"""Do the decisions hold when the mesh moves by its last bits? The reconstructed mesh of the same
capture differs between machines, SDF seeds and thread counts by fractions of a millimetre; a
kind or hinge side that changes under such a change had no margin. :func:`jitter_run` articulates
a scene again on its own decompose output with every mesh vertex moved by Gaussian noise of
``sigma`` metres (the faces, hence the segments, unchanged), and :func:`compare_parts` says which
parts kept their kind and hinge side (``scripts/decision_stability.py``). :func:`mesh_check`
goes further back, as the stage's ``articulate.check`` does: decompose runs again on the mesh
moved before it is simplified, so the segments may change too, as they do on another machine."""

import dataclasses
import shutil
import tempfile
from pathlib import Path

import numpy as np
import trimesh

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.pipeline import run_articulate
from drawer_lib.io.capture import Capture
from drawer_lib.io.parts import Part, PartsFile, read_parts
from drawer_lib.metrics.articulation import match_parts, part_kind
from drawer_lib.perturb import jitter_mesh
from drawer_lib.paths import stage_name
from drawer_lib.runner import stage_run


def compare_parts(ref: PartsFile, other: PartsFile) -> list[dict]:
    """Per articulated part of ``ref``: its kind, the kind of the part of ``other`` on the same
    front (front overlap, as the articulation metrics match) or ``missed``, whether it kept it,
    and ``ref``'s margin."""
    m = match_parts(other, ref)
    by_ref = {j: i for i, j, _ in m.pairs}
    rows = []
    for j, g in enumerate(m.gt):
        k_ref = part_kind(g)
        k_new = part_kind(m.pred[by_ref[j]]) if j in by_ref else "missed"
        rows.append({"part": g.id, "kind": k_ref, "now": k_new, "kept": k_ref == k_new,
                     "margin": g.extra.get("margin")})
    return rows


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


def mesh_check(cfg: ArticulateConfig, decompose_cfg, cap: Capture, mesh_path: Path, weights: dict | None,
               ref: PartsFile, progress=None) -> dict[str, list[dict]]:
    """Which parts of ``ref`` (articulate's result on ``cap`` and the mesh at ``mesh_path``)
    another machine's reconstruction could change: ``cfg.check.runs`` times, the mesh's every
    vertex moved by Gaussian noise of ``cfg.check.sigma`` m (run k's draw seeded by
    ``[decompose_cfg.seed, round(sigma * 1e12), k + 1]``, apart from ``decompose.mesh_jitter``'s),
    then decompose (``decompose_cfg``, a
    :class:`~drawer_lib.perception.config.DecomposeConfig`) and articulate (``cfg`` without its
    check) run on it in a temporary folder, and the parts compared on their fronts
    (:func:`compare_parts`). Returns {part id: [{"run": k, "now": its kind in that run, or
    ``missed``}]} for each part some run did not keep; ``{}`` with ``cfg.check.runs`` 0.
    ``progress``: a :meth:`StageRun.progress`-like wrapper for the runs, or None."""
    from drawer_lib.io.mesh import load_mesh
    from drawer_lib.perception.pipeline import run_decompose

    sigma, runs = cfg.check.sigma, cfg.check.runs
    inner = dataclasses.replace(cfg, check=dataclasses.replace(cfg.check, runs=0))
    inner_dc = dataclasses.replace(decompose_cfg, mesh_jitter=0.0)
    mesh = load_mesh(mesh_path, "run the mesh stage first")
    moved: dict[str, list[dict]] = {}
    ks = range(runs) if progress is None else progress(range(runs), desc="mesh check", total=runs)
    for k in ks:
        with tempfile.TemporaryDirectory() as tmp:
            t = Path(tmp)
            mp = t / "mesh.ply"
            jitter_mesh(mesh, sigma, [int(decompose_cfg.seed), round(sigma * 1e12), k + 1]).export(mp)
            with stage_run("decompose", t / "decompose", seed=0) as r:
                run_decompose(inner_dc, cap, mp, r)
            with stage_run("articulate", t / "articulate", seed=0) as r:
                run_articulate(inner, cap, t / "decompose", r, weights=weights)
            other = read_parts(t / "articulate" / stage_name("articulate", "parts"))
        for row in compare_parts(ref, other):
            if not row["kept"]:
                moved.setdefault(row["part"], []).append({"run": k, "now": row["now"]})
    return moved


def mark_near_mesh(parts: list[Part], report: list[dict], moved: dict[str, list[dict]]
                   ) -> tuple[list[Part], list[dict]]:
    """``parts`` and articulate's ``report`` (its ``decisions.json`` rows) with each part in
    ``moved`` (:func:`mesh_check`) marked ``low_margin`` and its row given ``near_mesh``: the
    runs that changed it. Kinds, joints and fronts stay as they are."""
    out = [dataclasses.replace(p, extra={**p.extra, "low_margin": True}) if p.id in moved else p for p in parts]
    rows = [{**r, "near_mesh": moved[r["part"]], "low_margin": True} if r.get("part") in moved else r
            for r in report]
    return out, rows
