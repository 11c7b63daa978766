"""What the ``articulate`` stage does: the decompose outputs + capture -> ``parts.json``
(``drawer.parts/1``, docs/formats.md) and ``decisions.json`` (why each segment got its type)."""

import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.estimators import get_estimator
from drawer_lib.articulation.rectify import View
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.geometry.camera import Camera
from drawer_lib.io.capture import Capture
from drawer_lib.io.images import write_json
from drawer_lib.io.mesh import load_mesh
from drawer_lib.io.parts import Part, PartsFile, read_parts, write_parts
from drawer_lib.io.working import at_working_size, working_size_metrics
from drawer_lib.metrics.articulation import compare_parts
from drawer_lib.paths import stage_name
from drawer_lib.perception.decompose import HANDLE_LABELS, Segment, absorb_handles
from drawer_lib.perception.pipeline import load_segments, run_decompose
from drawer_lib.perturb import jitter_mesh
from drawer_lib.runner import StageRun, stage_run


def mask_source(cap: Capture):
    """segment -> [(bool mask [H, W], the Camera of its frame)] of the detections it matched."""
    index = {cap.frames[i].stem: i for i in range(len(cap.frames))}
    cache: dict[int, np.ndarray] = {}

    def masks_of(seg: Segment) -> list[tuple[np.ndarray, Camera]]:
        out = []
        for stem, d in seg.matched:
            i = index.get(stem)
            if i is None:
                raise InputError(f"segments.json: segment {seg.id} refers to frame {stem!r}, which the capture lacks")
            if i not in cache:
                cache[i] = cap.detections(i)[0]
            out.append((cache[i] == d, cap.camera(i)))
        return out

    return masks_of


