"""Training of mesh-anchored Gaussians (and the textured-mesh baseline) on a capture."""

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import trimesh
from jaxtyping import Float

from drawer_lib.errors import ConfigError, InputError, NonFiniteError
from drawer_lib.geometry.camera import Camera
from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.io.capture import Capture
from drawer_lib.io.working import scale_intrinsics, working_factor
from drawer_lib.metrics.image import image_scores, psnr, ssim, ssim_target_stats
from drawer_lib.paths import capture_name
from drawer_lib.splat.anchored import AnchoredParams, FaceFrames, anchored_gaussians, bounds_violation, face_frames, init_anchored
from drawer_lib.splat.config import AppearanceConfig
from drawer_lib.splat.mesh_color import (colored_mesh_at_resolution, face_colors, mesh_depths, render_face_colored,
                                         to_tensor_images)
from drawer_lib.splat.losses import appearance_losses, total_loss
from drawer_lib.splat.render import RenderOutput, render

EVAL_BG = np.array([0.149, 0.1647, 0.2157])  # DRAWER's evaluation background


def decimate(mesh: trimesh.Trimesh, max_faces: int) -> trimesh.Trimesh:
    """``mesh`` simplified to at most ``max_faces`` faces (one Gaussian per face) by PyMeshLab's
    quadric collapse: the appearance variants' results were measured with it, and the mesh
    stage's faster default has been benchmarked for the mesh stage only (docs/speed.md)."""
    if len(mesh.faces) <= max_faces:
        return mesh
    from drawer_lib.mesh.clean import CleanConfig, clean_mesh

    out, _ = clean_mesh(mesh, CleanConfig(min_component_diag=0.0, target_faces=max_faces, decimator="pymeshlab"))
    return out


@dataclass
class Scene:
    """What training and evaluation need, prepared once."""

    mesh: trimesh.Trimesh
    rc: Raycaster
    train_cams: list[Camera]
    test_cams: list[Camera]
    train_rgb: torch.Tensor  # [C, H, W, 3]
    test_rgb: torch.Tensor
    train_mesh_depth: torch.Tensor  # [C, H, W]
    test_mesh_depth: np.ndarray


def downscale_camera(cam: Camera, f: int) -> Camera:
    """The camera of an image box-filtered by ``f`` x ``f`` (after cropping its right / bottom
    to a multiple of ``f``): exact in the pixel-centre convention of :class:`~drawer_lib.geometry.camera.Intrinsics`."""
    return cam if f == 1 else Camera(scale_intrinsics(cam.intrinsics, f), cam.w2c)


def downscale_images(images: Float[torch.Tensor, "C H W 3"], f: int) -> Float[torch.Tensor, "C h w 3"]:
    """Box filter by ``f`` x ``f``: [C, H, W, 3] -> [C, H // f, W // f, 3] (right / bottom
    remainders cropped)."""
    if f == 1:
        return images
    C, H, W, _ = images.shape
    h, w = H // f, W // f
    if h == 0 or w == 0:
        raise ConfigError(f"appearance.train_scale = {f} is larger than the images ({W} x {H})")
    return images[:, : h * f, : w * f].reshape(C, h, f, w, f, 3).mean((2, 4))


def train_factor(cap: Capture, cfg: AppearanceConfig) -> int:
    """The train images' box-filter factor: ``cfg.train_scale``, or the larger working factor
    that brings their longer side to at most ``cfg.max_side`` (:mod:`drawer_lib.io.working`)."""
    return max(cfg.train_scale, working_factor(cap.intrinsics.width, cap.intrinsics.height, cfg.max_side))


def prepare(cap: Capture, mesh: trimesh.Trimesh, cfg: AppearanceConfig) -> Scene:
    """Decimate the anchor mesh, load the train / test views (train views box-filtered by
    :func:`train_factor`, each as it is read; test views always full size) and the mesh's depth
    in each."""
    if len(mesh.faces) == 0:
        raise InputError("appearance: the mesh is empty")
    if not cap.test:
        raise InputError(f"{cap.root / capture_name('transforms')}: no test frames to evaluate on")
    m = decimate(mesh, cfg.max_faces)
    rc = Raycaster(np.asarray(m.vertices), np.asarray(m.faces))
    f = train_factor(cap, cfg)
    train_cams = [downscale_camera(c, f) for c in cap.cameras(cap.train)]
    w_tr = np.stack([c.w2c for c in train_cams])
    w_te = np.stack([cap.frames[i].w2c for i in cap.test])
    train_rgb = torch.cat([downscale_images(to_tensor_images(cap.image(i)[None]), f) for i in cap.train])
    return Scene(m, rc, train_cams, cap.cameras(cap.test), train_rgb,
                 to_tensor_images(np.stack([cap.image(i) for i in cap.test])),
                 torch.from_numpy(mesh_depths(rc, train_cams[0].intrinsics, w_tr)),
                 mesh_depths(rc, cap.intrinsics, w_te))


