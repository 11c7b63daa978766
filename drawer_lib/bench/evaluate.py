"""Score a benchmark split (the ``bench_eval`` stage): every kitchen of the split is articulated
again with the fitted decision weights, on its own decompose output, and both that and its
articulation with the prior weights are scored against its ground truth
(docs/formats.md#articulation-precision-and-recall, #ea-score).

Per split: the table of both weight sets (precision, recall and EA-score per kitchen: mean,
spread and worst; pooled over all parts) and the geometry the kitchens were built on. The
numbers of the fitted weights on the test split are the benchmark's headline: the split was
never tuned on.
"""

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.pipeline import run_articulate
from drawer_lib.bench.config import GEOMETRY_KEYS
from drawer_lib.io.capture import load_capture
from drawer_lib.io.atomic import atomic_write_text
from drawer_lib.io.images import read_json, write_json
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.articulation import articulation_metrics, match_parts, part_kind, precision_by_flag
from drawer_lib.metrics.motion import kinematic_motion_emd
from drawer_lib.paths import LAYOUT, BenchPaths, ScenePaths, bench_name, capture_name
from drawer_lib.report.markdown import md_table
from drawer_lib.runner import StageRun, stage_run

WEIGHT_SOURCES = ("fitted", "prior")
COUNT_KEYS = ("n_pred", "n_gt", "n_correct", "n_ignored")


def score_kitchen(kitchen: ScenePaths, parts_path: Path) -> dict:
    """Precision, recall, EA-score and counts of the parts at ``parts_path`` against the
    kitchen's ground truth, plus the EA-score of every correct revolute part (``eas``), the
    motion EMD of every correct pair with the prediction moved by its own joint in the first test
    view (``emds``; :func:`~drawer_lib.metrics.motion.kinematic_motion_emd`) and the
    (GT kind, predicted kind) of every GT part and every unmatched prediction outside the
    ignore boxes (``confusion``: :func:`part_kind`, ``none`` for no GT part), and the counts of
    the parts articulate flagged ``low_margin`` and of the others (``flagged``: [correct,
    counted] each; :func:`precision_by_flag`)."""
    cap = load_capture(kitchen.capture, check_files=False)
    gt = read_parts(kitchen.capture / capture_name("gt_parts"))
    pred = read_parts(parts_path)
    views = cap.cameras(cap.test)
    res, details = articulation_metrics(pred, gt, views)
    res["eas"] = [d["ea_score"] for d in details if d.get("ea_score") is not None]
    m = match_parts(pred, gt)
    by_flag = precision_by_flag(m)
    res["flagged"] = {"low_margin": list(by_flag[True]), "others": list(by_flag[False])}
    pairs = [(i, j) for i, j, _ in m.correct]
    _, emd_rows = kinematic_motion_emd(m.pred, m.gt, pairs, views[0]) if views else ({}, [])
    res["emds"] = [r["emd"] for r in emd_rows if r["emd"] is not None]
    by_gt = {j: i for i, j, _ in m.pairs}
    matched = set(by_gt.values()) | set(m.ignored)
    res["confusion"] = ([[part_kind(g), part_kind(m.pred[by_gt[j]] if j in by_gt else None)]
                         for j, g in enumerate(m.gt)]
                        + [["none", part_kind(p)] for i, p in enumerate(m.pred) if i not in matched])
    return res


def evaluate_kitchen(kitchen: ScenePaths, dst: ScenePaths, cfg: ArticulateConfig,
                     weights: dict[str, dict[str, float]], seed: int) -> dict:
    """Articulate ``kitchen`` (a built benchmark kitchen) with ``weights`` into ``dst``'s
    articulate folder, and score it and the kitchen's own (prior) articulation. Returns the row
    {``fitted``: scores, ``prior``: scores, geometry metrics, ``articulate_s``}."""
    cap = load_capture(kitchen.capture, check_files=False)
    with stage_run("articulate", dst.stage_dir("articulate"), seed=seed) as r:
        r.metrics.update(run_articulate(cfg, cap, kitchen.decompose, r, weights=weights))
    built = read_json(kitchen.root / LAYOUT["metrics"])
    return {"fitted": score_kitchen(kitchen, dst.parts), "prior": score_kitchen(kitchen, kitchen.parts),
            **{k: built[k] for k in GEOMETRY_KEYS if k in built},
            "articulate_s": float(read_json(dst.metrics("articulate"))["wall_s"])}