def train_views(cap: Capture, mesh, with_images: bool = False) -> list[View]:
    """The train views for :mod:`~drawer_lib.articulation.rectify`: camera, the depth of
    ``mesh`` ray-cast from it, the union of its "handle" masks and the label map of its other
    masks, each handle given to the front it sits on (None without detections) and, with ``with_images``, its image."""
    from drawer_lib.geometry.raycast import Raycaster

    rc = Raycaster(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    dets = cap.has("detections_path")
    views = []
    for i in cap.train:
        cam = cap.camera(i)
        depth, _, _ = rc.depth_normals(cap.intrinsics, cam.w2c)
        hmask, inst = None, None
        if dets:
            lab, rows = cap.detections(i)
            ids = [int(d["id"]) for d in rows if str(d.get("label", "")).strip().lower() in HANDLE_LABELS]
            hmask = np.isin(lab, ids) if ids else np.zeros(lab.shape, bool)
            inst = absorb_handles(lab, rows).astype(np.uint16)  # a handle's pixels belong to its front
            inst[np.isin(inst, ids)] = 0  # handles no front took
        views.append(View(cam, depth, hmask, cap.image(i) if with_images else None, cap.frames[i].stem, inst))
    return views


def run_articulate(cfg: ArticulateConfig, cap: Capture, seg_dir: Path, run: StageRun,
                   weights: dict[str, dict[str, float]] | None = None, recheck: tuple | None = None) -> dict:
    """Infer the parts of the segments in ``seg_dir`` (a decompose output) and write them;
    ``weights``: the score rule's (:func:`drawer_lib.articulation.weights.resolve_weights`;
    None: ``cfg.types.prior``). ``recheck``: (decompose's config, the mesh decompose read), which
    ``cfg.check.runs`` > 0 needs to infer the parts again from the mesh moved by its last bits
    (:func:`mesh_check`)."""
    if cfg.check.runs and recheck is None:
        raise ConfigError(f"articulate.check.runs = {cfg.check.runs}: the caller gave no decompose config and mesh "
                          "to run the check on (set articulate.check.runs=0)")
    cap0 = cap
    est = get_estimator(cfg.estimator)
    extra = {}
    if cfg.estimator == "vlm":  # loaded first: a missing model stops the stage before any work
        from drawer_lib.articulation.vlm import VlmTyper

        extra["typer"] = VlmTyper(cfg.vlm)
    cap = at_working_size(cap, cfg.max_side)
    run.metrics.update(working_size_metrics(cap))
    mesh, segs, hits, face_views = load_segments(seg_dir)
    if cfg.handles.evidence == "view_rate" and face_views is None:
        raise InputError(f"{seg_dir}: face_labels has no face_views, which articulate.handles.evidence = "
                         "view_rate needs (written by an older decompose: re-run it)")
    centers = np.stack([cap.frames[i].c2w[:3, 3] for i in cap.train])
    masks_of = mask_source(cap) if cap.has("detections_path") else None
    views = (train_views(cap, mesh, with_images=cfg.split.enabled or cfg.rectify.colour_handles)
             if cfg.rectify.enabled and cap.has("detections_path") else None)
    if cfg.estimator == "vlm":  # the model sees every train view, with or without detections
        extra["vlm_views"] = views if views is not None and all(v.image is not None for v in views) else \
            train_views(cap, mesh, with_images=True)
    parts, report = est(mesh, segs, centers, cfg, handle_hits=hits, masks_of=masks_of, face_views=face_views,
                        weights=weights, views=views, **extra)
    checked = {}
    if cfg.check.runs:
        t0 = time.perf_counter()
        moved = mesh_check(cfg, recheck[0], cap0, Path(recheck[1]), weights, PartsFile(tuple(parts)), run.progress)
        parts, report = mark_near_mesh(parts, report, moved)
        checked = {"n_near_mesh": len(moved), "check_s": round(time.perf_counter() - t0, 1)}
    pf = PartsFile(tuple(parts))
    write_parts(run.out("parts"), pf)
    write_json(run.out("decisions"), {"estimator": cfg.estimator, "segments": report})
    fam: dict[str, int] = {}
    for p in parts:
        f = p.extra.get("family", p.kind)
        fam[f] = fam.get(f, 0) + 1
    return {"estimator": cfg.estimator, "n_parts": len(parts), **{f"n_{k}": v for k, v in pf.kinds().items()},
            "families": fam, "n_fronts_cut_back": sum("cut_back" in r for r in report if r.get("part")),
            "n_fronts_found_twice": sum("inside" in r for r in report), **checked}


def mesh_check(cfg: ArticulateConfig, decompose_cfg, cap: Capture, mesh_path: Path, weights: dict | None,
               ref: PartsFile, progress=None) -> dict[str, list[dict]]:
    """Which parts of ``ref`` (articulate's result on ``cap`` and the mesh at ``mesh_path``)
    another machine's reconstruction could change: ``cfg.check.runs`` times, the mesh's every
    vertex moved by Gaussian noise of ``cfg.check.sigma`` m (run k's draw seeded by
    ``[decompose_cfg.seed, round(sigma * 1e12), k + 1]``, apart from ``decompose.mesh_jitter``'s),
    then decompose (``decompose_cfg``, a
    :class:`~drawer_lib.perception.config.DecomposeConfig`) and articulate (``cfg`` without its
    check) run on it in a temporary folder, and the parts compared on their fronts
    (:func:`~drawer_lib.metrics.articulation.compare_parts`). Returns {part id: [{"run": k,
    "now": its kind in that run, or ``missed``}]} for each part some run did not keep; ``{}``
    with ``cfg.check.runs`` 0.
    ``progress``: a :meth:`StageRun.progress`-like wrapper for the runs, or None."""
    sigma, runs = cfg.check.sigma, cfg.check.runs
    inner = dataclasses.replace(cfg, check=dataclasses.replace(cfg.check, runs=0))
    inner_dc = dataclasses.replace(decompose_cfg, mesh_jitter=0.0)
    mesh = load_mesh(mesh_path, "run the mesh stage first")
    moved: dict[str, list[dict]] = {}
    ks = range(runs) if progress is None else progress(range(runs), desc="mesh check", total=runs)
    for k in ks:
        with tempfile.TemporaryDirectory() as tmp:
            t = Path(tmp)
            mp = t / stage_name("mesh", "mesh")
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
