"""What the ``appearance`` stage does: one variant of the ablation on one scene."""

import time
from pathlib import Path

import numpy as np

from drawer_lib.errors import InputError, InvariantError
from drawer_lib.io.capture import Capture
from drawer_lib.io.images import write_rgb
from drawer_lib.io.mesh import load_mesh
from drawer_lib.paths import LAYOUT
from drawer_lib.perturb import displace_along_normals
from drawer_lib.runner import StageRun
from drawer_lib.splat.anchored import anchored_gaussians, bound_activity
from drawer_lib.splat.config import AppearanceConfig
from drawer_lib.splat.ply import write_face_binding, write_gaussian_ply
from drawer_lib.splat.train import (EvalResult, bounds_report, evaluate_images, prepare, render_test, textured_mesh,
                                    train_factor, train_gaussians)


def _write_renders(d: Path, cap: Capture, res: EvalResult) -> None:
    d.mkdir()
    for i, img in zip(cap.test, res.renders):
        write_rgb(d / f"{cap.frames[i].stem}.png", (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8))


def run_appearance(cfg: AppearanceConfig, cap: Capture, mesh_path: Path, run: StageRun,
                   field_path: Path | None = None) -> dict:
    """Train (or bake) one variant of the ablation on the mesh at ``mesh_path`` and write its
    model, test renders and metrics; ``field_path``: the neural SDF whose colour head the
    textured mesh bakes (``texture_source: sdf``)."""
    mesh = load_mesh(mesh_path, "run the mesh stage first")
    t0 = time.perf_counter()
    m: dict = {"variant": cfg.variant}
    disp = cfg.anchor_displacement
    if disp.rms_m > 0:  # a robustness study: a controlled error of the anchor mesh
        mesh, d = displace_along_normals(mesh, disp.rms_m, disp.wavelength_m, disp.seed)
        m["anchor_displacement_rms_m"] = round(float(np.sqrt(np.mean(d ** 2))), 6)
    sc = prepare(cap, mesh, cfg)
    prep_s = time.perf_counter() - t0
    m.update({"mesh_faces": len(sc.mesh.faces), "prepare_s": round(prep_s, 3), "train_scale": train_factor(cap, cfg),
              "working_size": [sc.train_cams[0].intrinsics.width, sc.train_cams[0].intrinsics.height]})
    model = run.out("model")
    model.mkdir()
    curve = run.curve(["test_psnr", "n_gaussians"])
    if cfg.variant == "textured_mesh":
        field = None
        if cfg.texture_source == "sdf":
            from drawer_lib.sdf.io import load_field

            lf = load_field(field_path)
            if lf.field is None:
                raise InputError(f"{field_path}: a {lf.kind} field has no colour; set appearance.texture_source: images")
            field = lf.field
        res, info, colored = textured_mesh(cap, sc, cfg, field)
        colored.export(run.dir / LAYOUT["appearance"]["textured_mesh"])
        m.update(info)
        m["train_s"] = info["bake_s"]
        curve.log(0, wall_s=info["bake_s"], test_psnr=res.psnr)  # one point, like the TSDF's
        run.skip("gaussians", "textured_mesh renders the mesh with baked colours; no Gaussians")
    else:

        def on_eval(step, train_s, p, frames):
            pred = render_test(p, frames, cfg, sc)
            r = evaluate_images(pred, sc.test_rgb, with_lpips=False)
            curve.log(step, wall_s=train_s, test_psnr=r.psnr, n_gaussians=float(p.face.shape[0]))
            run.progress_write(f"step {step}: {train_s:.0f} s, test PSNR {r.psnr:.2f} dB, {p.face.shape[0]} Gaussians")

        st = train_gaussians(cap, sc, cfg, run.seed, run.progress, on_eval)
        res = evaluate_images(render_test(st.params, st.frames, cfg, sc), sc.test_rgb)
        violation = bounds_report(st.params, st.frames, cfg)
        if cfg.clip != "free" and violation is not None:
            raise InvariantError(f"appearance {cfg.variant}: {violation} (clip = {cfg.clip} must keep every "
                                 "Gaussian in its face bounds)")
        a = anchored_gaussians(st.params, st.frames, cfg.bounds, cfg.clip)
        write_gaussian_ply(run.dir / LAYOUT["appearance"]["gaussians"], a.gaussians)
        write_face_binding(run.dir / LAYOUT["appearance"]["binding"], st.params.face, st.frames.face_ids, a.pos2d, a.elevate)
        sc.mesh.export(run.dir / LAYOUT["appearance"]["anchor_mesh"])
        m.update({"n_gaussians": int(st.params.face.shape[0]), "steps": st.steps, "train_s": round(st.train_s, 3),
                  "stopped_by_time": st.stopped_by_time,
                  "within_budget": st.train_s <= cfg.budget_s, "within_face_bounds": violation is None, **st.counts})
        if cfg.clip != "free":  # where the clips act at the end (hard: zero gradient there; ste: identity)
            m.update({f"at_bound_{k}": round(v, 4) for k, v in bound_activity(st.params, st.frames, cfg.bounds).items()})
    _write_renders(run.out("renders"), cap, res)
    m.update({"psnr": res.psnr, "ssim": res.ssim, "lpips": res.lpips})
    return m
