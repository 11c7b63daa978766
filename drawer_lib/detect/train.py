"""The built-in detector's fit (the ``detector_fit@<seed>`` stages): views of the train split's
kitchens, Adam on random crops with class-balanced cross-entropy, then the 2D instance precision
and recall of its fronts on the test split's kitchens, which it never saw; and the fits of
``detector.seeds`` as the one detector later stages read (the ``detector`` stage)."""

import copy
import dataclasses
import hashlib
import json
import shutil
import sys
import time
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from omegaconf import OmegaConf
from torch.optim.swa_utils import AveragedModel

from drawer_lib.bench.scenes import kitchen_scene
from drawer_lib.config.typed import to_typed
from drawer_lib.detect.builtin import CLASSES, MEAN, STD, DetectorEnsemble, TinyUNet, class_probs, decode_instances, load_detector, model_device, network_input, resize_mask, save_detector, working_shape
from drawer_lib.detect.config import BuiltinDetectConfig, DetectorTrainConfig
from drawer_lib.detect.data import View, render_views
from drawer_lib.devices import cuda_numerics, device_name, torch_device
from drawer_lib.errors import ConfigError, InputError, NonFiniteError
from drawer_lib.io.atomic import atomic_open
from drawer_lib.metrics.detections import match_fronts
from drawer_lib.paths import BENCH, LAYOUT, bench_name
from drawer_lib.runner import Curve, StageRun, deferred_interrupts
from drawer_lib.synth.config import LAYOUT_KEYS, RenderConfig


@dataclass
class Sample:
    x: torch.Tensor  # [3, h, w] normalised RGB at the working size
    y: torch.Tensor  # [h, w] int64 classes


def to_sample(v: View, size: int) -> Sample:
    H, W = v.classes.shape
    h, w = working_shape(H, W, size)
    x = network_input(v.rgb, size)
    y = torch.as_tensor(v.classes.astype(np.int64))[None, None].float()
    if (h, w) != (H, W):
        y = F.interpolate(y, size=(h, w), mode="nearest")
    return Sample(x[0], y[0, 0].long())


def _crop_batch(samples: list[Sample], batch: int, crop: int, g: torch.Generator, color_jitter: float = 0.0,
                scale_jitter: float = 1.0) -> tuple[torch.Tensor, torch.Tensor]:
    """``batch`` random ``crop``² crops ([B, 3, crop, crop] inputs, [B, crop, crop] classes, -100
    where padded): flipped at random, exposure jittered by ±15 %; with ``color_jitter`` c each
    channel's gain and the contrast drawn from 1 ± c/2 (a front's colour the train kitchens never
    showed); with ``scale_jitter`` s > 1 the crop covers crop × [1/s, s] pixels, resized to
    ``crop`` (bilinear images, nearest classes: fronts nearer or farther than rendered)."""
    mean_rgb, std_rgb = torch.tensor(MEAN)[:, None, None], torch.tensor(STD)[:, None, None]
    xs, ys = [], []
    for _ in range(batch):
        s = samples[int(torch.randint(len(samples), (1,), generator=g))]
        h, w = s.y.shape
        size = crop
        if scale_jitter > 1:
            size = round(crop * float(scale_jitter ** (2 * torch.rand((), generator=g) - 1)))
        ch, cw = min(size, h), min(size, w)
        i = int(torch.randint(h - ch + 1, (1,), generator=g))
        j = int(torch.randint(w - cw + 1, (1,), generator=g))
        x, y = s.x[:, i:i + ch, j:j + cw], s.y[i:i + ch, j:j + cw]
        if size != crop:
            f = crop / size
            ch, cw = min(crop, max(1, round(ch * f))), min(crop, max(1, round(cw * f)))
            x = F.interpolate(x[None], size=(ch, cw), mode="bilinear", align_corners=False, antialias=f < 1)[0]
            y = F.interpolate(y[None, None].float(), size=(ch, cw), mode="nearest")[0, 0].long()
        if (ch, cw) != (crop, crop):  # a small image: padded (ignored in the loss)
            x = F.pad(x, (0, crop - cw, 0, crop - ch))
            y = F.pad(y, (0, crop - cw, 0, crop - ch), value=-100)
        if bool(torch.rand((), generator=g) < 0.5):
            x, y = x.flip(-1), y.flip(-1)
        gain = 1.0 + 0.3 * (torch.rand((), generator=g) - 0.5)  # exposure jitter
        x = x * gain
        if color_jitter > 0:
            rgb = x * std_rgb + mean_rgb
            rgb = rgb * (1.0 + color_jitter * (torch.rand(3, 1, 1, generator=g) - 0.5))
            grey = rgb.mean()
            rgb = grey + (rgb - grey) * (1.0 + color_jitter * (torch.rand((), generator=g) - 0.5))
            x = (rgb - mean_rgb) / std_rgb
        xs.append(x)
        ys.append(y)
    return torch.stack(xs), torch.stack(ys)


