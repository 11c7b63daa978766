"""What the ``decompose``, ``articulate`` and ``evaluate`` stages do.

decompose: capture + mesh -> ``segments.json``, ``face_labels.npz`` (per face of
``perception_mesh.ply``: segment id or -1, the number of views whose "handle" masks cover it and
the number of train views that see it), ``perception_mesh.ply``.
articulate: those + capture -> ``parts.json`` (DESIGN §5) + ``decisions.json`` (why each segment
got its type). evaluate: ``parts.json`` vs ``gt/parts.json`` -> precision, recall, EA-score.
"""

import time
from pathlib import Path

import numpy as np
import trimesh

from drawer_lib.errors import InputError
from drawer_lib.io.capture import Capture
from drawer_lib.io.images import read_json, write_json
from drawer_lib.io.manifest import Manifest
from drawer_lib.io.parts import PartsFile, read_parts, write_parts
from drawer_lib.perception.articulate import get_estimator, infer_parts
from drawer_lib.perception.config import ArticulateConfig, DecomposeConfig
from drawer_lib.perception.decompose import Segment, decompose_from_detections, face_labels
from drawer_lib.perception.views import perception_mesh, render_views
from drawer_lib.runner import StageRun

SEGMENTS_SCHEMA = "drawer.segments/1"


def load_mesh(path: Path) -> trimesh.Trimesh:
    if not path.is_file():
        raise InputError(f"{path}: mesh is missing (run the mesh stage first)")
    m = trimesh.load(path, process=False)
    if not isinstance(m, trimesh.Trimesh) or len(m.faces) == 0:
        raise InputError(f"{path}: not a triangle mesh with faces")
    return m


def run_decompose(cfg: DecomposeConfig, cap: Capture, manifest: Manifest, mesh_path: Path, run: StageRun,
                  out: Path) -> dict:
    mesh = perception_mesh(load_mesh(mesh_path), cfg.max_faces, cfg.max_edge, cap, list(cap.train))
    has_det = cap.has("detections_path")
    source = cfg.source
    if source == "auto":
        source = "detections" if has_det else "geometric"
        if not has_det:
            run.skip("detections", manifest.lacks.get("detections", "the capture has no detections"))
    if source == "detections" and not has_det:
        raise InputError(f"{cap.root / 'transforms.json'}: decompose.source = detections, but the capture has no "
                         "detections (set decompose.source: auto or geometric)")
    t0 = time.perf_counter()
    views = render_views(mesh, cap, list(cap.train))
    t_views = time.perf_counter() - t0
    if source == "detections":
        segs, handle_hits, info = decompose_from_detections(cap, views, cfg, run.progress)
    else:
        from drawer_lib.perception.geometric import decompose_geometric

        segs, handle_hits, info = decompose_geometric(cap, views, cfg.geometric, cfg)
    mesh.export(out / "perception_mesh.ply")
    np.savez_compressed(out / "face_labels.npz", labels=face_labels(len(mesh.faces), segs), handle_hits=handle_hits,
                        face_views=views.face_frames())
    write_json(out / "segments.json", {"schema": SEGMENTS_SCHEMA, "source": source, "n_faces": int(len(mesh.faces)),
                                       "segments": [s.to_json() for s in segs]})
    return {"source": source, "n_segments": len(segs), "n_planar": sum(s.planar for s in segs),
            "mesh_faces": int(len(mesh.faces)), "views_s": round(t_views, 3), **info}


def load_segments(d: Path) -> tuple[trimesh.Trimesh, list[Segment], np.ndarray, np.ndarray | None]:
    """(perception mesh, segments with their faces, [F] handle-mask hits, [F] views seeing each
    face or None from an output written before that was stored) of a decompose output."""
    for name in ("segments.json", "face_labels.npz", "perception_mesh.ply"):
        if not (d / name).is_file():
            raise InputError(f"{d / name}: missing (run the decompose stage first)")
    js = read_json(d / "segments.json")
    if js.get("schema") != SEGMENTS_SCHEMA:
        raise InputError(f"{d / 'segments.json'}: schema {js.get('schema')!r}, expected {SEGMENTS_SCHEMA!r}")
    mesh = trimesh.load(d / "perception_mesh.ply", process=False)
    z = np.load(d / "face_labels.npz")
    labels, hits = z["labels"], z["handle_hits"]
    face_views = z["face_views"] if "face_views" in z.files else None
    for name, a in (("labels", labels), ("handle_hits", hits), ("face_views", face_views)):
        if a is not None and len(a) != len(mesh.faces):
            raise InputError(f"{d / 'face_labels.npz'}: {len(a)} {name} for {len(mesh.faces)} faces")
    segs = []
    for s in js["segments"]:
        segs.append(Segment(int(s["id"]), np.nonzero(labels == int(s["id"]))[0], float(s["score"]),
                            int(s["support_frames"]), dict(s["labels"]), bool(s["planar"]), np.asarray(s["normal"]),
                            float(s["area_m2"]), np.asarray(s["centroid"]), s.get("source", "detections"),
                            matched=[(str(a), int(b)) for a, b in s.get("matched", [])]))
    return mesh, segs, hits, face_views


