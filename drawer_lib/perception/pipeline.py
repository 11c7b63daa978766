"""What the ``decompose`` stage does, and the reader of its outputs.

decompose: capture + mesh -> ``segments.json``, ``face_labels.npz`` (per face of
``perception_mesh.ply``: segment id or -1, the number of views whose "handle" masks cover it and
the number of train views that see it), ``perception_mesh.ply``.
"""

import time
from pathlib import Path

import numpy as np
import trimesh

from drawer_lib.errors import InputError
from drawer_lib.io.capture import Capture
from drawer_lib.io.images import read_json, write_json
from drawer_lib.io.overlay import capture_manifest
from drawer_lib.io.working import at_working_size, working_size_metrics
from drawer_lib.io.mesh import load_mesh
from drawer_lib.paths import capture_name, stage_name
from drawer_lib.perception.config import DecomposeConfig
from drawer_lib.perception.decompose import Segment, decompose_from_detections, face_labels
from drawer_lib.perception.views import perception_mesh, render_views
from drawer_lib.runner import StageRun

SEGMENTS_SCHEMA = "drawer.segments/1"


def run_decompose(cfg: DecomposeConfig, cap: Capture, mesh_path: Path, run: StageRun) -> dict:
    """Segment the mesh at ``mesh_path`` from the capture's detections (or, without them, by the
    geometric fallback) and write the decompose outputs. Views and masks are at the working
    resolution of ``cfg.max_side``."""
    manifest = capture_manifest(cap)
    cap = at_working_size(cap, cfg.max_side)
    run.metrics.update(working_size_metrics(cap))
    mesh = load_mesh(mesh_path, "run the mesh stage first")
    if cfg.mesh_jitter > 0:  # a stability study's run, not a result: another machine's last bits, drawn
        from drawer_lib.perturb import jitter_mesh

        mesh = jitter_mesh(mesh, cfg.mesh_jitter, seed=[cfg.seed, round(cfg.mesh_jitter * 1e12)])
        run.metrics["mesh_jitter"] = cfg.mesh_jitter
    mesh = perception_mesh(mesh, cfg.max_faces, cfg.max_edge, cap, list(cap.train), cfg.snap)
    has_det = cap.has("detections_path")
    source = cfg.source
    if source == "auto":
        source = "detections" if has_det else "geometric"
        if not has_det:
            run.skip("detections", manifest.lacks.get("detections", "the capture has no detections"))
    if source == "detections" and not has_det:
        raise InputError(f"{cap.root / capture_name('transforms')}: decompose.source = detections, but the capture "
                         "has no detections (set decompose.source: auto or geometric)")
    t0 = time.perf_counter()
    views = render_views(mesh, cap, list(cap.train))
    t_views = time.perf_counter() - t0
    if source == "detections":
        segs, handle_hits, info = decompose_from_detections(cap, views, cfg, run.progress)
    else:
        from drawer_lib.perception.geometric import decompose_geometric

        segs, handle_hits, info = decompose_geometric(cap, views, cfg.geometric, cfg)
    near_missed = info.pop("near_missed_rows", [])
    mesh.export(run.out("mesh"))
    np.savez_compressed(run.out("face_labels"), labels=face_labels(len(mesh.faces), segs), handle_hits=handle_hits,
                        face_views=views.face_frames())
    write_json(run.out("segments"), {"schema": SEGMENTS_SCHEMA, "source": source, "n_faces": int(len(mesh.faces)),
                                     "segments": [s.to_json() for s in segs]}
               | ({"near_missed": near_missed} if near_missed else {}))
    return {"source": source, "n_segments": len(segs), "n_planar": sum(s.planar for s in segs),
            "mesh_faces": int(len(mesh.faces)), "views_s": round(t_views, 3), **info}


def load_segments(d: Path) -> tuple[trimesh.Trimesh, list[Segment], np.ndarray, np.ndarray | None]:
    """(perception mesh, segments with their faces, [F] handle-mask hits, [F] views seeing each
    face or None from an output written before that was stored) of a decompose output."""
    seg_p, lab_p, mesh_p = (d / stage_name("decompose", k) for k in ("segments", "face_labels", "mesh"))
    for p in (seg_p, lab_p, mesh_p):
        if not p.is_file():
            raise InputError(f"{p}: missing (run the decompose stage first)")
    js = read_json(seg_p)
    if js.get("schema") != SEGMENTS_SCHEMA:
        raise InputError(f"{seg_p}: schema {js.get('schema')!r}, expected {SEGMENTS_SCHEMA!r}")
    mesh = load_mesh(mesh_p)
    z = np.load(lab_p)
    labels, hits = z["labels"], z["handle_hits"]
    face_views = z["face_views"] if "face_views" in z.files else None
    for name, a in (("labels", labels), ("handle_hits", hits), ("face_views", face_views)):
        if a is not None and len(a) != len(mesh.faces):
            raise InputError(f"{lab_p}: {len(a)} {name} for {len(mesh.faces)} faces")
    segs = []
    for s in js["segments"]:
        segs.append(Segment(int(s["id"]), np.nonzero(labels == int(s["id"]))[0], float(s["score"]),
                            int(s["support_frames"]), dict(s["labels"]), bool(s["planar"]), np.asarray(s["normal"]),
                            float(s["area_m2"]), np.asarray(s["centroid"]), s.get("source", "detections"),
                            matched=[(str(a), int(b)) for a, b in s.get("matched", [])], near=list(s.get("near", []))))
    return mesh, segs, hits, face_views
