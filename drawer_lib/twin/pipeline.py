"""What the ``twin`` stage does: ``complete/`` + ``parts.json`` -> ``twin/`` in the format of
``drawer.twin/1`` (docs/formats.md).

1. the bodies of ``complete/`` (static scene, articulated parts, rigid objects) as a
   :class:`~drawer_lib.bodies.TwinModel`, validated;
2. ``scene.xml`` (+ ``assets/``) built with ``MjSpec``, compiled and checked before anything is
   written (every drive opens its part, a person's pull opens it, the limits hold, nothing
   penetrates, rigid objects rest, no NaN or MuJoCo warning; :func:`drawer_lib.sim.checks.
   check_twin`) — a failing check is reported per part (``checks.json`` ``failures``,
   ``twin.json`` ``checks``) and the twin still written (``on_check_failure: error`` stops
   instead); a simulation that goes non-finite stops the stage;
3. ``urdf/scene.urdf`` and ``scene.usda``;
4. ``gaussians/static.ply`` and ``gaussians/<id>.ply`` (INRIA layout, world frame at q = 0) and
   ``visual.glb`` (the visual meshes, one node per body); ``twin.json`` (bodies, their
   Gaussians and collision shapes; a collision mesh's PLY is copied to ``collision/``);
   ``open_parts.html`` / ``.viser``: every part opened in turn, a self-contained page to share
   (:mod:`drawer_lib.viewer.record`; ``recording.enabled``);
5. ``renders/<id>/<stem>.png`` + ``renders/index.json``: the twin's Gaussians in every test view
   with part ``<id>`` opened to ``renders.open_fraction`` of its range, every other part closed;
6. on a synthetic scene, the opened-state scores against the scene's own model posed with the
   matched GT part at the same q (``open_psnr``, ``open_ssim``, ``open_lpips``,
   ``open_region_psnr``; docs/formats.md#opened-state-nvs), the closed twin's scores against the capture's test
   images (``closed_psnr`` ...), and ``renders/contact_sheet.png`` (GT | twin, a row per part).
"""

import drawer_lib.synth.gl  # noqa: F401, I001  (before mujoco: the opened-state reference renders offscreen)
import shutil
import time
from pathlib import Path

import numpy as np
import torch
import trimesh
from PIL import Image

from drawer_lib.capture.config import SceneConfig
from drawer_lib.complete.io import STATIC, read_complete
from drawer_lib.errors import InputError, TwinCheckError
from drawer_lib.io.capture import Capture
from drawer_lib.io.images import write_json, write_rgb
from drawer_lib.io.manifest import read_manifest
from drawer_lib.io.parts import Part, read_parts
from drawer_lib.metrics.articulation import match_parts
from drawer_lib.metrics.image import image_scores
from drawer_lib.paths import capture_name, stage_name
from drawer_lib.runner import StageRun
from drawer_lib.bodies import Shape
from drawer_lib.sim.checks import check_twin
from drawer_lib.sim.repair import repair_penetrations
from drawer_lib.sim.mjcf import build_spec, compile_spec, write_mjcf
from drawer_lib.sim.urdf import write_urdf
from drawer_lib.sim.usd import write_usd
from drawer_lib.splat.render import Gaussians
from drawer_lib.synth.config import RenderConfig
from drawer_lib.sim.config import SimConfig
from drawer_lib.twin.config import TwinConfig
from drawer_lib.splat.gaussians import concat
from drawer_lib.splat.ply import read_gaussian_ply
from drawer_lib.twin.renders import opened_q, region_psnr, render_opened
from drawer_lib.viewer.record import record_twin

SCHEMA = "drawer.twin/1"


def _empty_gaussians(k: int) -> Gaussians:
    return Gaussians(torch.zeros(0, 3), torch.zeros(0, 4), torch.zeros(0, 3), torch.zeros(0), torch.zeros(0, k, 3))


def _visual_glb(model, path: Path) -> None:
    scene = trimesh.Scene()
    for name, shapes in [(STATIC, model.static_visual)] + [(b.id, b.visual) for b in model.bodies()]:
        meshes = [trimesh.Trimesh(*s.triangles(), process=False) for s in shapes]
        if meshes:
            scene.add_geometry(trimesh.util.concatenate(meshes), node_name=name, geom_name=name)
    scene.export(path)