def class_weights(samples: list[Sample]) -> torch.Tensor:
    """Inverse square-root frequency weights, normalised to mean 1 (rare edges and handles count)."""
    counts = torch.zeros(len(CLASSES))
    for s in samples:
        counts += torch.bincount(s.y.reshape(-1), minlength=len(CLASSES)).float()
    w = 1.0 / torch.sqrt(counts.clamp_min(1.0))
    return w / w.mean()


def _train_step(model: TinyUNet, opt: torch.optim.Optimizer, samples: list[Sample], cfg: DetectorTrainConfig,
                g: torch.Generator, weight: torch.Tensor, step: int) -> float:
    """One step of Adam on a batch of crops (:func:`_crop_batch`, drawn on the CPU from ``g``
    whatever the device, so every device sees the same crops) on ``weight``'s device; returns
    its loss (a :class:`NonFiniteError` if it is not finite)."""
    x, y = _crop_batch(samples, cfg.batch, cfg.crop, g, cfg.color_jitter, cfg.scale_jitter)
    loss = F.cross_entropy(model(x.to(weight.device)), y.to(weight.device), weight=weight, ignore_index=-100)
    if not torch.isfinite(loss):
        raise NonFiniteError(f"detector: loss {float(loss)} at step {step}")
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()
    return loss.item()


