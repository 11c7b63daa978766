#!/usr/bin/env python
"""Parts from each source of 2D detections, on benchmark kitchens: every kitchen of a split is
built with the benchmark's sensors and geometry (simulated RGB-D and detections whose failures
persist across views, the TSDF geometry; the same kitchens and views as the ``bench_kitchen``
stages, but its own draw of the sensors' noise, seeded 1000 x split + k, so its ``capture``
figures are another draw than the stages' and compare with this script's runs only; ``--draw N``
draws them again, seeded 100000 x N more, into an --out of its own), then for
each ``--detect`` model its ``detect`` stage runs and decompose and articulate read that:
``capture`` (the simulated detector), ``builtin`` (the detector the ``detector`` stage trained,
which never sees the capture's detections) and ``none`` (the geometric path). Scored against the
ground truth: precision, recall and EA-score (docs/formats.md#articulation-precision-and-recall),
and the detections' own 2D precision / recall against the parts.

Articulate's decision weights: ``--decisions prior`` (the hand-set ones, the same for every
model) or ``fitted``: for each model, the benchmark's fit (:func:`drawer_lib.bench.fit.fit_decisions`,
``bench.fit`` settings) on that model's own decisions in the train kitchens ``--fit-kitchens``
(which a ``--split train`` run must have written), so a detector's typical failures are
learnt from its own train kitchens, never from the split scored. ``fitted`` reruns articulate
only, into ``articulate_fitted/``, on the detect and decompose outputs a ``prior`` run left.

    python scripts/bench_detect.py --split test --jobs 2
    python scripts/bench_detect.py --split train --kitchens 16 17 18 19    # train kitchens the detector did not fit
    python scripts/bench_detect.py --split test --decisions fitted --fit-kitchens 16 17 18 19 --detect capture builtin
    python scripts/bench_detect.py --split train --tag mw1 --set decompose.missing_weight=1   # a variant, same detections
    python scripts/bench_detect.py --split train --tag me0 --set detect.builtin.merge_edge=0  # a variant with its own detections
    python scripts/bench_detect.py --split train --tag hm0 --from-tag swa --set articulate.types.hinged_min_height=null
        # articulate alone, on the detections and decomposition of the run tagged swa
    python scripts/bench_detect.py --split hand --kitchens 0 1 2 3 --detect capture builtin   # kitchens written by hand
    python scripts/bench_detect.py --split train --kitchens 16 17 --layout 'module_widths=[0.3, 0.35]' --out DIR
        # a stress variant: the same kitchens with narrower fronts (built apart, in DIR)

Writes ``<out>/<split>/summary.json``; each kitchen's folders stay under ``<out>`` (a rerun
scores again without rebuilding the capture and geometry). Simulated input: rendered RGB-D.
"""

import argparse
import dataclasses
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

import drawer_lib  # noqa: F401  (before torch: the OpenMP policy)
from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.pipeline import run_articulate
from drawer_lib.bench.cli import parse_layout
from drawer_lib.bench.config import BenchConfig
from drawer_lib.bench.evaluate import score_kitchen
from drawer_lib.bench.fit import fit_decisions, labelled_fronts
from drawer_lib.bench.resample import pooled_prf
from drawer_lib.bench.scenes import kitchen_scene
from drawer_lib.capture.build import build_capture
from drawer_lib.capture.config import CaptureConfig
from drawer_lib.config.compose import compose_config
from drawer_lib.config.typed import to_typed
from drawer_lib.detect.config import DetectConfig
from drawer_lib.detect.pipeline import run_detect
from drawer_lib.io.capture import load_capture
from drawer_lib.io.images import read_json
from drawer_lib.io.parts import read_parts
from drawer_lib.io.overlay import apply_overlay
from drawer_lib.mesh.config import MeshConfig
from drawer_lib.mesh.pipeline import run_mesh
from drawer_lib.paths import BenchPaths, ScenePaths, capture_name
from drawer_lib.perception.config import DecomposeConfig
from drawer_lib.perception.pipeline import run_decompose
from drawer_lib.runner import stage_run
from drawer_lib.sdf.config import SdfConfig
from drawer_lib.sdf.io import load_field
from drawer_lib.sdf.pipeline import run_sdf
from drawer_lib.synth.splits import SPLITS, WRITTEN, missing_kitchens