def evaluate_split(split: str, kitchens: Sequence[int], bench: BenchPaths, out: Path, cfg: ArticulateConfig,
                   weights: dict[str, dict[str, float]], seed: int, progress: Callable | None = None) -> list[dict]:
    """:func:`evaluate_kitchen` for every kitchen of ``split`` into ``out/kitchen_<k>/``; the
    rows, each with its ``kitchen`` index."""
    Path(out).mkdir(parents=True, exist_ok=True)
    rows = []
    for k in (progress(kitchens, desc=f"{split} kitchens") if progress else kitchens):
        src = bench.kitchen(split, k)
        rows.append({"kitchen": int(k), **evaluate_kitchen(src, ScenePaths(out, src.scene), cfg, weights, seed)})
    return rows


def summarise(rows: Sequence[dict], source: str) -> dict:
    """The split's figures for one weight ``source`` (fitted | prior): per-kitchen precision,
    recall and EA-score as mean, standard deviation and worst kitchen; pooled over all parts
    (precision = correct / (predicted - ignored), recall = correct / GT; the EA-score of every
    correct revolute part); and the precision of the parts flagged ``low_margin`` and of the
    others (``n_low_margin``, ``precision_low_margin``, ``precision_others``: what the flag is
    worth as "check this one first"; absent from rows scored before the flag was counted)."""
    per = [r[source] for r in rows]
    out: dict = {"n_kitchens": len(per)}
    for key in ("precision", "recall", "ea_score"):
        v = np.array([p[key] for p in per if key in p], float)
        if len(v):
            out[f"{key}_mean"], out[f"{key}_std"], out[f"{key}_worst"] = float(v.mean()), float(v.std()), float(v.min())
    n = {k: int(sum(p[k] for p in per)) for k in COUNT_KEYS}
    scored = n["n_pred"] - n["n_ignored"]
    out.update(n)
    if scored > 0:
        out["precision"] = n["n_correct"] / scored
    if n["n_gt"] > 0:
        out["recall"] = n["n_correct"] / n["n_gt"]
    if per and all("flagged" in p for p in per):
        for side in ("low_margin", "others"):
            right, counted = (sum(p["flagged"][side][i] for p in per) for i in (0, 1))
            if side == "low_margin":
                out["n_low_margin"] = counted
            if counted:
                out[f"precision_{side}"] = right / counted
    eas = [e for p in per for e in p["eas"]]
    out["n_revolute_scored"] = len(eas)
    if eas:
        out["ea_score"] = float(np.mean(eas))
    emds = [e for p in per for e in p.get("emds", [])]
    out["n_emd"] = len(emds)
    if emds:
        k_means = [float(np.mean(p["emds"])) for p in per if p.get("emds")]
        out["emd"], out["emd_mean"], out["emd_worst"] = float(np.mean(emds)), float(np.mean(k_means)), max(k_means)
    return out


def confusion_matrix(rows: Sequence[dict], source: str) -> tuple[list[str], list[str], np.ndarray]:
    """(GT kinds, predicted kinds, counts [G, P]) of the split's parts for weight ``source``
    (:func:`score_kitchen`'s ``confusion``), kinds sorted, ``missed`` and ``none`` last."""
    pairs = [tuple(c) for r in rows for c in r[source].get("confusion", [])]
    last = lambda k: (k in ("missed", "none"), k)  # noqa: E731
    g_kinds = sorted({g for g, _ in pairs}, key=last)
    p_kinds = sorted({p for _, p in pairs}, key=last)
    counts = np.zeros((len(g_kinds), len(p_kinds)), np.int64)
    for g, p in pairs:
        counts[g_kinds.index(g), p_kinds.index(p)] += 1
    return g_kinds, p_kinds, counts


