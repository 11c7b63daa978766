#!/usr/bin/env python
"""The built-in detector's fit on each ``--device`` in each ``--memory-format``, side by side in
one run: the same views, seed and settings (conf/detector/, ``detector.*`` overrides with
``--set``), ``--steps`` steps of the fit on each, its seconds per step (the first ``--warmup``
steps not timed), the first and last losses, and the projected time of the configured whole
fit (``detector.steps`` + ``detector.average_steps``).

    python scripts/bench_detector_device.py --kitchens 0 1 2 3 --save-views /tmp/views.npz   # render only
    python scripts/bench_detector_device.py --views /tmp/views.npz --device cpu cuda --steps 300
    python scripts/bench_detector_device.py --kitchens 0 1 --device cpu --steps 50 --set batch=4
    python scripts/bench_detector_device.py --views /tmp/views.npz --memory-format contiguous channels_last

Views are the train split's kitchens (the generator's renders: simulated input), every
``detector.frame_every``-th frame, as the ``detector_fit`` stage renders them; ``--save-views``
writes them (uint8 images and classes) so a machine without the renderer can time the fit.
"""

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

import drawer_lib  # noqa: F401  (before torch: the OpenMP policy)
import torch

from drawer_lib.config.compose import compose_config
from drawer_lib.devices import device_name
from drawer_lib.detect.builtin import MEMORY_FORMATS
from drawer_lib.detect.data import View
from drawer_lib.detect.train import Sample, fit_views, fit_detector, stage_inputs, to_sample
from drawer_lib.errors import ConfigError
from drawer_lib.runner import StageRun

ROOT = Path(__file__).resolve().parent.parent


def load_views(path: Path, size: int) -> list[Sample]:
    """The views :func:`main` saved (``--save-views``) as training samples at ``size``."""
    d = np.load(path)
    n = sum(k.startswith("rgb_") for k in d.files)
    return [to_sample(View(d[f"rgb_{i}"], d[f"classes_{i}"], np.zeros(d[f"classes_{i}"].shape, np.int32)), size)
            for i in range(n)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kitchens", type=int, nargs="+", default=[0, 1, 2, 3], help="train-split kitchens to render")
    ap.add_argument("--views", type=Path, help="views written by --save-views (no rendering)")
    ap.add_argument("--save-views", type=Path, help="render, write the views there, stop")
    ap.add_argument("--device", nargs="+", default=["cpu"], help="devices to fit on, in this order")
    ap.add_argument("--memory-format", nargs="+", default=None, choices=sorted(MEMORY_FORMATS),
                    help="the network's memory formats to fit in, each on every device (default: detector.memory_format)")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--warmup", type=int, default=10, help="first steps not timed (allocation, kernel choice)")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="detector.* overrides (Hydra syntax)")
    ap.add_argument("--out", type=Path, help="write the table as JSON here")
    a = ap.parse_args()
    cfg = compose_config(ROOT / "conf", ["scene=kitchen_small"] + [f"detector.{kv}" for kv in a.set])
    try:
        tc, base, render = stage_inputs(cfg)
    except ConfigError as e:
        raise SystemExit(f"error: {e}") from None
    if a.views:
        samples = load_views(a.views, tc.working_size)
    else:
        views = fit_views(tc, base, render, "train", a.kitchens, StageRun("bench", Path("."), Path("."), 0))
        if a.save_views:
            np.savez_compressed(a.save_views, **{f"rgb_{i}": v.rgb for i, v in enumerate(views)},
                                **{f"classes_{i}": v.classes for i, v in enumerate(views)})
            print(f"{len(views)} views of kitchens {a.kitchens} -> {a.save_views}")
            return
        samples = [to_sample(v, tc.working_size) for v in views]
    whole = tc.steps + tc.average_steps
    rows = []
    for dev, fmt in [(d, f) for d in a.device for f in (a.memory_format or [tc.memory_format])]:
        times: list[float] = []

        def timed(it, **kw):
            for x in it:
                times.append(time.perf_counter())
                yield x
            times.append(time.perf_counter())

        c = dataclasses.replace(tc, device=dev, steps=a.steps, log_every=1, checkpoint_every=0, memory_format=fmt)
        try:
            _, losses = fit_detector(samples, c, seed=0, progress=timed)
        except ConfigError as e:
            raise SystemExit(f"error: {e}") from None
        dt = np.diff(times)[a.warmup:]
        s_step = float(np.median(dt))
        rows.append({"device": device_name(dev), "memory_format": fmt, "threads": torch.get_num_threads(), "views": len(samples),
                     "steps": a.steps, "s_per_step_median": round(s_step, 5), "s_per_step_mean": round(float(dt.mean()), 5),
                     "loss_first": round(losses[0], 4), "loss_last": round(losses[-1], 4),
                     "whole_fit_train_min": round(whole * s_step / 60, 2)})
        print(json.dumps(rows[-1]), flush=True)
    print(f"\n{'device':32s} {'memory format':>14s} {'s/step':>9s} {'fit of ' + str(whole) + ' steps':>18s} {'loss first -> last':>20s}")
    for r in rows:
        print(f"{r['device']:32s} {r['memory_format']:>14s} {r['s_per_step_median']:9.4f} {r['whole_fit_train_min']:15.1f} min "
              f"{r['loss_first']:9.4f} -> {r['loss_last']:.4f}")
    if a.out:
        a.out.write_text(json.dumps({"argv": sys.argv[1:], "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
