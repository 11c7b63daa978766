#!/usr/bin/env python
"""Error against time of the mesh stage's two decimators (``mesh.clean.decimator``):
Fast-Quadric-Mesh-Simplification (``fast_quadric``, the default) and PyMeshLab's quadric edge
collapse (``pymeshlab``), at several face targets, on raw marching-cubes meshes.

Meshes, and which split they belong to:
- tune: ``neural``, the default scene's neural SDF field (the mesh on which fast_quadric's unit
  normalisation was chosen);
- held out: ``tsdf`` and ``neural_mono``, the same scene's other geometry variants (other
  fields, other noise); ``neural_cm``, the neural mesh in centimetres (another unit);
  ``torus``, ``rounded_box`` and ``sphere``, analytic SDFs marched at 5 mm, whose exact
  distance to the decimated vertices is known.

For each mesh, target (a fraction of its faces) and decimator, one row: seconds of the clean-up
with that decimator (``clean_mesh``: duplicate and null faces, then the decimation; the median
of ``--rounds``, the decimators alternating, one thread), faces out, the mean and 99th percentile
distance from points sampled on the decimated surface to the undecimated one and back (mm, in
the mesh's own unit / 1000 for the metre meshes), the exact analytic error for the analytic
shapes, and for ``neural`` Chamfer-L1 and F@1cm against the capture's ground truth. Writes
``<out>/decimate.csv`` and ``decimate.png`` (distance against seconds, one panel per mesh) and
prints a table. Needs ``make run`` first (the fields of the default scene).

    python scripts/bench_decimate.py [--out reports/speed] [--rounds 3] [--only neural torus]
"""

import argparse
import csv
import os
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import torch
import trimesh


from drawer_lib.io.capture import load_capture
from drawer_lib.mesh.clean import CleanConfig, clean_mesh
from drawer_lib.mesh.config import MeshConfig
from drawer_lib.geometry.isosurface import marching_cubes_mesh, sdf_grid
from drawer_lib.mesh.pipeline import extract_mesh
from drawer_lib.metrics.geometry import SurfaceDistance, sample_surface
from drawer_lib.report.markdown import md_table
from drawer_lib.sdf.io import load_field

ROOT = Path(__file__).resolve().parent.parent

SCENE = ROOT / "out" / "kitchen_small"
FRACTIONS = (0.1, 0.3, 0.5)


def torus(x: torch.Tensor) -> torch.Tensor:
    q = torch.stack([torch.linalg.norm(x[:, :2], dim=-1) - 0.35, x[:, 2]], -1)
    return torch.linalg.norm(q, dim=-1) - 0.12


def rounded_box(x: torch.Tensor) -> torch.Tensor:
    q = x.abs() - torch.tensor([0.4, 0.25, 0.15])
    return torch.linalg.norm(q.clamp_min(0.0), dim=-1) + q.max(-1).values.clamp_max(0.0) - 0.03


def sphere(x: torch.Tensor) -> torch.Tensor:
    return torch.linalg.norm(x, dim=-1) - 0.45


ANALYTIC = {"torus": torus, "rounded_box": rounded_box, "sphere": sphere}


def raw_meshes(only: list[str] | None) -> dict[str, tuple[trimesh.Trimesh, float, str]]:
    """name -> (raw mesh, unit in metres, split)."""
    out: dict[str, tuple[trimesh.Trimesh, float, str]] = {}
    want = lambda n: not only or n in only  # noqa: E731
    cap = load_capture(SCENE / "capture", check_files=False)
    fields = {"neural": SCENE / "sdf/field.pt", "tsdf": SCENE / "geometry/tsdf/sdf/field.pt",
              "neural_mono": SCENE / "geometry/neural_mono/sdf/field.pt"}
    for name, path in fields.items():
        if want(name) or (name == "neural" and want("neural_cm")):
            if not path.exists():
                raise SystemExit(f"{path} is missing: run `make run` first")
            out[name] = (extract_mesh(MeshConfig(), load_field(path), cap), 1.0, "tune" if name == "neural" else "held out")
    if want("neural_cm"):
        m = out["neural"][0]
        out["neural_cm"] = (trimesh.Trimesh(m.vertices * 100.0, m.faces, process=False), 0.01, "held out")
        if not want("neural"):
            del out["neural"]
    for name, fn in ANALYTIC.items():
        if want(name):
            lo, hi, cell = np.full(3, -0.6), np.full(3, 0.6), 0.005
            out[name] = (marching_cubes_mesh(sdf_grid(fn, lo, hi, cell, 4), lo, cell), 1.0, "held out")
    return out