def _score(pred: list[torch.Tensor], gt: list[torch.Tensor], regions: list[np.ndarray] | None, with_lpips: bool) -> dict:
    out = {k: v.tolist() for k, v in image_scores(torch.stack(pred), torch.stack(gt), with_lpips).items()}
    if regions is not None:
        out["region_psnr"] = [region_psnr(p, g, m) for p, g, m in zip(pred, gt, regions)]
    return out


def _collision_files(entries: list[dict], complete_dir: Path, out: Path) -> list[dict]:
    """A body's collision shapes as ``twin.json`` lists them, world frame at q = 0: boxes as they
    are, a mesh's PLY copied from ``complete/`` to the same relative path under ``twin/`` (every
    file twin.json names lives in the twin folder)."""
    for e in entries:
        if e.get("file"):
            (out / e["file"]).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(complete_dir / e["file"], out / e["file"])
    return entries


def _box_json(s: Shape) -> dict:
    """A collision box as ``complete.json`` and ``twin.json`` write it."""
    return {"kind": "box", **s.box.to_json()}


def _overlap_with(r: dict) -> str:
    """What a repair record (:func:`~drawer_lib.sim.repair.repair_penetrations`) overlapped."""
    where = "opening, " if r.get("along_path") else ""
    if "other" in r:
        return f"{where}piece {r['piece']} into {r['other']!r} piece {r['other_piece']}"
    return f"{where}into static piece {r['static_piece']}"


def _tile(img: np.ndarray, width: int) -> np.ndarray:
    h = max(1, round(img.shape[0] * width / img.shape[1]))
    return np.asarray(Image.fromarray(img).resize((width, h), Image.BILINEAR))


