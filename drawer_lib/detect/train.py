"""The built-in detector's fit (the ``detector`` stage): views of the train split's kitchens,
Adam on random crops with class-balanced cross-entropy, then the 2D instance precision and recall
of its fronts on the test split's kitchens, which it never saw."""

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from drawer_lib.bench.scenes import kitchen_scene
from drawer_lib.detect.builtin import CLASSES, MEAN, STD, DetectorEnsemble, TinyUNet, class_probs, decode_instances, normalise, resize_mask, save_detector, working_shape
from drawer_lib.detect.config import BuiltinDetectConfig, DetectorTrainConfig
from drawer_lib.detect.data import View, render_views
from drawer_lib.errors import ConfigError, InputError, NonFiniteError
from drawer_lib.metrics.detections import match_fronts
from drawer_lib.paths import bench_name
from drawer_lib.runner import Curve, StageRun
from drawer_lib.synth.config import LAYOUT_KEYS, RenderConfig


@dataclass
class Sample:
    x: torch.Tensor  # [3, h, w] normalised RGB at the working size
    y: torch.Tensor  # [h, w] int64 classes


def to_sample(v: View, size: int) -> Sample:
    H, W = v.classes.shape
    h, w = working_shape(H, W, size)
    x = normalise(v.rgb)[None]
    y = torch.as_tensor(v.classes.astype(np.int64))[None, None].float()
    if (h, w) != (H, W):
        x = F.interpolate(x, size=(h, w), mode="bilinear", align_corners=False, antialias=True)
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


def fit_detector(samples: list[Sample], cfg: DetectorTrainConfig, seed: int, curve: Curve | None = None,
                 progress: Callable = lambda it, **kw: it, curve_extra: dict | None = None
                 ) -> tuple[TinyUNet, list[float]]:
    """Train a :class:`TinyUNet` on ``samples``; returns it (in eval mode) and the loss of every
    ``log_every``-th step (logged to ``curve`` with the values of ``curve_extra``)."""
    if not samples:
        raise InputError("detector: no training views (detector.kitchens rendered nothing)")
    torch.manual_seed(seed)
    g = torch.Generator().manual_seed(seed)
    model = TinyUNet(cfg.width)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=cfg.steps, pct_start=0.1)
    weight = class_weights(samples)
    losses = []
    model.train()
    for step in progress(range(1, cfg.steps + 1), desc="train", total=cfg.steps):
        x, y = _crop_batch(samples, cfg.batch, cfg.crop, g, cfg.color_jitter, cfg.scale_jitter)
        loss = F.cross_entropy(model(x), y, weight=weight, ignore_index=-100)
        if not torch.isfinite(loss):
            raise NonFiniteError(f"detector: loss {float(loss)} at step {step}")
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        if step % cfg.log_every == 0 or step == cfg.steps:
            losses.append(loss.item())
            if curve is not None:
                curve.log(step, loss=losses[-1], **(curve_extra or {}))
    return model.eval(), losses


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
        for s in samples:
            p = model(s.x[None])[0].argmax(0)
            ok += int((p == s.y).sum())
            n += s.y.numel()
    return ok / max(n, 1)


def run_train_detector(cfg: DetectorTrainConfig, base_scene: dict, render: RenderConfig, seed: int,
                       run: StageRun) -> dict:
    """Render the train split's kitchens ``cfg.kitchens``, fit the built-in detector (``cfg.members``
    fits from seeds ``seed``, ``seed + 1``, ...: one ensemble), write ``weights.pt`` and
    ``curve.csv`` (loss against time; with several fits a ``member`` column), and score it on
    the train views and on the test split's kitchens ``cfg.eval_kitchens`` (with several fits,
    each fit on the latter too)."""
    unknown = set(cfg.layout) - LAYOUT_KEYS
    if unknown:
        raise ConfigError(f"detector.layout: unknown keys {sorted(unknown)} (the fields of a scene's synth.layout)")

    def views(split: str, kitchens: list[int]) -> list:
        out = []
        for k in run.progress(kitchens, desc=f"render {split}", total=len(kitchens)):
            synth = kitchen_scene(base_scene, split, k, layout=cfg.layout if split == "train" else None).synth
            frames = list(range(0, synth.camera.n_frames, cfg.frame_every))
            out += list(render_views(synth, render, frames, cfg.edge_px))
        return out

    t0 = time.perf_counter()
    train_views = views("train", cfg.kitchens)
    test_views = views("test", cfg.eval_kitchens)
    render_s = time.perf_counter() - t0
    samples = [to_sample(v, cfg.working_size) for v in train_views]
    t1 = time.perf_counter()
    curve = run.curve(["loss"] if cfg.members == 1 else ["member", "loss"])
    fits = [fit_detector(samples, cfg, seed + k, curve, run.progress, None if cfg.members == 1 else {"member": k})
            for k in range(cfg.members)]
    nets = [net for net, _ in fits]
    train_s = time.perf_counter() - t1
    dc = BuiltinDetectConfig(working_size=cfg.working_size)
    save_detector(run.dir / bench_name("detector_weights"), nets,
                  {"train_kitchens": list(cfg.kitchens), "working_size": cfg.working_size, "steps": cfg.steps})
    model = nets[0] if cfg.members == 1 else DetectorEnsemble(nets).eval()
    m = {"train_views": len(train_views), "test_views": len(test_views), "render_s": round(render_s, 2),
         "train_s": round(train_s, 2), "final_loss": round(float(np.mean([losses[-1] for _, losses in fits])), 4),
         "pixel_accuracy_train": round(pixel_accuracy(model, samples), 4),
         "pixel_accuracy_test": round(pixel_accuracy(model, [to_sample(v, cfg.working_size) for v in test_views]), 4)}
    for split, vs in (("train", train_views), ("test", test_views)):
        s = score_views(model, vs, dc, cfg.iou_match)
        m[f"fronts_2d_precision_{split}"] = s["precision"]
        m[f"fronts_2d_recall_{split}"] = s["recall"]
    if cfg.members > 1:
        m["members"] = cfg.members
        each = [score_views(net, test_views, dc, cfg.iou_match) for net in nets]
        m["fronts_2d_precision_test_members"] = [s["precision"] for s in each]
        m["fronts_2d_recall_test_members"] = [s["recall"] for s in each]
    return m