ROOT = Path(__file__).resolve().parent.parent
FITTED_DIR = "articulate_fitted"
LAYOUT_FILE = "layout.json"  # beside a kitchen built with --layout: its keys
DRAW_FILE = "draw.json"  # beside a kitchen built with --draw N > 0: N
DRAW_STRIDE = 100_000  # the seeds of draw N lie N x this above draw 0's
OVERRIDES = ["scene=kitchen_small", "capture/detections=persistent", "capture/depth=sensor", "sdf=tsdf"]


def variant(model: str, tag: str) -> str:
    """The folder under ``by_detector/`` of ``model``'s decompose and articulate outputs."""
    return f"{model}-{tag}" if tag else model


def reused_run(root: Path, model: str, from_tag: str) -> tuple[ScenePaths, ScenePaths]:
    """(detections, decomposition): the outputs of ``model``'s run tagged ``from_tag`` under
    kitchen folder ``root`` that a ``--from-tag`` variant reads; the detections are that run's
    own, or the model's untagged ones when it decoded none (a tag that varied decompose or
    articulate only); stops when the run has no decomposition."""
    src = ScenePaths(root / "by_detector", variant(model, from_tag))
    if not src.metrics("decompose").is_file():
        raise SystemExit(f"error: {src.metrics('decompose')}: missing; run this split with --tag {from_tag} first")
    return (src if src.metrics("detect").is_file() else ScenePaths(root / "by_detector", model)), src


def kitchen(split: str, k: int, models: list[str], out: Path, weights: list[Path],
            decisions: dict[str, dict] | None = None, overrides: tuple[str, ...] = (), tag: str = "",
            layout: dict | None = None, own_detect: bool = False, from_tag: str | None = None, draw: int = 0) -> dict:
    """Build (or reuse) kitchen ``k`` and score each detection model; ``decisions``: fitted
    weights per model (articulate alone reruns, into ``articulate_fitted/``), None: the prior.
    ``overrides``: Hydra overrides of detect, decompose and articulate; ``tag``: their outputs
    go to ``by_detector/<model>-<tag>/``, reading the detections of ``by_detector/<model>/``
    unless ``overrides`` change ``detect.*`` or ``own_detect`` (other detector weights) is set
    (then the variant's own detections, there). ``weights``: the built-in detector's files (more
    than one: their fits as one ensemble).
    ``layout``: keys of the kitchen's layout block over the split's (a stress variant of the
    split: other widths, handle styles); recorded in ``layout.json`` beside the kitchen, and a
    kitchen built with other keys is not reused. ``from_tag``: read the detections and the
    decomposition of ``by_detector/<model>-<from_tag>/`` (a run with that tag; ``""``: the untagged
    run) and rerun articulate alone (``overrides`` then vary articulate only). ``draw``: the
    sensors' noise drawn again (0: as ever; N: seeded ``DRAW_STRIDE`` x N higher, the same kitchen
    and views), recorded in ``draw.json`` beside the kitchen."""
    import torch

    torch.set_num_threads(1)
    cfg = compose_config(ROOT / "conf", OVERRIDES + list(overrides))
    base = OmegaConf.to_container(cfg.scene, resolve=True)
    scene = kitchen_scene(base, split, k, layout=layout)
    sp = ScenePaths(out / split, f"kitchen_{k}")
    seed = 1000 * SPLITS.index(split) + k + DRAW_STRIDE * draw  # not the stages' kitchen_seed: docs/ drew with this
    if not sp.metrics("mesh").is_file():
        if layout:
            sp.root.mkdir(parents=True, exist_ok=True)
            (sp.root / LAYOUT_FILE).write_text(json.dumps(layout))
        if draw:
            sp.root.mkdir(parents=True, exist_ok=True)
            (sp.root / DRAW_FILE).write_text(json.dumps({"draw": draw}))
        with stage_run("capture", sp.capture, seed) as r:
            build_capture(f"{split}_{k}", scene, to_typed(CaptureConfig, cfg.capture, "capture"), r.dir, r.rng, ROOT)
        cap = load_capture(sp.capture, check_files=False)
        with stage_run("sdf", sp.stage_dir("sdf"), seed) as r:
            r.metrics.update(run_sdf(to_typed(SdfConfig, cfg.sdf, "sdf"), cap, r))
        with stage_run("mesh", sp.stage_dir("mesh"), seed) as r:
            r.metrics.update(run_mesh(to_typed(MeshConfig, cfg.mesh, "mesh"), load_field(sp.field), cap, r))
    cap = load_capture(sp.capture, check_files=False)
    ac = to_typed(ArticulateConfig, cfg.articulate, "articulate")
    own_detect = own_detect or any(o.lstrip("+~").startswith("detect.") for o in overrides)
    row = {"kitchen": k}
    reuse = from_tag is not None  # detect and decompose: read from the run tagged from_tag
    for model in models:
        v = ScenePaths(sp.root / "by_detector", variant(model, tag))  # decompose, articulate
        d = v if own_detect else ScenePaths(sp.root / "by_detector", model)  # the detections
        src = v  # the decomposition articulate reads
        if reuse:
            d, src = reused_run(sp.root, model, from_tag)
        t0 = time.perf_counter()
        if not reuse and decisions is None and not (tag and not own_detect and d.metrics("detect").is_file()):
            dc = dataclasses.replace(to_typed(DetectConfig, cfg.detect, "detect"), model=model)
            with stage_run("detect", d.detect, seed) as r:
                r.metrics.update(run_detect(dc, cap, weights, r))
        elif decisions is not None and not v.metrics("decompose").is_file():
            raise SystemExit(f"error: {v.metrics('decompose')}: missing; run this split with --decisions prior first")
        vcap = apply_overlay(cap, d.file("detect", "index"))
        if decisions is None and not reuse:
            with stage_run("decompose", v.stage_dir("decompose"), seed) as r:
                r.metrics.update(run_decompose(to_typed(DecomposeConfig, cfg.decompose, "decompose"), vcap, sp.mesh, r))
        art = v.stage_dir("articulate") if decisions is None else v.root / FITTED_DIR
        with stage_run("articulate", art, seed) as r:
            r.metrics.update(run_articulate(ac, vcap, src.stage_dir("decompose"), r,
                                            weights=ac.types.prior if decisions is None else decisions[model],
                                            recheck=(to_typed(DecomposeConfig, cfg.decompose, "decompose"), sp.mesh)))
        s = score_kitchen(sp, art / v.parts.name)
        dm = read_json(d.metrics("detect"))
        row[model] = {"precision": s["precision"], "recall": s["recall"], "ea_score": s.get("ea_score"),
                      "n_pred": s["n_pred"] - s["n_ignored"], "n_gt": s["n_gt"], "n_correct": s["n_correct"],
                      "parts_2d_precision": dm.get("parts_2d_precision"), "parts_2d_recall": dm.get("parts_2d_recall"),
                      "source": read_json(src.metrics("decompose"))["source"], "s": round(time.perf_counter() - t0, 1)}
    return row