def fit_fingerprint(samples: list[Sample], cfg: DetectorTrainConfig, seed: int) -> str:
    """What a fit's saved state must agree with to be gone on from: the fit's settings (every
    ``detector`` key a fit reads), ``seed``, the torch version, and the number and the sums of
    the training views' inputs and classes (sha256, hex)."""
    keys = {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg) if f.name not in cfg.NOT_FIT_KEYS}
    x = sum(float(s.x.double().sum()) for s in samples)
    y = sum(int(s.y.sum()) for s in samples)
    blob = json.dumps({"cfg": keys, "seed": seed, "torch": torch.__version__, "views": len(samples),
                       "x": f"{x:.9e}", "y": y}, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def _load_state(path: Path, fingerprint: str, what: str = "fitting") -> dict | None:
    """The saved state at ``path`` when it belongs to this run (its fingerprint), else ``None``
    (a stale or unreadable one is reported and ignored: ``what`` starts afresh)."""
    if not path.is_file():
        return None
    try:
        state = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as e:  # noqa: BLE001  (a truncated or foreign file: start afresh, say so)
        print(f"[detector] {path}: unreadable saved state ({e.__class__.__name__}), {what} from step 0", file=sys.stderr)
        return None
    if not isinstance(state, dict) or state.get("fingerprint") != fingerprint:
        print(f"[detector] {path}: saved by a fit with other settings or views, {what} from step 0", file=sys.stderr)
        return None
    return state


def _restore(state: dict, g: torch.Generator, **objects) -> list[tuple]:
    """Load a saved state (:func:`_load_state`) into ``objects`` (name in the state -> a module or
    optimiser), the crop generator ``g`` and torch's random stream; returns the logged rows."""
    for name, obj in objects.items():
        obj.load_state_dict(state[name])
    g.set_state(state["generator"])
    torch.set_rng_state(state["torch_rng"])
    return [tuple(r) for r in state["rows"]]


def _run_steps(start: int, total: int, take_step: Callable[[int], None], save: Callable[[int], None] | None,
               checkpoint_every: int, progress: Callable, desc: str, where: Path | None = None) -> None:
    """``take_step(step)`` for steps ``start`` .. ``total`` under ``progress``. With ``save`` (a
    run that can be gone on from): ``save(step)`` every ``checkpoint_every`` steps (0: never),
    at an interrupt (Ctrl-C, SIGTERM, SIGHUP: held to the end of the step in progress,
    :func:`~drawer_lib.runner.deferred_interrupts`; a second signal within a step leaves the
    last periodic save) when ``checkpoint_every`` > 0, and after the last step, which keeps a
    finished run for its caller to drop (:func:`drop_fit_state`). The interrupt is re-raised."""
    done, in_step = start - 1, False
    try:
        with deferred_interrupts() if save is not None else nullcontext([]) as pending:
            for step in progress(range(start, total + 1), desc=desc, total=total, initial=start - 1):
                in_step = True
                take_step(step)
                done, in_step = step, False
                if pending:
                    raise KeyboardInterrupt(f"signal {pending[0]}")
                if save is not None and checkpoint_every and step % checkpoint_every == 0 and step < total:
                    save(step)
    except KeyboardInterrupt:
        # between two steps (a signal held to the step's end, or the progress bar's iterator):
        # this step's state; within one (a second signal): the last periodic save stands
        if save is not None and checkpoint_every and done >= start and not in_step:
            save(done)
            print(f"[detector] interrupted: {desc} step {done} of {total} kept in {where}; rerun to go on",
                  file=sys.stderr)
        raise
    if save is not None and done == total and start <= total:
        save(done)


def fit_detector(samples: list[Sample], cfg: DetectorTrainConfig, seed: int, curve: Curve | None = None,
                 progress: Callable = lambda it, **kw: it, resume: Path | None = None) -> tuple[TinyUNet, list[float]]:
    """Train a :class:`TinyUNet` on ``samples``; returns it (in eval mode) and the loss of every
    ``log_every``-th step (logged to ``curve``).

    ``resume``: where the fit keeps its state (model, Adam, the one-cycle schedule, the crop
    generator's and torch's random state, the losses logged so far with their times) every
    ``cfg.checkpoint_every`` steps and when interrupted (Ctrl-C, SIGTERM, SIGHUP: held to the end
    of the step in progress, :func:`~drawer_lib.runner.deferred_interrupts`): a later call with the
    same settings, seed and views (:func:`fit_fingerprint`) goes on from the saved step to the
    same weights, bit for bit on the same machine and threads, as a fit never stopped; its
    ``curve`` gets the earlier rows again first. A finished fit leaves its last state there (a
    rerun returns its weights without a step) for the caller to remove with
    :func:`drop_fit_state` once what it makes of the fit is written.

    ``cfg.device``: where the network trains (``cpu``, ``cuda``); it starts from the same
    weights and sees the same crops on every device, and comes back on the CPU."""
    if not samples:
        raise InputError("detector: no training views (detector.kitchens rendered nothing)")
    dev = train_device(cfg)
    torch.manual_seed(seed)
    g = torch.Generator().manual_seed(seed)
    model = TinyUNet(cfg.width, memory_format=cfg.memory_format).to(dev)  # initialised on the CPU from ``seed``, then moved
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=cfg.steps, pct_start=0.1)
    weight = class_weights(samples).to(dev)
    rows: list[tuple[int, float, float]] = []  # (step, wall_s, loss) as logged
    fingerprint = fit_fingerprint(samples, cfg, seed) if resume is not None else ""
    state = _load_state(resume, fingerprint) if resume is not None else None
    start, wall0 = 1, 0.0
    if state is not None:
        rows = _restore(state, g, model=model, opt=opt, sched=sched)
        start, wall0 = state["step"] + 1, state["wall_s"]
        print(f"[detector] going on from step {state['step']} of {cfg.steps} ({resume})", file=sys.stderr)
        if curve is not None:
            for step, wall_s, loss in rows:
                curve.log(step, wall_s=wall_s, loss=loss)
    t0 = time.perf_counter()

    def save(step: int) -> None:
        with atomic_open(resume) as f:  # a kill mid-write leaves the last whole state
            torch.save({"fingerprint": fingerprint, "step": step, "wall_s": wall0 + time.perf_counter() - t0,
                        "model": model.state_dict(), "opt": opt.state_dict(), "sched": sched.state_dict(),
                        "generator": g.get_state(), "torch_rng": torch.get_rng_state(), "rows": rows}, f)

    def take_step(step: int) -> None:
        loss = _train_step(model, opt, samples, cfg, g, weight, step)
        sched.step()
        if step % cfg.log_every == 0 or step == cfg.steps:
            rows.append((step, wall0 + time.perf_counter() - t0, loss))
            if curve is not None:
                curve.log(step, wall_s=rows[-1][1], loss=loss)

    model.train()
    with cuda_numerics(dev):
        _run_steps(start, cfg.steps, take_step, save if resume is not None else None, cfg.checkpoint_every,
                   progress, "train", resume)
    return model.cpu().eval(), [r[2] for r in rows]