def split_metrics(rows: Sequence[dict]) -> dict:
    """The split's ``metrics.json``: the fitted weights' pooled figures under the pipeline's
    metric names (``precision``, ``recall``, ``ea_score``), every summary of both sources
    prefixed by it (``fitted_recall_worst``, ``prior_precision``, ...), and the geometry's mean
    and worst kitchen."""
    s = {src: summarise(rows, src) for src in WEIGHT_SOURCES}
    out = {k: s["fitted"][k] for k in ("precision", "recall", "ea_score", "emd") if k in s["fitted"]}
    for src in WEIGHT_SOURCES:
        out.update({f"{src}_{k}": v for k, v in s[src].items()})
    for key in GEOMETRY_KEYS:
        v = np.array([r[key] for r in rows if key in r], float)
        if len(v):
            worst = v.max() if key == "chamfer_l1" else v.min()
            out[f"{key}_mean"], out[f"{key}_worst"] = float(v.mean()), float(worst)
    return out


def _fmt(v: float | None, spec: str = ".3f") -> str:
    return "–" if v is None or not np.isfinite(v) else format(v, spec)


def split_table(split: str, rows: Sequence[dict]) -> str:
    """The split's markdown: both weight sources side by side, then every kitchen."""
    head = ["weights", "kitchens", "precision pooled (correct / predicted)", "recall pooled (correct / GT)",
            "EA pooled (revolute parts)", "precision per kitchen: mean ± sd / worst", "recall: mean ± sd / worst",
            "EA: mean ± sd / worst", "motion EMD pooled / worst kitchen"]
    body = []
    for src in WEIGHT_SOURCES:
        s = summarise(rows, src)
        scored = s["n_pred"] - s["n_ignored"]

        def per(key):
            return (f"{_fmt(s.get(f'{key}_mean'))} ± {_fmt(s.get(f'{key}_std'))} / {_fmt(s.get(f'{key}_worst'))}"
                    if f"{key}_mean" in s else "–")

        body.append([src, s["n_kitchens"], f"{_fmt(s.get('precision'))} ({s['n_correct']} / {scored})",
                     f"{_fmt(s.get('recall'))} ({s['n_correct']} / {s['n_gt']})",
                     f"{_fmt(s.get('ea_score'), '.4f')} (n = {s['n_revolute_scored']})", per("precision"),
                     per("recall"), per("ea_score"),
                     f"{_fmt(s.get('emd'), '.2e')} / {_fmt(s.get('emd_worst'), '.2e')} (n = {s['n_emd']})"])
    kitchens = [[r["kitchen"], r["fitted"]["n_gt"], *(f"{_fmt(r[src].get('precision'))} / {_fmt(r[src].get('recall'))}"
                                                      f" / {_fmt(r[src].get('ea_score'), '.3f')}" for src in WEIGHT_SOURCES),
                 _fmt(1000 * r["chamfer_l1"], ".2f") if "chamfer_l1" in r else "–", _fmt(r.get("fscore_2cm"))]
                for r in rows]
    g_kinds, p_kinds, counts = confusion_matrix(rows, "fitted")
    conf = md_table(["GT \\ predicted", *p_kinds], [[g, *c.tolist()] for g, c in zip(g_kinds, counts)])
    return (f"## The {split} split\n\n" + md_table(head, body) + "\n"
            + md_table(["kitchen", "GT parts", "fitted P / R / EA", "prior P / R / EA", "mesh Chamfer-L1 (mm)",
                        "F@2cm"], kitchens)
            + "\nKinds, fitted weights (rows: ground truth, `none` a prediction that matches no GT part; "
              "columns: prediction, `missed` no prediction):\n\n" + conf)


def run_eval(split: str, kitchens: Sequence[int], bench: BenchPaths, cfg: ArticulateConfig,
             weights: dict[str, dict[str, float]], run: StageRun) -> dict:
    """The ``bench_eval`` stage's work: :func:`evaluate_split` into ``run.dir``, its rows
    (``rows.json``) and table (``table.md``); returns :func:`split_metrics`."""
    rows = evaluate_split(split, kitchens, bench, run.dir / bench_name("kitchens"), cfg, weights, run.seed,
                          run.progress)
    write_json(run.dir / bench_name("rows"), rows)
    atomic_write_text(run.dir / LAYOUT["report"]["table"], split_table(split, rows))
    return split_metrics(rows)