def _marker(root: Path, name: str, absent):
    """The JSON a build left beside a kitchen (``layout.json``, ``draw.json``); ``absent`` without one."""
    path = root / name
    return json.loads(path.read_text()) if path.is_file() else absent


def check_built(out: Path, split: str, kitchens: list[int], layout: dict, draw: int = 0) -> None:
    """Refuse kitchens under ``out`` that were built with other ``--layout`` keys than ``layout``
    or another ``--draw`` of the sensors than ``draw``."""
    for k in kitchens:
        sp = ScenePaths(out / split, f"kitchen_{k}")
        if sp.metrics("mesh").is_file():
            built = _marker(sp.root, LAYOUT_FILE, {})
            if built != layout:
                raise SystemExit(f"error: {sp.root}: built with layout {built}, not {layout}; use another --out")
            built_draw = _marker(sp.root, DRAW_FILE, {"draw": 0})["draw"]
            if built_draw != draw:
                raise SystemExit(f"error: {sp.root}: built with --draw {built_draw}, not {draw}; use another --out")


def fit_per_model(models: list[str], out: Path, kitchens: list[int], overrides: tuple[str, ...] = (), tag: str = ""
                  ) -> tuple[dict[str, dict], dict[str, dict]]:
    """(weights, fit record) per model, each fitted on that model's decisions in train ``kitchens``
    (those of the ``tag`` variant when given)."""
    cfg = compose_config(ROOT / "conf", OVERRIDES + list(overrides))
    bc, ac = to_typed(BenchConfig, cfg.bench, "bench"), to_typed(ArticulateConfig, cfg.articulate, "articulate")
    weights, records = {}, {}
    for model in models:
        rows = []
        for k in kitchens:
            sp = ScenePaths(out / "train", f"kitchen_{k}")
            dec = ScenePaths(sp.root / "by_detector", variant(model, tag)).file("articulate", "decisions")
            if not dec.is_file():
                raise SystemExit(f"error: {dec}: missing; run --split train --kitchens {' '.join(map(str, kitchens))} first")
            rows += labelled_fronts(f"train_{k}", dec, read_parts(sp.capture / capture_name("gt_parts")))
        res = fit_decisions(rows, ac.types.prior, bc.fit.lambdas, min(bc.fit.folds, len(kitchens)), bc.fit.min_examples,
                            select=bc.fit.select)
        weights[model] = res.weights
        records[model] = {"n_fronts": len(rows), "lambda": res.lam, "cv_accuracy": dict(res.cv)[res.lam],
                          "train_accuracy": res.train_accuracy, "kitchens": kitchens}
        print(f"fitted {model}: {len(rows)} fronts of train kitchens {kitchens}, lambda {res.lam}, "
              f"CV accuracy {dict(res.cv)[res.lam]:.2f}", flush=True)
    return weights, records