def camera_centers(cap: Capture, frames: list[int]) -> np.ndarray:
    return np.stack([cap.frames[i].c2w[:3, 3] for i in frames])


def _mask_source(cap: Capture):
    """segment -> [(bool mask, w2c, (fx, fy, cx, cy))] of the detections it matched."""
    index = {cap.frames[i].stem: i for i in range(len(cap.frames))}
    it = cap.intrinsics
    K = (it.fx, it.fy, it.cx, it.cy)
    cache: dict[int, np.ndarray] = {}

    def masks_of(seg: Segment) -> list:
        out = []
        for stem, d in seg.matched:
            i = index.get(stem)
            if i is None:
                raise InputError(f"segments.json: segment {seg.id} refers to frame {stem!r}, which the capture lacks")
            if i not in cache:
                cache[i] = cap.detections(i)[0]
            out.append((cache[i] == d, cap.frames[i].w2c, K))
        return out

    return masks_of


def run_articulate(cfg: ArticulateConfig, cap: Capture, seg_dir: Path, out: Path) -> dict:
    est = get_estimator(cfg.estimator)
    mesh, segs, hits, face_views = load_segments(seg_dir)
    if cfg.handle_evidence == "view_rate" and face_views is None:
        raise InputError(f"{seg_dir / 'face_labels.npz'}: has no face_views, which articulate.handle_evidence = "
                         "view_rate needs (written by an older decompose: re-run it)")
    if est is infer_parts:
        masks_of = _mask_source(cap) if cap.has("detections_path") else None
        parts, report = infer_parts(mesh, segs, camera_centers(cap, list(cap.train)), cfg, hits, masks_of, face_views)
    else:
        parts, report = est(mesh, segs, camera_centers(cap, list(cap.train)), cfg, handle_hits=hits)
    pf = PartsFile(tuple(parts))
    write_parts(out / "parts.json", pf)
    write_json(out / "decisions.json", {"estimator": cfg.estimator, "segments": report})
    kinds = pf.kinds()
    fam: dict[str, int] = {}
    for p in parts:
        f = p.extra.get("family", p.kind)
        fam[f] = fam.get(f, 0) + 1
    return {"estimator": cfg.estimator, "n_parts": len(parts), **{f"n_{k}": v for k, v in kinds.items()},
            "families": fam}


def eval_views(cap: Capture) -> list:
    it = cap.intrinsics
    return [(cap.frames[i].w2c, (it.fx, it.fy, it.cx, it.cy), it.width, it.height) for i in cap.test]


def run_evaluate(cap: Capture, manifest: Manifest, parts_path: Path, run: StageRun, out: Path) -> dict:
    from drawer_lib.metrics.articulation import articulation_metrics

    if not parts_path.is_file():
        raise InputError(f"{parts_path}: missing (run the articulate stage first)")
    pred = read_parts(parts_path)
    m: dict = {"n_pred": sum(p.articulated for p in pred.parts)}
    if not run.needs(manifest, "articulation", "gt"):
        write_json(out / "matches.json", {"parts": [], "skipped": run.skipped["articulation"]})
        return m
    gt = read_parts(cap.root / "gt" / "parts.json")
    res, details = articulation_metrics(pred, gt, eval_views(cap))
    if res["n_pred"] - res["n_ignored"] == 0:
        run.skip("precision", "no articulated part predicted")
        res.pop("precision")
    if res["n_gt"] == 0:
        run.skip("recall", "the ground truth has no articulated part")
        res.pop("recall")
    if "ea_score" not in res:
        run.skip("ea_score", "no correctly predicted revolute part is visible in a test view")
    write_json(out / "matches.json", {"parts": details})
    m.update(res)
    return m
