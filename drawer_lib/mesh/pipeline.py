"""What the ``mesh`` stage does: marching cubes of a field where the train cameras saw, PyMeshLab
clean-up, ``mesh.ply``, and the metrics against ``gt/mesh.ply`` when it exists."""

import time

import numpy as np
import trimesh

from drawer_lib.errors import InputError
from drawer_lib.io.capture import Capture
from drawer_lib.io.overlay import capture_manifest
from drawer_lib.io.mesh import load_mesh
from drawer_lib.mesh.clean import clean_mesh
from drawer_lib.mesh.config import MeshConfig
from drawer_lib.geometry.isosurface import grid_field_mesh, marching_cubes_mesh, sdf_grid, seen_crossing_mask
from drawer_lib.metrics.geometry import MeshEvaluator
from drawer_lib.paths import capture_name
from drawer_lib.runner import StageRun
from drawer_lib.sdf.io import LoadedField


def extract_mesh(cfg: MeshConfig, field: LoadedField, cap: Capture) -> trimesh.Trimesh:
    """Raw marching-cubes mesh of ``field`` restricted to the train frusta (and, for grid
    fields, to cubes whose 8 corners were observed)."""
    w2c = np.stack([cap.frames[i].w2c for i in cap.train])
    empty = InputError(f"mesh: no part of the field's box {np.round(field.lo, 3).tolist()} - "
                       f"{np.round(field.hi, 3).tolist()} lies in a train camera's view "
                       f"where its level set s = {cfg.level} crosses it (empty visibility region)")
    if field.grid is not None:
        try:
            return grid_field_mesh(field.grid, cap.intrinsics, w2c, cfg.level, cfg.near)
        except ValueError as e:
            raise empty from e
    lo, cell = field.lo, cfg.cell
    values = sdf_grid(field.sdf, field.lo, field.hi, cfg.cell, cfg.coarse_factor)
    if not values.min() <= cfg.level <= values.max():  # run_mesh says that the level set does not cross the box
        return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), process=False)
    mask = seen_crossing_mask(values, lo, cell, cap.intrinsics, w2c, cfg.level, cfg.near)
    if not mask.any():
        raise empty
    return marching_cubes_mesh(values, lo, cell, cfg.level, mask)


def run_mesh(cfg: MeshConfig, field: LoadedField, cap: Capture, run: StageRun) -> dict:
    """Mesh ``field`` where the train cameras saw, clean it up, write the stage's ``mesh.ply``
    and score it against the capture's ground-truth mesh when there is one."""
    manifest = capture_manifest(cap)
    t0 = time.perf_counter()
    raw = extract_mesh(cfg, field, cap)
    t_mc = time.perf_counter() - t0
    if len(raw.faces) == 0:
        raise InputError(f"mesh: the level set s = {cfg.level} of the field does not cross the seen region "
                         f"(field made by {field.info.get('method', field.kind)}); nothing to mesh")
    mesh, counts = clean_mesh(raw, cfg.clean)
    if len(mesh.faces) == 0:
        raise InputError(f"mesh: clean-up removed every face (min_component_diag = {cfg.clean.min_component_diag})")
    t_clean = time.perf_counter() - t0 - t_mc
    mesh.export(run.out("mesh"))
    m = {"field": field.info.get("method", field.kind), "marching_cubes_s": round(t_mc, 3),
         "clean_s": round(t_clean, 3), **counts, "vertices": len(mesh.vertices),
         "area_m2": float(mesh.area)}
    if run.needs(manifest, "metrics_vs_gt", "gt"):
        gt = load_mesh(cap.root / capture_name("gt_mesh"))
        w2c = np.stack([cap.frames[i].w2c for i in cap.train])
        ev = MeshEvaluator(gt, cap.intrinsics, w2c, n_points=cfg.eval_points, seed=run.seed)
        r = ev(mesh)
        m.update({k: r[k] for k in ("chamfer_l1", "accuracy", "completeness", "fscore_1cm", "fscore_2cm",
                                    "precision_1cm", "recall_1cm", "precision_2cm", "recall_2cm",
                                    "normal_consistency")})
    return m
