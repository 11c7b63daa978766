#!/usr/bin/env python
"""A phone's LiDAR depth brought to its RGB's size: nearest (nerfstudio's) against the
edge-aware upsampling of :mod:`drawer_lib.io.rgbd`, on synthetic kitchens rendered with
exact depth, the depth sampled as the sensor does (one sample per ``--factor`` x ``--factor``
cell: the mean of its central 2 x 2 pixels). ``kitchen_tiny`` is the scene the defaults were
chosen on; the others are held out. Reports per scene the mean absolute error over the pixels
with a depth (every method gives depth to the same pixels) and the fractions of pixels more
than 2 and 5 cm off, averaged over every third frame, and the wall time per frame.

    python scripts/bench_rgbd.py                          # kitchen_tiny, kitchen_small
    python scripts/bench_rgbd.py --scenes kitchen_medium --factor 8

Writes ``<out>/summary.json`` and prints a table. Simulated input: rendered depth, exact.
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig, SceneConfig
from drawer_lib.config.compose import compose_config
from drawer_lib.config.typed import to_typed
from drawer_lib.io.capture import load_capture
from drawer_lib.io.rgbd import upsample_depth

ROOT = Path(__file__).resolve().parents[1]

METHODS = {
    "nearest": {"method": "nearest"},
    "edge_aware (pick only)": {"method": "edge_aware", "same_surface": 0.0},
    "edge_aware (default)": {"method": "edge_aware"},
}


def sensor(depth: np.ndarray, s: int) -> np.ndarray:
    c = s // 2
    return (depth[c - 1::s, c - 1::s] + depth[c - 1::s, c::s] + depth[c::s, c - 1::s] + depth[c::s, c::s]) / 4


def capture_of(scene: str, out: Path) -> Path:
    d = out / scene
    if not (d / "transforms.json").is_file():
        cfg = compose_config(ROOT / "conf", [f"scene={scene}", "capture/depth=exact", "capture/mono=off",
                                             "capture/detections=off"])
        d.mkdir(parents=True, exist_ok=True)
        build_capture(scene, to_typed(SceneConfig, cfg.scene, f"scene {scene}"),
                      to_typed(CaptureConfig, cfg.capture, "capture"), d, np.random.default_rng(0), ROOT)
    return d


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["kitchen_tiny", "kitchen_small"])
    ap.add_argument("--factor", type=int, default=4, help="RGB size / depth size (4: 256x192 beside 1024x768)")
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_rgbd"))
    a = ap.parse_args()
    summary = {"factor": a.factor, "scenes": {}}
    for scene in a.scenes:
        cap = load_capture(capture_of(scene, a.out))
        rows: dict[str, list] = {m: [] for m in METHODS}
        for k in range(0, len(cap.frames), 3):
            z, rgb = cap.depth(k), cap.image(k)
            H, W = (np.array(z.shape) // a.factor) * a.factor  # a whole number of sensor cells
            z, rgb = z[:H, :W], rgb[:H, :W]
            lo = sensor(z, a.factor)
            for name, kw in METHODS.items():
                t0 = time.perf_counter()
                up = upsample_depth(lo, z.shape, rgb, **kw)
                dt = time.perf_counter() - t0
                ok = (up > 0) & (z > 0)
                e = np.abs(up - z)[ok]
                rows[name].append((e.mean(), np.mean(e > 0.02), np.mean(e > 0.05), dt))
        res = {m: dict(zip(("mae_m", "frac_2cm", "frac_5cm", "s_per_frame"), np.mean(v, 0).round(5).tolist()))
               for m, v in rows.items()}
        summary["scenes"][scene] = {"size": [cap.intrinsics.width, cap.intrinsics.height],
                                    "frames": len(rows["nearest"]), "tuned_on": scene == "kitchen_tiny", **res}
        print(f"\n{scene} ({cap.intrinsics.width}x{cap.intrinsics.height}, depth 1/{a.factor}, "
              f"{'tuned on' if scene == 'kitchen_tiny' else 'held out'})")
        print(f"| method | MAE (cm) | > 2 cm | > 5 cm | s / frame |\n|---|---|---|---|---|")
        for m, r in res.items():
            print(f"| {m} | {100 * r['mae_m']:.2f} | {100 * r['frac_2cm']:.1f} % | {100 * r['frac_5cm']:.1f} % | "
                  f"{r['s_per_frame']:.3f} |")
    (a.out / "summary.json").write_text(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
