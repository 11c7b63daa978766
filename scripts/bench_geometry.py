#!/usr/bin/env python
"""Benchmark of the geometry components on a capture (default: out/kitchen_small/capture, made by
`dvc repro capture@kitchen_small`). Prints, side by side in one run:

- the grid encoding's forward+backward, numba kernels vs the PyTorch reference (same output);
- one neural-SDF training step (render 1024 rays, all losses, backward, Adam);
- TSDF fusion of exact depth (if --exact-capture is given) and of the capture's sensor depth,
  with Chamfer-L1 / F@2cm of the mesh against gt/mesh.ply;
- the photometric calibration of the monocular depth: time and depth error against GT depth.

The full comparison (neural SDF with sensor depth, neural SDF with RGB + monocular priors, TSDF;
curves against time) is the pipeline itself: `dvc repro geometry_table` -> reports/geometry/.

    python scripts/bench_geometry.py [--capture out/kitchen_small/capture] [--exact-capture DIR]
"""

import argparse
import time
from pathlib import Path

import numpy as np

import drawer_lib  # noqa: F401, I001  (before torch: the library's OpenMP wait policy, as a stage runs)
import torch
import trimesh

from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.io.capture import load_capture
from drawer_lib.io.manifest import read_manifest
from drawer_lib.mesh.config import MeshConfig
from drawer_lib.mesh.pipeline import extract_mesh
from drawer_lib.metrics.geometry import MeshEvaluator
from drawer_lib.sdf.config import NeuralConfig, TsdfConfig
from drawer_lib.sdf.encoding import MultiResGrid
from drawer_lib.sdf.io import LoadedField
from drawer_lib.sdf.monocal import calibrate_mono_depth
from drawer_lib.sdf.rays import focus_depth
from drawer_lib.sdf.tsdf import fuse_tsdf


def timeit(fn, repeat=5, warmup=2):
    for _ in range(warmup):
        fn()
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def bench_encoding(n=24_576):
    e = NeuralConfig().encoding
    lo, hi = torch.tensor([-2.0, -1.5, -0.3]), torch.tensor([4.7, 0.4, 2.9])
    grids = {b: MultiResGrid(lo, hi, e.levels, e.features, e.cell_coarse, e.cell_fine, e.log2_table, backend=b)
             for b in ("numba", "torch")}
    grids["torch"].load_state_dict(grids["numba"].state_dict())
    x = lo + torch.rand(n, 3) * (hi - lo)
    out = {}
    for b, g in grids.items():
        def step():
            f, df = g(x, with_grad=True)
            (f.sum() + df.sum()).backward()
        out[b] = timeit(step)
    fa = grids["numba"](x, with_grad=True)[0]
    fb = grids["torch"](x, with_grad=True)[0]
    print(f"encoding fwd+bwd ({n} points, {e.levels} levels, with d/dx): numba {1000 * out['numba']:.1f} ms, "
          f"torch {1000 * out['torch']:.1f} ms -> {out['torch'] / out['numba']:.1f}x; max |diff| "
          f"{float((fa - fb).detach().abs().max()):.2e}")


def bench_train_step(cap, manifest):
    from drawer_lib.sdf.train import train_neural_sdf

    for steps in (20, 60):
        cfg = NeuralConfig(steps=steps, eval_every=10**9)
        t = time.perf_counter()
        r = train_neural_sdf(cap, manifest, cfg, 0)
        print(f"neural SDF, {steps} steps: train {r.train_s:.1f} s ({steps / r.train_s:.1f} it/s), "
              f"wall incl. set-up {time.perf_counter() - t:.1f} s")


def bench_tsdf(cap, ev, label):
    t = time.perf_counter()
    g = fuse_tsdf(cap, cap.train, TsdfConfig())
    fuse = time.perf_counter() - t
    mesh = extract_mesh(MeshConfig(), LoadedField("grid", g.sdf, g.lo, g.hi, {}, grid=g), cap)
    total = time.perf_counter() - t
    r = ev(mesh)
    print(f"TSDF 2 cm, {label}: fuse {fuse:.2f} s, fuse+mesh {total:.2f} s, Chamfer-L1 {1000 * r['chamfer_l1']:.2f} mm, "
          f"F@1cm {r['fscore_1cm']:.3f}, F@2cm {r['fscore_2cm']:.3f}")


def bench_monocal(cap, gt):
    fr = cap.train
    imgs = torch.tensor(np.stack([cap.image(i) for i in fr]), dtype=torch.float32) / 255
    mono = torch.tensor(np.stack([cap.mono_depth(i) for i in fr]))
    c2w = torch.tensor(np.stack([cap.frames[i].c2w for i in fr]), dtype=torch.float32)
    f = focus_depth(c2w[:, :3, 3].numpy(), c2w[:, :3, 2].numpy())
    t = time.perf_counter()
    res = calibrate_mono_depth(imgs, mono, cap.intrinsics, c2w, f, NeuralConfig().monocal)
    dt = time.perf_counter() - t
    rc = Raycaster(np.asarray(gt.vertices), np.asarray(gt.faces))
    err = []
    for k, i in enumerate(fr):
        z = rc.depth_normals(cap.intrinsics, cap.frames[i].w2c)[0]
        ok = z > 0
        err.append(np.abs(res.depth[k].numpy()[ok] - z[ok]))
    e = np.concatenate(err)
    print(f"mono calibration ({len(fr)} frames): {dt:.1f} s, |z - z_gt| median {1000 * np.median(e):.1f} mm, "
          f"mean {1000 * e.mean():.1f} mm, p90 {1000 * np.percentile(e, 90):.1f} mm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--capture", type=Path, default=Path("out/kitchen_small/capture"))
    ap.add_argument("--exact-capture", type=Path, help="the same scene rendered with capture/depth=exact")
    ap.add_argument("--skip-train", action="store_true")
    a = ap.parse_args()
    torch.set_num_threads(2)
    cap = load_capture(a.capture)
    manifest = read_manifest(a.capture / "manifest.json")
    gt = trimesh.load(a.capture / "gt" / "mesh.ply", process=False)
    ev = MeshEvaluator(gt, cap.intrinsics, np.stack([cap.frames[i].w2c for i in cap.train]))
    bench_encoding()
    if not a.skip_train:
        bench_train_step(cap, manifest)
    if a.exact_capture:
        bench_tsdf(load_capture(a.exact_capture), ev, "exact depth")
    bench_tsdf(cap, ev, "sensor depth")
    bench_monocal(cap, gt)


if __name__ == "__main__":
    main()