@dataclass
class EvalResult:
    psnr: float
    ssim: float
    lpips: float
    renders: np.ndarray  # [T, H, W, 3] in [0, 1]


def evaluate_images(pred: torch.Tensor, gt: torch.Tensor, with_lpips: bool = True) -> EvalResult:
    """Mean PSNR / SSIM / LPIPS (docs/formats.md#nvs) of predictions [T, H, W, 3] against GT
    (:func:`~drawer_lib.metrics.image.image_scores`, in chunks)."""
    s = image_scores(pred, gt, with_lpips)
    lp = float(s["lpips"].mean()) if with_lpips else float("nan")
    return EvalResult(float(s["psnr"].mean()), float(s["ssim"].mean()), lp, pred.numpy())


@torch.no_grad()
def field_colors(field, points: np.ndarray, normals: np.ndarray, chunk: int = 65536) -> np.ndarray:
    """Colour [F, 3] of a neural SDF's colour head at surface points seen along -normal."""
    out = []
    for x, n in zip(torch.tensor(points, dtype=torch.float32).split(chunk),
                    torch.tensor(normals, dtype=torch.float32).split(chunk)):
        out.append(field(x, -n, with_grad=False)[2])
    return torch.cat(out).clamp(0, 1).numpy().astype(np.float64)


def textured_mesh(cap: Capture, sc: Scene, cfg: AppearanceConfig, field=None) -> tuple[EvalResult, dict, trimesh.Trimesh]:
    """The baseline: the mesh split to ``texture_cell`` resolution, one colour per face (from
    the SDF's colour head, or from the train views), rendered (ray cast) at the test views."""
    t0 = time.perf_counter()
    fine = colored_mesh_at_resolution(sc.mesh, cfg.texture_cell)
    rc = Raycaster(np.asarray(fine.vertices), np.asarray(fine.faces))
    it = sc.train_cams[0].intrinsics  # the train views' (train_scale)
    cnt = np.ones(len(fine.faces))
    if cfg.texture_source == "sdf":
        if field is None:
            raise InputError("appearance.texture_source = sdf needs a neural SDF field with a colour head (the sdf "
                             "stage's field of a neural run); use texture_source: images for a TSDF")
        cols = field_colors(field, np.asarray(fine.triangles_center), np.asarray(fine.face_normals))
    else:
        w_tr = np.stack([c.w2c for c in sc.train_cams])
        depth = mesh_depths(rc, it, w_tr)
        cols, cnt = face_colors(np.asarray(fine.triangles_center), sc.train_rgb.numpy(), it, w_tr, depth)
    bake_s = time.perf_counter() - t0
    renders = torch.from_numpy(np.stack([render_face_colored(rc, cols, c.intrinsics, c.w2c, EVAL_BG)
                                         for c in sc.test_cams]))
    info = {"texture_faces": len(fine.faces), "texture_cell_m": cfg.texture_cell, "texture_source": cfg.texture_source,
            "faces_unseen": int((cnt == 0).sum()), "bake_s": round(bake_s, 3)}
    fine.visual.face_colors = np.concatenate([(cols * 255 + 0.5).astype(np.uint8), np.full((len(cols), 1), 255, np.uint8)], 1)
    return evaluate_images(renders, sc.test_rgb), info, fine


@dataclass
class TrainState:
    params: AnchoredParams
    frames: FaceFrames
    steps: int
    train_s: float
    stopped_by_time: bool
    counts: dict


def _optimizer(p: AnchoredParams, cfg: AppearanceConfig) -> torch.optim.Adam:
    lr = cfg.lr
    rates = {"means_2d": lr.position, "elevate": lr.position, "log_scales": lr.scales, "angles": lr.angles,
             "sh_dc": lr.sh_dc, "sh_rest": lr.sh_rest, "opacity_logit": lr.opacity}
    groups = []
    for name, t in p.trainable().items():
        frozen = cfg.static and name in ("means_2d", "elevate")
        par = torch.nn.Parameter(t.detach().clone(), requires_grad=not frozen)
        setattr(p, name, par)
        if not frozen:
            groups.append({"params": [par], "lr": rates[name], "name": name})
    return torch.optim.Adam(groups, eps=1e-15, fused=True)


