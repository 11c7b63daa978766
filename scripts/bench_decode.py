#!/usr/bin/env python
"""The built-in detector's decoding compared on rendered views: each ``--variant`` (a set of
``detect.builtin`` keys) decodes the same per-pixel probabilities into instance masks, scored
against the renderer's true fronts (2D precision / recall at IoU ``--iou``, as the ``detector``
stage scores its fit). The network runs once per view; only the decoding varies.

    python scripts/bench_decode.py --split train --kitchens $(seq 16 31) --every 3 \\
        --variant "core_handle=false merge_edge=0" --variant "merge_edge=0" --variant ""
    python scripts/bench_decode.py --split test --kitchens 0 1 2 3 4 5 --every 2 --variant "core_handle=false merge_edge=0" --variant ""
    python scripts/bench_decode.py --kitchens $(seq 16 31) --layout 'module_widths=[0.6, 0.9]' --variant "merge_edge=0.7" --variant ""
        # a stress variant of the same kitchens (other layout keys, as scripts/bench_detect.py --layout)

Tune on the train split's kitchens 16-31 (the fit uses 0-15 and 32-79); score on the test split.
Simulated input: the generator's renders.
"""

import argparse
import dataclasses
from pathlib import Path

from omegaconf import OmegaConf

import drawer_lib  # noqa: F401  (before torch: the OpenMP policy)
from drawer_lib.bench.cli import parse_layout
from drawer_lib.bench.scenes import kitchen_scene
from drawer_lib.config.compose import compose_config
from drawer_lib.config.typed import to_typed
from drawer_lib.detect.builtin import class_probs, load_detector
from drawer_lib.detect.config import BuiltinDetectConfig, DetectorTrainConfig
from drawer_lib.detect.data import render_views
from drawer_lib.detect.train import score_probs
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.paths import BenchPaths
from drawer_lib.synth.config import RenderConfig

ROOT = Path(__file__).resolve().parent.parent


def parse_variant(text: str, base: BuiltinDetectConfig) -> BuiltinDetectConfig:
    """``base`` with the ``key=value`` pairs of ``text`` (space separated) replaced."""
    fields = {f.name: f.type for f in dataclasses.fields(BuiltinDetectConfig)}
    over = {}
    for kv in text.split():
        k, _, v = kv.partition("=")
        if k not in fields or not v:
            raise SystemExit(f"error: --variant {text!r}: {kv!r} is not KEY=VALUE of detect.builtin ({', '.join(fields)})")
        over[k] = v.lower() in ("1", "true", "yes") if fields[k] in (bool, "bool") else type(getattr(base, k))(v)
    try:
        return dataclasses.replace(base, **over)
    except ConfigError as e:
        raise SystemExit(f"error: --variant {text!r}: {e}") from None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--split", default="train", choices=["train", "test", "hand_tune"])
    ap.add_argument("--kitchens", type=int, nargs="+", default=list(range(16, 32)))
    ap.add_argument("--every", type=int, default=3, help="every n-th view of each kitchen's camera path")
    ap.add_argument("--weights", type=Path, nargs="+", default=[BenchPaths(ROOT / "bench").detector_weights],
                    help="the detector stage's weights; several files: their fits as one ensemble")
    ap.add_argument("--variant", action="append", default=None, metavar="'KEY=VALUE ...'",
                    help="detect.builtin keys over conf/detect's (repeat; '' is the configured decoding)")
    ap.add_argument("--iou", type=float, default=0.5)
    ap.add_argument("--layout", nargs="*", default=[], metavar="KEY=VALUE",
                    help="keys of each kitchen's layout block over its split's, values in YAML (a stress variant)")
    a = ap.parse_args()
    layout = parse_layout(a.layout)
    cfg = compose_config(ROOT / "conf", ["scene=kitchen_small"])
    base = to_typed(BuiltinDetectConfig, cfg.detect.builtin, "detect.builtin")
    variants = [(v, parse_variant(v, base)) for v in (a.variant or [""])]
    try:
        model, _ = load_detector(a.weights)
    except InputError as e:
        raise SystemExit(f"error: {e}") from None
    render = to_typed(RenderConfig, cfg.capture.render, "capture.render")
    edge_px = to_typed(DetectorTrainConfig, cfg.detector, "detector").edge_px
    scene = OmegaConf.to_container(cfg.scene, resolve=True)
    views = []
    for k in a.kitchens:
        synth = kitchen_scene(scene, a.split, k, layout=layout or None).synth
        frames = list(range(0, synth.camera.n_frames, a.every))
        views += [(class_probs(model, v.rgb, base.working_size), v.fronts) for v in render_views(synth, render, frames, edge_px)]
        print(f"{a.split} kitchen {k}: {len(views)} views", flush=True)
    where = f"{a.split} kitchens {a.kitchens[0]}..{a.kitchens[-1]}" + (f" ({' '.join(a.layout)})" if a.layout else "")
    print(f"\n| {where}, one view in {a.every} | 2D precision | 2D recall | matched / predicted / true |")
    print("|---|---|---|---|")
    for text, dc in variants:
        s = score_probs(views, dc, a.iou)
        print(f"| {text or 'configured'} | {s['precision']} | {s['recall']} | {s['fronts_matched']} / {s['fronts_pred']} / {s['fronts_true']} |")


if __name__ == "__main__":
    main()