def run_twin(cfg: TwinConfig, sim: SimConfig, cap: Capture, parts_path: Path, complete_dir: Path, run: StageRun,
             scene: SceneConfig | None = None, render_cfg: RenderConfig | None = None) -> dict:
    """Build, check and write the twin (see the module doc) with the simulation config ``sim``;
    ``scene``: the scene config, whose
    ``synth`` block (synthetic scenes only) gives the opened-state reference, rendered with
    ``render_cfg`` (the capture's ``capture.render``, so that it equals the capture at q = 0)."""
    if not parts_path.is_file():
        raise InputError(f"{parts_path}: missing (run the articulate stage first)")
    parts = read_parts(parts_path)
    by_id = {p.id: p for p in parts.parts}
    model, gfiles, cj = read_complete(complete_dir)
    model.validate()
    for b in model.bodies():
        if b.id not in by_id:
            raise InputError(f"{complete_dir}: body {b.id!r} is not a part of {parts_path}")
    t0 = time.perf_counter()
    model, repairs, kept, part_changed = repair_penetrations(model, sim, cfg.repair)
    if repairs:
        print(f"[twin] repaired {sum(r['action'] in ('carved', 'removed') for r in repairs)} overlap(s) at q = 0:\n"
              + "\n".join(f"  {r['part']}: {_overlap_with(r)} {r['depth_m'] * 1000:.1f} mm deep, {r['action']}"
                          for r in repairs), flush=True)
    m: dict = {"repair_s": round(time.perf_counter() - t0, 3),
               "n_repairs": sum(r["action"] in ("carved", "removed") for r in repairs),
               "n_unrepaired": sum(r["action"] not in ("carved", "removed") for r in repairs),
               "n_parts": len(model.parts), "n_rigid": len(model.rigid),
               "n_static_collision": len(model.static_collision),
               "n_part_collision": sum(len(p.collision) for p in model.parts)}
    out = run.dir

    # 1-2: MJCF, compiled and checked before anything else is written
    t0 = time.perf_counter()
    spec = build_spec(model, sim)
    compile_spec(spec)
    m["build_s"] = round(time.perf_counter() - t0, 3)
    write_mjcf(spec, out)
    failed: dict[str, list[str]] = {}
    stops: dict[str, dict] = {}
    if cfg.check:
        t0 = time.perf_counter()
        try:
            rep = check_twin(run.out("mjcf"), model, sim)
            rep["failures"] = []
        except TwinCheckError as e:
            if cfg.on_check_failure == "error":
                raise
            rep = {**(e.report or {}), "failures": e.failures}
            for f in e.failures:
                failed.setdefault(f["id"], []).append(f["check"])
            print(f"[twin] {len(e.failures)} physical check(s) failed; the twin is written and they are "
                  f"reported (twin.on_check_failure = report):\n" + "\n".join(f["message"] for f in e.failures),
                  flush=True)
        rep["repairs"] = repairs
        stops = {pid: {"q": r["stop_q"], "by": r["stopped_by"]} for pid, r in rep.get("parts", {}).items()
                 if "stop_q" in r}
        m["check_s"] = round(time.perf_counter() - t0, 3)
        m["n_check_failures"] = len(rep["failures"])
        m["n_parts_failing_checks"] = len(failed)
        m.update({f"sim_{k}": v for k, v in rep.items() if isinstance(v, (int, float)) and not isinstance(v, bool)})
        write_json(run.out("checks"), rep)
    else:
        run.skip("checks", "twin.check = false")
    # 3: URDF, USD
    t0 = time.perf_counter()
    write_urdf(model, out, sim)
    write_usd(model, out, sim)
    _visual_glb(model, run.out("glb"))
    m["export_s"] = round(time.perf_counter() - t0, 3)

    # 4: Gaussians per body
    gdir = stage_name("twin", "gaussians")  # twin.json names files relative to the twin folder
    run.out("gaussians").mkdir()
    gauss: dict[str, Gaussians] = {}
    for bid, f in gfiles.items():
        shutil.copyfile(f, run.out("gaussians") / f"{bid}.ply")
        gauss[bid] = read_gaussian_ply(f)
    k = next(iter(gauss.values())).sh.shape[1] if gauss else (cfg.renders.sh_degree + 1) ** 2
    static = concat([gauss.get(STATIC, _empty_gaussians(k))] + [gauss[r.id] for r in model.rigid if r.id in gauss])
    bodies = {p.id: gauss.get(p.id, _empty_gaussians(k)) for p in model.parts}
    m["n_gaussians"] = int(len(static.means) + sum(len(g.means) for g in bodies.values()))

    raw = {b["id"]: b for b in cj["bodies"]}
    man = cap.root / capture_name("manifest")
    world = read_manifest(man).world_frame if man.is_file() else {}
    twin_json = {"schema": SCHEMA, "world": world, "parts": [], "static": {
        "body": "static", "gaussians": f"{gdir}/{STATIC}.ply" if STATIC in gauss else None,
        "collision": _collision_files([raw[STATIC]["collision"][k] if new is None else _box_json(new)
                                       for k, new in kept], complete_dir, out)}}
    for b in model.bodies():
        twin_json["parts"].append({"id": b.id, "kind": by_id[b.id].kind, "body": b.id, "joint": b.id,
                                   "actuator": b.id if by_id[b.id].articulated else None,
                                   "gaussians": f"{gdir}/{b.id}.ply" if b.id in gauss else None,
                                   "collision": _collision_files(
                                       [_box_json(part_changed[b.id][k]) if k in part_changed.get(b.id, {}) else e
                                        for k, e in enumerate(raw[b.id]["collision"])], complete_dir, out),
                                   "interior": raw[b.id].get("interior", {}),
                                   "grasp": raw[b.id].get("grasp"),
                                   "stop": stops.get(b.id),
                                   "checks": sorted(set(failed.get(b.id, []))) if cfg.check else None,
                                   "confidence": by_id[b.id].extra.get("confidence"),
                                   "low_margin": bool(by_id[b.id].extra.get("low_margin", False))})
    write_json(run.out("index"), twin_json)

    # 4b: the shareable browser recording, every part opened in turn (drawer_lib/viewer)
    if cfg.recording.enabled:
        r = record_twin(out, run.out("recording"), run.out("recording_viser"), cfg.recording)
        m["recording_s"] = r["wall_s"]
        m["recording_mb"] = round(r["html_bytes"] / 1e6, 3)
    else:
        run.skip("recording", "twin.recording.enabled = false")

    # 5-6: opened-state renders and their scores
    rc = cfg.renders
    test = list(cap.test)[: rc.max_views or None]
    if not test or not model.parts:
        run.skip("renders", "no test views" if not test else "no articulated part")
        run.out("renders").mkdir()
        write_json(run.out("renders_index"), {"renders": []})
        return m
    cams = cap.cameras(test)
    stems = [cap.frames[i].stem for i in test]
    bg = torch.tensor(rc.background, dtype=torch.float32)
    rdir = run.out("renders")
    rdir.mkdir()
    synth = scene.synth if scene is not None and scene.source == "synth" else None
    opened = _OpenedScores(cap, cams, parts, synth, rc, render_cfg, run)
    t_render, index = 0.0, []
    try:
        for p in model.parts:  # one part's views at a time (13 parts x 32 views of 1280 x 960 held at once: 12.4 GB peak, 3.9 GB so)
            t0 = time.perf_counter()
            part = by_id[p.id]
            q = opened_q(part, rc.open_fraction)
            views = render_opened(static, bodies, by_id, p.id, q, cams, rc.sh_degree, bg)
            (rdir / p.id).mkdir()
            for stem, v, i in zip(stems, views, test):
                f = f"{p.id}/{stem}.png"
                write_rgb(rdir / f, (v.rgb.numpy() * 255 + 0.5).astype(np.uint8))
                index.append({"id": p.id, "q": q, "file_path": cap.frames[i].file_path, "image": f})
            t_render += time.perf_counter() - t0
            opened.add(p.id, q, views)
            del views
    finally:
        opened.close()
    write_json(run.out("renders_index"), {"renders": index})
    m["render_s"] = round(t_render, 3)

    closed = [v.rgb for v in render_opened(static, bodies, by_id, model.parts[0].id, 0.0, cams, rc.sh_degree, bg)]
    real = [torch.from_numpy(cap.image(i).astype(np.float32) / 255.0) for i in test]
    sc = _score(closed, real, None, rc.lpips)
    m.update({f"closed_{k}": float(np.mean(v)) for k, v in sc.items()})
    opened.finish(m)
    return m