def drop_fit_state(resume: Path) -> None:
    """Remove a finished fit's or averaging's saved state (:func:`fit_detector`'s or
    :func:`average_fit`'s ``resume``) and its folder when no other state is left in it. Called
    once the stage's outputs are in place: a kill between the last step and that moment costs a
    rerun no step."""
    resume.unlink(missing_ok=True)
    if resume.parent.is_dir() and not any(resume.parent.iterdir()):
        resume.parent.rmdir()


def average_fingerprint(model: TinyUNet, samples: list[Sample], cfg: DetectorTrainConfig, seed: int) -> str:
    """What an averaging's saved state must agree with to be gone on from: the fit's
    (:func:`fit_fingerprint` of ``samples``), the averaging's settings and the weights it
    starts from (sha256, hex)."""
    h = hashlib.sha256(fit_fingerprint(samples, cfg, seed).encode())
    h.update(json.dumps([cfg.average_steps, cfg.average_lr, cfg.average_warmup]).encode())
    for k, v in model.state_dict().items():
        h.update(k.encode() + b"\0" + v.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


def average_state_path(fit_resume: Path) -> Path:
    """Where the ``detector`` stage's averaging of a fit keeps its state: beside the fit's own
    (``detector_fit_resume/<seed>.pt`` -> ``detector_fit_resume/<seed>.average.pt``)."""
    return Path(fit_resume).with_suffix(".average.pt")


def average_fit(model: TinyUNet, samples: list[Sample], cfg: DetectorTrainConfig, seed: int,
                curve: Curve | None = None, progress: Callable = lambda it, **kw: it,
                resume: Path | None = None) -> TinyUNet:
    """Stochastic weight averaging after a fit (Izmailov et al. 2018; densely, every step, as
    SWAD, Cha et al. 2021, for unseen domains): ``cfg.average_steps`` further steps on
    ``samples`` from ``model``'s weights, Adam afresh with its rate raised linearly to
    ``cfg.average_lr`` over ``cfg.average_warmup`` steps and then held, and the uniform mean of
    the weights over every step after the warm-up. Returns that mean as a new :class:`TinyUNet`
    (eval mode; ``model`` is left as it was); its loss every ``log_every``-th step goes to
    ``curve`` (columns ``seed``, ``loss``).

    ``resume``: as :func:`fit_detector`'s (the network, the running mean and its count, Adam,
    the random streams, the losses logged), every ``cfg.checkpoint_every`` steps, at an
    interrupt and at the end; a later call with the same fit, settings, seed and views
    (:func:`average_fingerprint`) goes on to the same mean, bit for bit on the same machine and
    threads. The caller removes it (:func:`drop_fit_state`) once the detector is written."""
    if cfg.average_steps <= cfg.average_warmup:
        raise ValueError(f"average_fit: {cfg.average_steps} steps do not pass the warm-up of {cfg.average_warmup}")
    if not samples:
        raise InputError("detector: no training views to average over (detector.kitchens rendered nothing)")
    dev = train_device(cfg)
    g = torch.Generator().manual_seed(seed)
    net = copy.deepcopy(model).to(dev).train()
    avg = AveragedModel(net, use_buffers=True)  # the first update sets it to the weights of that step
    opt = torch.optim.Adam(net.parameters(), lr=cfg.average_lr)
    weight = class_weights(samples).to(dev)
    rows: list[tuple[int, float]] = []  # (step, loss) as logged
    fingerprint = average_fingerprint(model, samples, cfg, seed) if resume is not None else ""
    state = _load_state(resume, fingerprint, "averaging") if resume is not None else None
    start = 1
    if state is not None:
        rows = _restore(state, g, net=net, avg=avg, opt=opt)
        start = state["step"] + 1
        print(f"[detector] averaging fit {seed}: going on from step {state['step']} of {cfg.average_steps} ({resume})",
              file=sys.stderr)
        if curve is not None:
            for step, loss in rows:
                curve.log(step, seed=seed, loss=loss)

    def save(step: int) -> None:
        with atomic_open(resume) as f:
            torch.save({"fingerprint": fingerprint, "step": step, "net": net.state_dict(), "avg": avg.state_dict(),
                        "opt": opt.state_dict(), "generator": g.get_state(), "torch_rng": torch.get_rng_state(),
                        "rows": rows}, f)

    def take_step(step: int) -> None:
        for group in opt.param_groups:
            group["lr"] = cfg.average_lr * min(1.0, step / max(cfg.average_warmup, 1))
        loss = _train_step(net, opt, samples, cfg, g, weight, step)
        if step > cfg.average_warmup:
            avg.update_parameters(net)
        if step % cfg.log_every == 0 or step == cfg.average_steps:
            rows.append((step, loss))
            if curve is not None:
                curve.log(step, seed=seed, loss=loss)

    with cuda_numerics(dev):
        _run_steps(start, cfg.average_steps, take_step, save if resume is not None else None, cfg.checkpoint_every,
                   progress, f"average fit {seed}", resume)
    out = TinyUNet(model.width, memory_format=model.memory_format)
    out.load_state_dict(avg.module.state_dict())
    return out.eval()


def score_views(model: TinyUNet | DetectorEnsemble, views: list[View], dc: BuiltinDetectConfig, iou: float) -> dict:
    """2D instance precision / recall of the detector's fronts over ``views`` (at the views' size)."""
    return score_probs([(class_probs(model, v.rgb, dc.working_size), v.fronts) for v in views], dc, iou)


def score_probs(views: list[tuple[np.ndarray, np.ndarray]], dc: BuiltinDetectConfig, iou: float) -> dict:
    """:func:`score_views` of probabilities already computed: ``views`` holds per view the
    class probabilities [C, h, w] at the working size and the true front ids [H, W] (id + 1, 0
    elsewhere), so decodings (``dc``) are compared without running the network again."""
    tp = n_pred = n_true = 0
    for prob, fronts in views:
        H, W = fronts.shape
        masks = [resize_mask(d.mask, H, W) for d in decode_instances(prob, dc) if d.label == "front"]
        a, b, c = match_fronts(masks, fronts, dc.min_area_px, iou)
        tp, n_pred, n_true = tp + a, n_pred + b, n_true + c
    return {"precision": round(tp / n_pred, 4) if n_pred else None, "recall": round(tp / n_true, 4) if n_true else None,
            "views": len(views), "fronts_true": n_true, "fronts_pred": n_pred, "fronts_matched": tp}


def pixel_accuracy(model: TinyUNet | DetectorEnsemble, samples: list[Sample]) -> float:
    with torch.inference_mode():
        ok = n = 0
        dev = model_device(model)
        for s in samples:
            p = model(s.x[None].to(dev))[0].argmax(0).cpu()
            ok += int((p == s.y).sum())
            n += s.y.numel()
    return ok / max(n, 1)


def stage_inputs(cfg) -> tuple[DetectorTrainConfig, dict, RenderConfig]:
    """What the detector's stages read from their Hydra config ``cfg``: the fit's settings
    (``detector``, its layout keys and device checked here, before a stage makes its folder),
    the benchmark's base scene (``scene``, resolved) and the renderer's (``capture.render``)."""
    tc = to_typed(DetectorTrainConfig, cfg.detector, "detector")
    check_layouts(tc)
    train_device(tc)
    return tc, OmegaConf.to_container(cfg.scene, resolve=True), to_typed(RenderConfig, cfg.capture.render, "capture.render")


def fit_views(cfg: DetectorTrainConfig, base_scene: dict, render: RenderConfig, split: str, kitchens: list[int],
               run: StageRun, extra_layout: dict | None = None) -> list[View]:
    """Every ``cfg.frame_every``-th view of ``split``'s kitchens, rendered and labelled (the
    train split's with ``cfg.layout``, then ``extra_layout``, merged over each kitchen's; never
    the scored ones)."""
    if split != "train" and extra_layout:
        raise ValueError(f"fit_views: a layout over the {split} split's kitchens")
    layout = {**cfg.layout, **(extra_layout or {})} if split == "train" else None
    out = []
    for k in run.progress(kitchens, desc=f"render {split}", total=len(kitchens)):
        synth = kitchen_scene(base_scene, split, k, layout=layout).synth
        frames = list(range(0, synth.camera.n_frames, cfg.frame_every))
        out += list(render_views(synth, render, frames, cfg.edge_px))
    return out


def train_device(cfg: DetectorTrainConfig) -> torch.device:
    """Where the detector's stages run the network (``detector.device``), checked: a
    :class:`ConfigError` when this machine cannot (:func:`~drawer_lib.devices.torch_device`)."""
    return torch_device(cfg.device, "detector.device", "use detector.device: cpu")


def check_layouts(cfg: DetectorTrainConfig) -> None:
    """A :class:`ConfigError` naming any key of ``cfg.layout`` or ``cfg.average_layout`` that is
    not a field of a kitchen's layout block, before a stage does any work."""
    for name in ("layout", "layout_beside", "average_layout"):
        unknown = set(getattr(cfg, name)) - LAYOUT_KEYS
        if unknown:
            raise ConfigError(f"detector.{name}: unknown keys {sorted(unknown)} (the fields of a scene's synth.layout)")


def fit_decoding(cfg: DetectorTrainConfig) -> BuiltinDetectConfig:
    """The fixed decoding the fits and the ``detector`` stage are scored with (the library's
    defaults at the fit's working size), so their figures do not move when ``detect.builtin`` does."""
    return BuiltinDetectConfig(working_size=cfg.working_size)


def fit_info(cfg: DetectorTrainConfig) -> dict:
    """What a fit's ``weights.pt`` records of the settings it was made with (its ``info``), which
    the ``detector`` stage holds against ``detector.*`` before using the fit."""
    return {"train_kitchens": list(cfg.kitchens), "working_size": cfg.working_size, "steps": cfg.steps}


def run_fit_detector(cfg: DetectorTrainConfig, base_scene: dict, render: RenderConfig, seed: int,
                     run: StageRun, resume: Path | None = None) -> dict:
    """One fit of the built-in detector (the ``detector_fit@<seed>`` stage): render the train
    split's kitchens ``cfg.kitchens``, fit from ``seed``, write ``weights.pt`` and ``curve.csv``
    (loss against training time), and score it on the train views and on the test split's kitchens
    ``cfg.eval_kitchens``, which it never saw. ``resume``: where an interrupted fit keeps its
    state and a rerun goes on from it (:func:`fit_detector`); still there when this returns, for
    the caller to drop once the stage's outputs are in place (:func:`drop_fit_state`)."""
    check_layouts(cfg)
    dev = train_device(cfg)
    t0 = time.perf_counter()
    train_views = fit_views(cfg, base_scene, render, "train", cfg.kitchens, run)
    n_drawn = len(train_views)
    if cfg.layout_beside:  # the same kitchens once more, as layout_beside draws them
        train_views += fit_views(cfg, base_scene, render, "train", cfg.kitchens, run, cfg.layout_beside)
    test_views = fit_views(cfg, base_scene, render, "test", cfg.eval_kitchens, run)
    render_s = time.perf_counter() - t0
    samples = [to_sample(v, cfg.working_size) for v in train_views]
    t1 = time.perf_counter()
    model, losses = fit_detector(samples, cfg, seed, run.curve(["loss"]), run.progress, resume)
    train_s = time.perf_counter() - t1
    dc = fit_decoding(cfg)
    save_detector(run.dir / BENCH["detector_fit_weights"], model, fit_info(cfg))
    model.to(dev)  # scored where it was fitted
    m = {"device": device_name(dev), "train_views": len(train_views), "test_views": len(test_views),
         **({"layout_beside": dict(cfg.layout_beside), "layout_beside_views": len(train_views) - n_drawn}
            if cfg.layout_beside else {}),
         "render_s": round(render_s, 2), "train_s": round(train_s, 2), "final_loss": round(losses[-1], 4),
         "pixel_accuracy_train": round(pixel_accuracy(model, samples), 4),
         "pixel_accuracy_test": round(pixel_accuracy(model, [to_sample(v, cfg.working_size) for v in test_views]), 4)}
    for split, vs in (("train", train_views), ("test", test_views)):
        s = score_views(model, vs, dc, cfg.iou_match)
        m[f"fronts_2d_precision_{split}"] = s["precision"]
        m[f"fronts_2d_recall_{split}"] = s["recall"]
    return m


def run_combine_detector(cfg: DetectorTrainConfig, base_scene: dict, render: RenderConfig, fit_dirs: list[Path],
                         run: StageRun, resume: list[Path] | None = None) -> dict:
    """The built-in detector the later stages read (the ``detector`` stage): the fits of
    ``cfg.seeds`` (``fit_dirs``, one ``detector_fit@<seed>`` folder each, in that order) as one
    ``weights.pt``, each fit's weights averaged over ``cfg.average_steps`` further steps first
    (:func:`average_fit`, its loss in ``curve.csv``) when that is > 0 (on the train kitchens'
    views, and with ``cfg.average_layout`` on those kitchens rendered once more with it). One
    fit, not averaged:
    its file, copied byte for byte, and its figures. Otherwise one file
    (:func:`~drawer_lib.detect.builtin.save_detector`; several fits an ensemble), scored again
    on the test split's kitchens ``cfg.eval_kitchens``, with each fit's own figures beside it.
    A missing fit, or one fitted with other settings than ``cfg``, is an :class:`InputError`
    naming it. ``resume`` (one path per seed): where each fit's averaging keeps its state
    (:func:`average_fit`), for the caller to drop once the stage's outputs are in place."""
    check_layouts(cfg)
    dev = train_device(cfg)
    if len(fit_dirs) != len(cfg.seeds):
        raise ValueError(f"run_combine_detector: {len(fit_dirs)} fit folders for detector.seeds = {list(cfg.seeds)}")
    want = fit_info(cfg)
    fits = []
    for seed, d in zip(cfg.seeds, fit_dirs):
        w, mp = Path(d) / BENCH["detector_fit_weights"], Path(d) / LAYOUT["metrics"]
        if not w.is_file() or not mp.is_file():
            raise InputError(f"{d}: the detector's fit from seed {seed} is missing (run `dvc repro detector_fit@{seed}`)")
        _, info = load_detector(w)
        got = {k: info.get(k) for k in want}
        if got != want:
            raise InputError(f"{w}: fitted with {got}, but detector.* asks for {want} (run `dvc repro detector_fit@{seed}`)")
        fits.append((w, json.loads(mp.read_text())))
    dst = run.dir / bench_name("detector_weights")
    curve = run.curve(["seed", "loss"])  # the averaging's loss; only its header when there is none
    if len(fits) == 1 and not cfg.average_steps:  # its figures; this stage's run writes its own wall_s, peak_rss_mb and threads over the fit's
        shutil.copyfile(fits[0][0], dst)
        return {"seeds": list(cfg.seeds), "average_steps": 0, **fits[0][1]}
    model, _ = load_detector([w for w, _ in fits])
    members = [model] if isinstance(model, TinyUNet) else list(model.members)
    info = {**want, "seeds": list(cfg.seeds)}
    m = {"seeds": list(cfg.seeds), "average_steps": cfg.average_steps}
    if cfg.average_steps:
        t0 = time.perf_counter()
        samples = [to_sample(v, cfg.working_size) for v in fit_views(cfg, base_scene, render, "train", cfg.kitchens, run)]
        m["train_views"] = len(samples)
        if cfg.average_layout:  # the same kitchens once more, as average_layout draws them
            samples += [to_sample(v, cfg.working_size)
                        for v in fit_views(cfg, base_scene, render, "train", cfg.kitchens, run, cfg.average_layout)]
            m["average_layout"], m["average_layout_views"] = dict(cfg.average_layout), len(samples) - m["train_views"]
        m["render_train_s"] = round(time.perf_counter() - t0, 2)
        t1 = time.perf_counter()
        if resume is not None and len(resume) != len(cfg.seeds):
            raise ValueError(f"run_combine_detector: {len(resume)} resume paths for detector.seeds = {list(cfg.seeds)}")
        members = [average_fit(net, samples, cfg, seed, curve, run.progress, resume[i] if resume is not None else None)
                   for i, (net, seed) in enumerate(zip(members, cfg.seeds))]
        m["average_s"] = round(time.perf_counter() - t1, 2)
        info["average"] = {"steps": cfg.average_steps, "lr": cfg.average_lr, "warmup": cfg.average_warmup,
                           **({"layout": dict(cfg.average_layout)} if cfg.average_layout else {})}
    save_detector(dst, members[0] if len(members) == 1 else members, info)
    model = (members[0] if len(members) == 1 else DetectorEnsemble(members)).to(dev)
    m["device"] = device_name(dev)
    t0 = time.perf_counter()
    test_views = fit_views(cfg, base_scene, render, "test", cfg.eval_kitchens, run)
    m["render_s"] = round(time.perf_counter() - t0, 2)
    s = score_views(model, test_views, fit_decoding(cfg), cfg.iou_match)
    return {**m, "test_views": len(test_views),
            "pixel_accuracy_test": round(pixel_accuracy(model, [to_sample(v, cfg.working_size) for v in test_views]), 4),
            "fronts_2d_precision_test": s["precision"], "fronts_2d_recall_test": s["recall"],
            "fronts_2d_precision_test_members": [f.get("fronts_2d_precision_test") for _, f in fits],
            "fronts_2d_recall_test_members": [f.get("fronts_2d_recall_test") for _, f in fits]}


def run_score_detector(cfg: DetectorTrainConfig, dc: BuiltinDetectConfig, base_scene: dict, render: RenderConfig,
                       weights: Path, run: StageRun) -> dict:
    """The detector later stages read (``weights``, the ``detector`` stage's file) scored as they
    decode it (the ``detector_score`` stage): 2D instance precision / recall of its fronts on the
    test split's kitchens ``cfg.eval_kitchens`` (every ``cfg.frame_every``-th view, matched at IoU
    ``cfg.iou_match``) decoded with ``dc`` (``detect.builtin``), and beside it with the fixed
    decoding the fits are scored with (:func:`fit_decoding`), both from
    one pass of the network. A decoding change reruns this stage only, never a fit. A missing
    file, or one made at another working size than ``dc``'s, is an :class:`InputError`."""
    if not Path(weights).is_file():
        raise InputError(f"{weights}: the built-in detector is missing (run `dvc repro detector`)")
    model, info = load_detector(weights)
    if info.get("working_size") != dc.working_size:
        raise InputError(f"{weights}: fitted at working size {info.get('working_size')}, but detect.builtin.working_size "
                         f"= {dc.working_size}")
    dev = train_device(cfg)
    model.to(dev)
    t0 = time.perf_counter()
    views = fit_views(cfg, base_scene, render, "test", cfg.eval_kitchens, run)
    render_s = time.perf_counter() - t0
    t1 = time.perf_counter()
    probs = [(class_probs(model, v.rgb, dc.working_size), v.fronts)
             for v in run.progress(views, desc="detect test views", total=len(views))]
    infer_s = time.perf_counter() - t1
    used = score_probs(probs, dc, cfg.iou_match)
    fit = score_probs(probs, fit_decoding(cfg), cfg.iou_match)
    return {"device": device_name(dev), "eval_kitchens": list(cfg.eval_kitchens), "test_views": len(views),
            "render_s": round(render_s, 2),
            "infer_s": round(infer_s, 2), "merge_edge": dc.merge_edge,
            "fronts_2d_precision_test": used["precision"], "fronts_2d_recall_test": used["recall"],
            "fronts_true": used["fronts_true"], "fronts_pred": used["fronts_pred"], "fronts_matched": used["fronts_matched"],
            "fronts_2d_precision_test_fit_decoding": fit["precision"], "fronts_2d_recall_test_fit_decoding": fit["recall"],
            "fronts_pred_fit_decoding": fit["fronts_pred"], "fronts_matched_fit_decoding": fit["fronts_matched"]}
