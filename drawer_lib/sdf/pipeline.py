"""What the ``sdf`` stage does, given a loaded capture: train the neural SDF or fuse the TSDF,
log the error-against-time curve, write ``field.pt`` and the metrics."""

import time

import numpy as np

from drawer_lib.errors import InputError
from drawer_lib.io.capture import Capture
from drawer_lib.io.overlay import capture_manifest
from drawer_lib.io.working import at_working_size, working_size_metrics
from drawer_lib.paths import capture_name
from drawer_lib.runner import StageRun
from drawer_lib.sdf.config import SdfConfig
from drawer_lib.sdf.io import save_grid, save_neural
from drawer_lib.sdf.probe import GeometryProbe
from drawer_lib.sdf.train import NeuralSDF, final_beta, train_neural_sdf
from drawer_lib.sdf.tsdf import fuse_tsdf

CURVE_COLUMNS = ["chamfer_l1", "fscore_1cm", "fscore_2cm", "test_depth_l1"]


def _finite(r: dict[str, float]) -> dict[str, float | None]:
    """NaN (e.g. no quick mesh yet) -> an empty curve cell."""
    return {k: (v if np.isfinite(v) else None) for k, v in r.items()}


def check_capture(cap: Capture) -> None:
    if not cap.train:
        raise InputError(f"{cap.root / capture_name('transforms')}: no train frames")
    it = cap.intrinsics
    if it.width < 8 or it.height < 8:
        raise InputError(f"{cap.root / capture_name('transforms')}: images of {it.width}x{it.height} px are too small")


def run_sdf(cfg: SdfConfig, cap: Capture, run: StageRun) -> dict:
    """Fit the field selected by ``cfg.method`` on ``cap`` read at ``cfg.max_side`` and write
    the stage's ``field.pt``; returns metrics."""
    check_capture(cap)
    cap = at_working_size(cap, cfg.max_side)
    run.metrics.update(working_size_metrics(cap))
    manifest = capture_manifest(cap)
    probe = None
    if manifest.has.get("gt", False):
        cell = cfg.neural.eval_cell
        probe = GeometryProbe(cap, cell=cell)
    else:
        run.skip("geometry_curve_metrics", manifest.missing("gt") or "no ground truth")
    if cfg.method == "tsdf":
        return _run_tsdf(cfg, cap, manifest, run, probe)
    return _run_neural(cfg, cap, manifest, run, probe)


def unmet_input(cfg: SdfConfig, manifest) -> str | None:
    """Why ``cfg`` cannot run on a capture with this manifest (None: it can): the TSDF fuses
    metric depth, which a plain video lacks."""
    if cfg.method == "tsdf" and not manifest.has.get("depth", False):
        return f"sdf.method = tsdf needs metric depth, but {manifest.missing('depth')}"
    return None


def _run_tsdf(cfg, cap, manifest, run, probe) -> dict:
    why = unmet_input(cfg, manifest)
    if why:
        raise InputError(f"{why}; use the neural SDF (sdf=neural) for RGB + monocular priors")
    t0 = time.perf_counter()
    grid = fuse_tsdf(cap, cap.train, cfg.tsdf, run.progress)
    fuse_s = time.perf_counter() - t0
    observed = grid.observed()
    save_grid(run.out("field"), grid, {"method": "tsdf", "frames": len(cap.train)})
    m = {"method": "tsdf", "train_s": round(fuse_s, 3), "voxels_observed": int(observed.sum()),
         "grid_shape": list(grid.values.shape)}
    curve = run.curve(CURVE_COLUMNS)
    if probe is not None:
        r = probe(grid.sdf, grid.lo, grid.hi, None, grid=grid)
        curve.log(len(cap.train), wall_s=fuse_s, **_finite(r))
        m.update({f"quick_{k}": v for k, v in r.items() if np.isfinite(v)})
    return m


def _run_neural(cfg, cap, manifest, run, probe) -> dict:
    n = cfg.neural
    curve = run.curve(CURVE_COLUMNS + ["loss", "beta"])
    last_probe: dict[str, float] = {}

    def on_eval(model: NeuralSDF, step: int, train_s: float, losses: dict) -> None:
        beta = final_beta(n, step)
        r = probe(model.field.sdf, model.lo.numpy(), model.hi.numpy(),
                  lambda o, d: model.render_depth(o, d, beta)) if probe is not None else {}
        curve.log(step, wall_s=train_s, beta=beta, loss=losses.get("total"), **_finite(r))
        last_probe.clear()
        last_probe.update(r)
        if r and np.isfinite(r["chamfer_l1"]):
            run.progress_write(f"step {step}: {train_s:.0f} s, chamfer {1000 * r['chamfer_l1']:.2f} mm, "
                               f"F@2cm {r['fscore_2cm']:.3f}, test depth {1000 * r['test_depth_l1']:.1f} mm")

    res = train_neural_sdf(cap, manifest, n, run.seed, run.progress, on_eval)
    for k, why in res.priors.skipped.items():
        run.skip(k, why)
    info = {"method": "neural", "box_how": res.box_how, "steps": res.steps}
    save_neural(run.out("field"), res.model.field, n, info)
    m = {"method": "neural", "train_s": round(res.train_s, 3), "steps": res.steps,
         "stopped_by_time": res.stopped_by_time, "within_budget": res.train_s <= n.budget_s, "box": [res.lo.tolist(), res.hi.tolist()], "box_how": res.box_how,
         "depth_source": ("sensor" if res.priors.depth else "calibrated_mono" if res.priors.calibrated else "none"),
         "final_losses": {k: round(v, 6) for k, v in res.last_losses.items()}}
    if res.calibration is not None:
        c = res.calibration
        m["monocal"] = {"photo_cost_search": round(c.cost_search, 6), "photo_cost_final": round(c.cost_final, 6),
                        "frames_without_neighbours": sum(1 for x in c.neighbours if not x)}
    m.update({f"quick_{k}": v for k, v in last_probe.items() if np.isfinite(v)})
    return m