class _OpenedScores:
    """The opened twin's scores against the procedural scene opened the same way, one part at a
    time as its views are rendered (``render_scores.json``, ``open_*`` metrics, the contact
    sheet). Skips with the reason when the scene is not procedural, has no GT parts or no
    predicted part matches one of its kind."""

    def __init__(self, cap: Capture, cams, parts, synth, rc, render_cfg: RenderConfig | None, run: StageRun):
        self.rc, self.run, self.ref, self.pairs, self.why = rc, run, None, {}, None
        self.rows: list[dict] = []
        self.sheet: list[np.ndarray] = []
        self.ref_s = 0.0
        if synth is None or not (cap.root / capture_name("gt_parts")).is_file():
            self.why = "no synthetic reference (the scene is not procedural or has no GT parts)"
            return
        gt = read_parts(cap.root / capture_name("gt_parts"))
        match = match_parts(parts, gt)
        self.pairs = {match.pred[i].id: match.gt[j] for i, j, _ in match.correct}
        if not self.pairs:
            self.why = "no predicted part matches a GT part of its kind"
            return
        from drawer_lib.metrics.opened import SynthReference

        t0 = time.perf_counter()
        self.ref = SynthReference(synth, cams, render_cfg)
        self.ref_s += time.perf_counter() - t0

    def add(self, pid: str, q: float, views: list) -> None:
        g: Part | None = self.pairs.get(pid)
        if self.ref is None or g is None:
            return
        t0 = time.perf_counter()
        qg = float(np.clip(q, *g.limits))
        gv = self.ref.views(g.id, qg)
        regions = [(v.part_alpha.numpy() > 0.5) | mask for v, (_, mask) in zip(views, gv)]
        s = _score([v.rgb for v in views], [rgb for rgb, _ in gv], regions, self.rc.lpips)
        self.rows.append({"id": pid, "gt": g.id, "q": q, "gt_q": qg, **s})
        best = int(np.argmax([r.sum() for r in regions]))
        w = self.rc.sheet_width
        self.sheet.append(np.concatenate([_tile((gv[best][0].numpy() * 255).astype(np.uint8), w),
                                          _tile((views[best].rgb.numpy() * 255).astype(np.uint8), w)], 1))
        self.ref_s += time.perf_counter() - t0

    def close(self) -> None:
        if self.ref is not None:
            self.ref.close()

    def finish(self, m: dict) -> None:
        run = self.run
        if self.why is not None:
            run.skip("open_psnr", self.why)
            return
        m["reference_s"] = round(self.ref_s, 3)
        rows = self.rows
        for key in ("psnr", "ssim", "lpips"):
            vals = [x for r in rows for x in r.get(key, [])]
            if vals:
                m[f"open_{key}"] = float(np.mean(vals))
        reg = [x for r in rows for x in r["region_psnr"] if x is not None]
        if reg:
            m["open_region_psnr"] = float(np.mean(reg))
        m["n_parts_scored_open"] = len(rows)
        write_json(run.out("render_scores"), {"parts": rows})
        if self.sheet:
            Image.fromarray(np.concatenate(self.sheet, 0)).save(run.out("contact_sheet"))