def surface_distance(a: trimesh.Trimesh, b: trimesh.Trimesh, n: int = 200_000) -> np.ndarray:
    """Distances from ``n`` area-uniform points on ``a`` to the surface of ``b`` (the geometry
    metrics' own sampler and exact point-to-triangle distance)."""
    return SurfaceDistance(b)(sample_surface(a, n, seed=0).points)[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "reports" / "speed")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--only", nargs="*", default=None)
    args = ap.parse_args()
    torch.set_num_threads(1)
    meshes = raw_meshes(args.only)
    gt_eval = None
    if "neural" in meshes:
        from drawer_lib.io.mesh import load_mesh
        from drawer_lib.metrics.geometry import MeshEvaluator

        cap = load_capture(SCENE / "capture", check_files=False)
        w2c = np.stack([cap.frames[i].w2c for i in cap.train])
        gt_eval = MeshEvaluator(load_mesh(SCENE / "capture/gt/mesh.ply"), cap.intrinsics, w2c, n_points=500_000, seed=0)
    rows = []
    for name, (raw, unit, split) in meshes.items():
        mm = unit * 1e3  # mesh units -> mm
        for frac in FRACTIONS:
            target = int(round(frac * len(raw.faces)))
            times: dict[str, list[float]] = {"fast_quadric": [], "pymeshlab": []}
            result = {}
            for _ in range(args.rounds):
                for dec in times:
                    cfg = CleanConfig(min_component_diag=0.0, target_faces=target, decimator=dec)
                    t0 = time.perf_counter()
                    result[dec], _ = clean_mesh(raw, cfg)
                    times[dec].append(time.perf_counter() - t0)
            for dec, m in result.items():
                d = np.concatenate([surface_distance(m, raw), surface_distance(raw, m)]) * mm
                row = {"mesh": name, "split": split, "faces_in": len(raw.faces), "target": target,
                       "decimator": dec, "seconds": round(statistics.median(times[dec]), 3), "faces_out": len(m.faces),
                       "dist_mean_mm": round(float(d.mean()), 4), "dist_p99_mm": round(float(np.quantile(d, 0.99)), 4)}
                if name in ANALYTIC:
                    e = ANALYTIC[name](torch.as_tensor(m.vertices, dtype=torch.float32)).abs().numpy() * mm
                    row["vertex_sdf_max_mm"] = round(float(e.max()), 4)
                if name == "neural" and gt_eval is not None:
                    r = gt_eval(m)
                    row.update({"chamfer_l1_mm": round(r["chamfer_l1"] * 1e3, 4), "fscore_1cm": round(r["fscore_1cm"], 5)})
                rows.append(row)
                print(" ".join(f"{k}={v}" for k, v in row.items()), flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(args.out / "decimate.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    plot(rows, args.out / "decimate.png")
    cells = []
    for name in meshes:
        for frac in FRACTIONS:
            r = {x["decimator"]: x for x in rows if x["mesh"] == name and abs(x["target"] / x["faces_in"] - frac) < 1e-3}
            a, b = r["fast_quadric"], r["pymeshlab"]
            cells.append([name, a["split"], f"{a['faces_in']} -> {a['target']}", a["seconds"], b["seconds"],
                          f"{b['seconds'] / max(a['seconds'], 1e-9):.1f}x", f"{a['dist_mean_mm']} / {a['dist_p99_mm']}",
                          f"{b['dist_mean_mm']} / {b['dist_p99_mm']}"])
    print()
    print(md_table(["mesh", "split", "faces in -> target", "fast_quadric s", "pymeshlab s", "speed-up",
                    "mean / p99 dist, fast_quadric (mm)", "mean / p99 dist, pymeshlab (mm)"], cells), end="")
    print(f"\nwrote {args.out / 'decimate.csv'} and {args.out / 'decimate.png'}")


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from matplotlib.ticker import NullFormatter

    names = list(dict.fromkeys(r["mesh"] for r in rows))
    cols = min(4, len(names))
    nrows = -(-len(names) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(3.4 * cols, 2.9 * nrows), squeeze=False)
    for ax in axes.ravel()[len(names):]:
        ax.axis("off")
    for ax, name in zip(axes.ravel(), names):
        for dec, colour in (("fast_quadric", "tab:blue"), ("pymeshlab", "tab:orange")):
            rs = sorted((r for r in rows if r["mesh"] == name and r["decimator"] == dec), key=lambda r: r["target"])
            ax.plot([r["seconds"] for r in rs], [r["dist_mean_mm"] for r in rs], "o-", color=colour, label=dec)
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_title(f"{name} ({rows[[r['mesh'] for r in rows].index(name)]['split']})", fontsize=9)
        ax.set_xlabel("seconds (1 thread)")
    for row in axes:
        row[0].set_ylabel("mean dist. to raw (mm)")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
