#!/usr/bin/env python
"""Interior depth: fitted templates (drawer_lib/complete/interiors/) against DRAWER's fixed
rule (1.5 x width for doors, 1.25 x for drawers), both scored against the GT interior depth
(drawer_lib/metrics/interiors.py). Prints one row per kitchen (mean / worst absolute error of
the free depth, m) and, with ``--parts``, one row per part.

Kitchens:
- ``kitchen_small``: the pipeline's own outputs under ``out/kitchen_small`` (predicted
  ``articulate/parts.json``, reconstructed ``mesh/mesh.ply``), scored against its ``capture/gt``;
- procedural kitchens ``train:K`` / ``test:K`` (drawer_lib/synth/splits.py), *without* running
  the pipeline: the parts are the GT parts with noise on their fronts (centre +-5 mm, size
  +-1 cm, normal tilted ~1 deg), the mesh evidence is the GT surface seen by the kitchen's own
  camera path (depth test) with 2 mm noise along the normals.

    python scripts/bench_interiors.py [--kitchens kitchen_small,train:0,train:3,test:6,test:11] [--parts]
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np
import trimesh
from omegaconf import OmegaConf


from drawer_lib.complete.interiors.config import InteriorsConfig
from drawer_lib.complete.interiors.drawer_rule import drawer_rule_interiors
from drawer_lib.complete.interiors.fit import build_interiors
from drawer_lib.config.typed import to_typed
from drawer_lib.geometry.camera import Intrinsics, invert_rigid
from drawer_lib.io.parts import Axis, Front, Part, PartsFile, read_parts
from drawer_lib.metrics.geometry import gt_views, sample_surface, seen_mask
from drawer_lib.metrics.interiors import interior_depth_error, summarise_depth_errors
from drawer_lib.synth.camera_path import camera_path
from drawer_lib.synth.config import SynthConfig
from drawer_lib.synth.gt import layout_mesh, layout_parts
from drawer_lib.synth.layout import sample_layout
from drawer_lib.synth.splits import split_synth

ROOT = Path(__file__).resolve().parent.parent

N_POINTS = 300_000


def kitchen_small(out: Path):
    """(predicted parts, mesh points, normals, GT mesh, GT parts, GT face instances)."""
    d = out / "kitchen_small"
    mesh = trimesh.load(d / "mesh" / "mesh.ply", process=False)
    s = sample_surface(mesh, N_POINTS, 0)
    gt = d / "capture" / "gt"
    return (read_parts(d / "articulate" / "parts.json"), s.points, s.normals,
            trimesh.load(gt / "mesh.ply", process=False), read_parts(gt / "parts.json"),
            np.load(gt / "mesh_instances.npy"))


def _noisy_front(f: Front, rng: np.random.Generator) -> Front:
    n = np.asarray(f.normal) + rng.normal(0, np.deg2rad(1.0), 3)
    n /= np.linalg.norm(n)
    u = np.asarray(f.u) - (np.asarray(f.u) @ n) * n
    u /= np.linalg.norm(u)
    c = np.asarray(f.center) + rng.normal(0, 0.005, 3)
    size = tuple(float(max(0.05, s + rng.normal(0, 0.01))) for s in f.size)
    return Front(tuple(c.tolist()), tuple(n.tolist()), tuple(u.tolist()), size)


def procedural(split: str, k: int, seed: int = 0):
    """A procedural kitchen: noisy GT parts and the visible GT surface (module doc)."""
    cfg = to_typed(SynthConfig, OmegaConf.create(split_synth(split, k)), "synth", strict=False)
    layout = sample_layout(cfg)
    gt_parts = layout_parts(layout)
    mesh, inst = layout_mesh(layout)
    cc = cfg.camera
    intr = Intrinsics.from_fovy(np.deg2rad(cc.fovy_deg), cc.width, cc.height)
    poses = camera_path(layout, cc, np.random.default_rng([cfg.seed, 2]))  # OpenCV c2w
    views = gt_views(mesh, intr, np.stack([invert_rigid(T) for T in poses]))
    s = sample_surface(mesh, N_POINTS, seed)
    seen = seen_mask(views, s.points, s.normals, 0.01)
    rng = np.random.default_rng([seed, k])
    pts = s.points[seen] + rng.normal(0, 0.002, (int(seen.sum()), 1)) * s.normals[seen]
    parts = []
    for p in gt_parts.parts:
        if not p.articulated:
            continue
        f = _noisy_front(p.front, rng)
        axis = Axis(f.center, f.normal) if p.kind == "prismatic" and np.dot(p.axis.direction, p.front.normal) > 0.8 \
            else p.axis
        parts.append(Part(p.id, p.kind, axis, p.limits, f, p.instance_id, extra=dict(p.extra)))
    return PartsFile(tuple(parts)), pts, s.normals[seen], mesh, gt_parts, inst


def run(name: str, out: Path, cfg: InteriorsConfig) -> tuple[dict, dict, float]:
    if name == "kitchen_small":
        pred, pts, nrm, gm, gt, inst = kitchen_small(out)
    else:
        split, k = name.split(":")
        pred, pts, nrm, gm, gt, inst = procedural(split, int(k))
    t = time.perf_counter()
    res = build_interiors(pred.parts, pts, nrm, cfg)
    wall = time.perf_counter() - t
    floor = res.evidence[0].floor_z if res.evidence else None
    rule = drawer_rule_interiors(pred.parts, cfg, floor)
    rows = interior_depth_error(pred, gm, gt, {x.part_id: (x.template, x.free_depth) for x in res.interiors},
                                {x.part_id: x.free_depth for x in rule}, inst)
    for it in res.interiors:
        if it.part_id in rows:
            rows[it.part_id]["evidence"] = it.record["evidence"]
            rows[it.part_id]["active"] = it.record["active"]
    return rows, summarise_depth_errors(rows), wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kitchens", default="kitchen_small,train:0,train:3,test:6,test:11")
    ap.add_argument("--out", type=Path, default=ROOT / "out", help="where kitchen_small's outputs are")
    ap.add_argument("--parts", action="store_true", help="print one row per part")
    ap.add_argument("--json", type=Path, default=None, help="write all rows and summaries here")
    args = ap.parse_args()
    cfg = InteriorsConfig()
    allrows, summaries = {}, {}
    head = (f"{'kitchen':<14} {'parts':>5} {'fitted mean':>11} {'fitted worst':>12} {'rule mean':>10} "
            f"{'rule worst':>10} {'fit s':>6}  excluded (GT solid / no GT depth)")
    lines = []
    for name in args.kitchens.split(","):
        rows, summ, wall = run(name, args.out, cfg)
        allrows[name], summaries[name] = rows, summ
        f = lambda x: "-" if x is None else f"{x:.3f}"  # noqa: E731
        lines.append(f"{name:<14} {summ['n']:>5} {f(summ['fitted_mean']):>11} {f(summ['fitted_max']):>12} "
                     f"{f(summ['rule_mean']):>10} {f(summ['rule_max']):>10} {wall:>6.1f}  {','.join(summ['excluded'])}")
        if args.parts:
            for pid, r in rows.items():
                g = "-" if r["gt_depth"] is None else f"{r['gt_depth']:.3f}"
                print(f"  {name:<13} {pid:<12} {r['gt']:<12} {r['template']:<9} gt {g:>6}  fitted {r['fitted']:.3f}"
                      f"  rule {r['rule']:.3f}  evidence {r.get('evidence')}  active {r.get('active')}")
        print(lines[-1], flush=True)
    e_fit = [r["fitted_error"] for rows in allrows.values() for r in rows.values()
             if r["fitted_error"] is not None and not r["gt_solid"]]
    e_rule = [r["rule_error"] for rows in allrows.values() for r in rows.values()
              if r["rule_error"] is not None and not r["gt_solid"]]
    print("\nInterior free depth |error| vs GT (m): fitted templates vs DRAWER's fixed rule")
    print(head)
    print("\n".join(lines))
    print(f"{'all':<14} {len(e_fit):>5} {np.mean(e_fit):>11.3f} {np.max(e_fit):>12.3f} {np.mean(e_rule):>10.3f} "
          f"{np.max(e_rule):>10.3f}")
    if args.json:
        args.json.write_text(json.dumps({"rows": allrows, "summary": summaries}, indent=1, default=float))


if __name__ == "__main__":
    main()