def render_params(p: AnchoredParams, frames: FaceFrames, cfg: AppearanceConfig, cam: Camera, sh_degree: int,
                  bg: torch.Tensor) -> tuple[RenderOutput, torch.Tensor]:
    a = anchored_gaussians(p, frames, cfg.bounds, cfg.clip)
    return render(a.gaussians, cam, sh_degree, bg, tile=cfg.tile, backend=cfg.backend), a.scales


def train_gaussians(cap: Capture, sc: Scene, cfg: AppearanceConfig, seed: int, progress: Callable = lambda it, **kw: it,
                    on_eval: Callable[[int, float, AnchoredParams, FaceFrames], None] | None = None) -> TrainState:
    gen = torch.Generator().manual_seed(seed)
    torch.manual_seed(seed)
    V = torch.tensor(np.asarray(sc.mesh.vertices), dtype=torch.float32)
    Fc = torch.tensor(np.asarray(sc.mesh.faces), dtype=torch.long)
    frames = face_frames(V, Fc)
    if frames.A.shape[0] == 0:
        raise InputError("appearance: the mesh has no face with a non-zero area")
    it = sc.train_cams[0].intrinsics
    w_tr = np.stack([c.w2c for c in sc.train_cams])
    cols, _ = face_colors(frames.centroid.double().numpy(), sc.train_rgb.numpy(), it, w_tr, sc.train_mesh_depth.numpy())
    p = init_anchored(frames, torch.tensor(cols, dtype=torch.float32), cfg.sh_degree, cfg.init_opacity)
    opt = _optimizer(p, cfg)
    strat = cfg.strategy
    state = strat.initialize_state() if strat is not None else None
    w = cfg.losses
    n_img = len(sc.train_cams)
    size = max(it.width, it.height)
    with torch.no_grad():  # the D-SSIM target's local mean / variance, once per train image
        gt_stats = [ssim_target_stats(im.permute(2, 0, 1)[None]) for im in sc.train_rgb]
    train_s, stopped, step = 0.0, False, 0
    counts = {"split": 0, "dup": 0, "culled": 0}
    for step in progress(range(cfg.steps), desc="train", total=cfg.steps):
        t0 = time.perf_counter()
        k = int(torch.randint(0, n_img, (1,), generator=gen))
        bg = torch.rand(3, generator=gen)
        deg = min(step // cfg.sh_every, cfg.sh_degree)
        out, scales = render_params(p, frames, cfg, sc.train_cams[k], deg, bg)
        terms = appearance_losses(out, sc.train_rgb[k], scales, step, w, gt_stats[k], sc.train_mesh_depth[k])
        loss = total_loss(terms, w)
        if not torch.isfinite(loss):
            bad = [name for name, v in terms.items() if not torch.isfinite(v)]
            raise NonFiniteError(f"appearance: loss terms {bad} are not finite at step {step}")
        opt.zero_grad(set_to_none=True)
        loss.backward()
        if strat is not None:
            strat.step_post_backward(state, out.absgrad_cpu(), out.radii.cpu(), size)
        frac = min(step / max(cfg.steps - 1, 1), 1.0)
        for g in opt.param_groups:
            if g["name"] in ("means_2d", "elevate"):
                g["lr"] = cfg.lr.position * (cfg.lr.position_final / cfg.lr.position) ** frac
        opt.step()
        if strat is not None:
            r = strat.step_post_optimizer(state, step, p, frames, scales, opt, gen, allow_split=not cfg.static)
            for kk in counts:
                counts[kk] += r[kk]
        train_s += time.perf_counter() - t0
        if on_eval is not None and step > 0 and step % cfg.eval_every == 0:
            on_eval(step, train_s, p, frames)
        if cfg.max_seconds is not None and train_s > cfg.max_seconds:
            stopped = True
            break
    steps_done = step + 1
    if on_eval is not None:
        on_eval(steps_done, train_s, p, frames)
    return TrainState(p, frames, steps_done, train_s, stopped, counts)


@torch.no_grad()
def render_test(p: AnchoredParams, frames: FaceFrames, cfg: AppearanceConfig, sc: Scene) -> torch.Tensor:
    bg = torch.tensor(EVAL_BG, dtype=torch.float32)
    return torch.stack([render_params(p, frames, cfg, c, cfg.sh_degree, bg)[0].rgb for c in sc.test_cams])


def bounds_report(p: AnchoredParams, frames: FaceFrames, cfg: AppearanceConfig) -> str | None:
    """None when every Gaussian is within its face bounds, else the first violation."""
    return bounds_violation(anchored_gaussians(p, frames, cfg.bounds, cfg.clip), p, frames, cfg.bounds)