def summarise(rows: list[dict], models: list[str]) -> dict:
    out = {}
    for m in models:
        rs = [r[m] for r in rows]
        corr, pred, gt = (sum(r[k] for r in rs) for k in ("n_correct", "n_pred", "n_gt"))
        prec, rec, _ = (None if np.isnan(x) else float(x) for x in pooled_prf(np.array([[corr, pred, gt]])))
        eas = [r["ea_score"] for r in rs if r["ea_score"] is not None]
        p2 = [r["parts_2d_precision"] for r in rs if r["parts_2d_precision"] is not None]
        r2 = [r["parts_2d_recall"] for r in rs if r["parts_2d_recall"] is not None]
        out[m] = {"precision_pooled": prec, "recall_pooled": rec,
                  "precision_mean": float(np.mean([r["precision"] for r in rs if r["precision"] is not None])),
                  "recall_mean": float(np.mean([r["recall"] for r in rs])),
                  "precision_worst": float(min(r["precision"] if r["precision"] is not None else 0.0 for r in rs)),
                  "recall_worst": float(min(r["recall"] for r in rs)),
                  "ea_score_mean": float(np.mean(eas)) if eas else None,
                  "n_pred": pred, "n_gt": gt, "n_correct": corr,
                  "parts_2d_precision_mean": float(np.mean(p2)) if p2 else None,
                  "parts_2d_recall_mean": float(np.mean(r2)) if r2 else None}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--split", default="test", choices=list(SPLITS))
    ap.add_argument("--kitchens", type=int, nargs="+", default=None, help="default: 0 .. 19 (hand: its 8)")
    ap.add_argument("--detect", nargs="+", default=["capture", "builtin", "none"])
    ap.add_argument("--weights", type=Path, nargs="+", default=[BenchPaths(ROOT / "bench").detector_weights],
                    help="the built-in detector's weights (the detector stage's output); several files: their "
                    "fits as one ensemble (mean class probabilities). Other than the default, a --tag's "
                    "variant runs its own detections")
    ap.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 2)))
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_detect"))
    ap.add_argument("--decisions", default="prior", choices=["prior", "fitted"],
                    help="articulate's decision weights: the prior, or fitted per model on --fit-kitchens")
    ap.add_argument("--fit-kitchens", type=int, nargs="+", default=[16, 17, 18, 19],
                    help="train kitchens (already run with --split train) the fitted weights learn from")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="Hydra overrides of detect, decompose and articulate (e.g. decompose.missing_weight=1)")
    ap.add_argument("--layout", nargs="*", default=[], metavar="KEY=VALUE",
                    help="keys of each kitchen's layout block over its split's, values in YAML (a stress "
                    "variant of the split, e.g. 'module_widths=[0.3, 0.35]'); needs an --out of its own")
    ap.add_argument("--tag", default="", help="write decompose and articulate to by_detector/<model>-TAG/ "
                    "(the detections of by_detector/<model>/ are read unless --set changes detect.*; the summary is "
                    "summary-TAG.json)")
    ap.add_argument("--from-tag", default=None, metavar="TAG",
                    help="rerun articulate alone on the detections and decomposition of the run tagged TAG "
                    "('' for the untagged run); --set may then vary articulate.* only")
    ap.add_argument("--draw", type=int, default=0,
                    help="draw the sensors' noise (depth, simulated detections) again: N > 0 seeds every kitchen "
                    "N x 100000 higher (the same kitchens and views); needs an --out of its own")
    a = ap.parse_args()
    if a.draw < 0:
        raise SystemExit(f"error: --draw {a.draw}: 0 (the usual draw) or a positive number")
    layout = parse_layout(a.layout)
    if a.kitchens is None:
        a.kitchens = list(range(len(WRITTEN[a.split]) if a.split in WRITTEN else 20))
    why = missing_kitchens(a.split, a.kitchens)
    if why:
        raise SystemExit(f"error: --kitchens {' '.join(map(str, a.kitchens))}: {why}")
    if a.set and not a.tag:
        raise SystemExit("error: --set needs a --tag, so that the variant does not overwrite the default's outputs")
    set_keys = [o.split("=")[0].lstrip("+~") for o in a.set]
    if any(not key.startswith(("detect.", "decompose.", "articulate.")) for key in set_keys):
        raise SystemExit(f"error: --set {' '.join(a.set)}: only detect.*, decompose.* and articulate.* keys vary here")
    if any(key.startswith("detect.model") for key in set_keys):
        raise SystemExit("error: --set detect.model: the models are --detect's")
    if a.from_tag is not None:
        if not a.tag or a.tag == a.from_tag:
            raise SystemExit("error: --from-tag needs a --tag of its own, so that the variant does not overwrite the run it reads")
        if any(not key.startswith("articulate.") for key in set_keys):
            raise SystemExit(f"error: --set {' '.join(a.set)}: with --from-tag only articulate.* keys vary (detect and decompose are read)")
        if a.decisions == "fitted":
            raise SystemExit("error: --from-tag reruns articulate with the prior weights; --decisions fitted has its own rerun")
    if a.decisions == "fitted" and a.split == "train" and set(a.kitchens) & set(a.fit_kitchens):
        raise SystemExit("error: --decisions fitted would score train kitchens the weights were fitted on")
    check_built(a.out, a.split, a.kitchens, layout, a.draw)
    for k in a.kitchens if a.from_tag is not None else []:  # before any build
        for model in a.detect:
            reused_run(a.out / a.split / f"kitchen_{k}", model, a.from_tag)
    for w in a.weights if "builtin" in a.detect else []:
        if not w.is_file():
            raise SystemExit(f"error: {w}: the built-in detector's weights are missing (run `dvc repro detector`)")
    weights = [w.resolve() for w in a.weights]
    own_weights = weights != [BenchPaths(ROOT / "bench").detector_weights.resolve()]
    fitted, fit_rec = (fit_per_model(a.detect, a.out, a.fit_kitchens, tuple(a.set), a.tag) if a.decisions == "fitted"
                       else (None, None))
    with ProcessPoolExecutor(a.jobs) as ex:
        futs = [ex.submit(kitchen, a.split, k, a.detect, a.out, weights, fitted, tuple(a.set), a.tag,
                          layout, own_weights and bool(a.tag), a.from_tag, a.draw)
                for k in a.kitchens]
        rows = []
        for f in futs:
            row = f.result()
            rows.append(row)
            print(f"{a.split} {row['kitchen']:2d}: " + "   ".join(
                f"{m} P {row[m]['precision'] if row[m]['precision'] is not None else float('nan'):.2f} "
                f"R {row[m]['recall']:.2f}" for m in a.detect), flush=True)
    summ = {"split": a.split, "kitchens": a.kitchens, "layout": layout, "draw": a.draw, "weights": a.decisions, "fit": fit_rec, "set": a.set,
            "from_tag": a.from_tag,
            "detector_weights": [str(w) for w in weights],
            "by_model": summarise(rows, a.detect), "rows": rows}
    (a.out / a.split).mkdir(parents=True, exist_ok=True)
    name = "summary" + ("" if a.decisions == "prior" else "-fitted") + (f"-{a.tag}" if a.tag else "") + ".json"
    (a.out / a.split / name).write_text(json.dumps(summ, indent=2))

    def f(x):
        return "–" if x is None else f"{x:.2f}"

    print(f"\n| {a.split} ({len(rows)} kitchens, {a.decisions} decisions) | precision (pooled / mean / worst) | recall (pooled / mean / worst) "
          "| EA-score | parts found | 2D masks: precision / recall |\n|---|---|---|---|---|---|")
    for m, s in summ["by_model"].items():
        print(f"| {m} | {f(s['precision_pooled'])} / {f(s['precision_mean'])} / {f(s['precision_worst'])} | "
              f"{f(s['recall_pooled'])} / {f(s['recall_mean'])} / {f(s['recall_worst'])} | {f(s['ea_score_mean'])} | "
              f"{s['n_correct']}/{s['n_gt']} ({s['n_pred']} predicted) | "
              f"{f(s['parts_2d_precision_mean'])} / {f(s['parts_2d_recall_mean'])} |")


if __name__ == "__main__":
    main()
