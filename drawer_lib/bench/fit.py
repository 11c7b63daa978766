"""Fit the type decision's weights (:mod:`drawer_lib.articulation.scoring`) on the benchmark's
train split: the ``fit_decisions`` stage.

Every train kitchen's articulation (with the prior weights: a front's features do not depend
on the weights) records each front's features in ``decisions.json``. Each front is labelled with
the ground-truth hypothesis it belongs to (:func:`gt_label`: drawer, door_left / door_right by the
side of the GT hinge, flap_top / flap_bottom, sliding, or fixed for a front no GT part
contains; fronts inside a GT ignore box carry no label), and a multinomial logistic model is
fitted with an L2 penalty chosen by leave-kitchens-out cross-validation. The label-vote weights
(:data:`~drawer_lib.articulation.vocab.LABEL_FEATURES`) are not fitted (generic detections
carry no labels to fit them on) and keep their prior values. A hypothesis with fewer than
``min_examples`` train fronts gets only its bias fitted, its other weights from the prior: a few
examples would otherwise teach it whatever they happen to share. A feature that is 0 on every
train front (a cue the train kitchens never show, such as a tall stacked front without a handle)
keeps its prior weight too: the data say nothing about it, and the penalty alone would drive it
to 0 and silently drop a cue the prior put there on purpose.
"""

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.vocab import COMMON, DOOR_ONLY, HYPOTHESES, LABEL_FEATURES, WEIGHT_SETS, weight_set
from drawer_lib.articulation.weights import write_weights
from drawer_lib.bench.cases import run_cases
from drawer_lib.bench.config import BenchConfig
from drawer_lib.errors import InputError
from drawer_lib.io.images import write_json
from drawer_lib.io.parts import Front, PartsFile, read_parts
from drawer_lib.paths import BenchPaths, bench_name, capture_name
from drawer_lib.runner import StageRun

Row = tuple[str, dict[str, float], dict[str, dict[str, float]], str]  # (kitchen, features, door features, label)


def gt_label(front: Front, gt: PartsFile) -> str | None:
    """The hypothesis of the GT part whose front contains this front's centre (same plane
    within 5 cm, normals within 25 deg, sizes within a factor 1.5); None inside a GT ignore box;
    ``fixed`` otherwise."""
    c, n, u = np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u)
    for p in gt.parts:
        if not p.articulated:
            continue
        g = p.front
        gc, gn = np.asarray(g.center), np.asarray(g.normal)
        d = c - gc
        if gn @ n < 0.9 or abs(d @ gn) > 0.05:
            continue
        if abs(d @ np.asarray(g.u)) > g.size[0] / 2 or abs(d @ g.v) > g.size[1] / 2:
            continue
        if max(front.size[0] / g.size[0], g.size[0] / front.size[0], front.size[1] / g.size[1],
               g.size[1] / front.size[1]) > 1.5:
            continue
        o, a = np.asarray(p.axis.origin), np.asarray(p.axis.direction)
        if p.kind == "revolute":
            if abs(a[2]) > 0.7:
                return "door_left" if (o - c) @ u < 0 else "door_right"
            return "flap_top" if o[2] > c[2] else "flap_bottom"
        return "drawer" if abs(a @ n) > 0.7 else "sliding"
    if any(b.contains(c) for b in gt.ignore_boxes):
        return None
    return "fixed"


def labelled_fronts(kitchen: str, decisions: Path, gt: PartsFile) -> list[Row]:
    """The fronts of one kitchen's ``decisions.json`` that carry features, with their GT label
    (fronts without a label left out, and the doors of a front read as a pair: their rows carry
    the whole front's features, which the pair rule typed, not the scores)."""
    try:
        segs = json.loads(Path(decisions).read_text())["segments"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(f"{decisions}: not an articulation decisions file ({e})") from None
    rows = []
    for r in segs:
        if "features" not in r or "pair" in r:
            continue
        lab = gt_label(Front.from_json(r["front"], f"{decisions}: segment {r.get('segment')} front"), gt)
        if lab is not None:
            rows.append((kitchen, r["features"], r["door_features"], lab))
    return rows


def tensors(rows: Sequence[Row]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(X_common [N, C], X_door [N, 2, D] (left, right), y [N] indices into HYPOTHESES)."""
    Xc = torch.tensor([[f[k] for k in COMMON] for _, f, _, _ in rows], dtype=torch.float64).reshape(-1, len(COMMON))
    Xd = torch.tensor([[[df[s][k] for k in DOOR_ONLY] for s in ("left", "right")] for _, _, df, _ in rows],
                      dtype=torch.float64).reshape(-1, 2, len(DOOR_ONLY))
    y = torch.tensor([HYPOTHESES.index(lab) for *_, lab in rows], dtype=torch.int64)
    return Xc, Xd, y


def unseen_features(Xc: torch.Tensor, Xd: torch.Tensor) -> frozenset[str]:
    """The names of COMMON and DOOR_ONLY features that are exactly 0 on every row of ``Xc``
    [N, C] and ``Xd`` [N, 2, D] (both sides, for a door feature); all of them when N = 0."""
    zc = (Xc == 0).all(0) if len(Xc) else torch.ones(len(COMMON), dtype=torch.bool)
    zd = (Xd == 0).all(0).all(0) if len(Xd) else torch.ones(len(DOOR_ONLY), dtype=torch.bool)
    return frozenset([k for k, z in zip(COMMON, zc.tolist()) if z] + [k for k, z in zip(DOOR_ONLY, zd.tolist()) if z])


def scores(W: dict[str, torch.Tensor], Xc: torch.Tensor, Xd: torch.Tensor) -> torch.Tensor:
    """[N, len(HYPOTHESES)] in the order of HYPOTHESES (``W[set]``: weights in the order of
    :func:`~drawer_lib.articulation.vocab.set_features`)."""
    cols = []
    for h in HYPOTHESES:
        if h.startswith("door_"):
            s = 0 if h == "door_left" else 1
            cols.append(Xc @ W["door"][:len(COMMON)] + Xd[:, s] @ W["door"][len(COMMON):])
        else:
            cols.append(Xc @ W[h])
    return torch.stack(cols, -1)


def fit(Xc: torch.Tensor, Xd: torch.Tensor, y: torch.Tensor, lam: float, prior: dict[str, dict[str, float]],
        min_examples: int = 0, centre: str = "zero") -> dict[str, torch.Tensor]:
    """Weights minimising the mean cross-entropy + ``lam`` x the sum of squared fitted weights,
    biases included (unpenalised, they would all rise together without bound whenever a
    hypothesis has no example: that lowers its probability at no cost); with ``centre="prior"``
    the penalty is on each fitted weight's distance from its prior value instead, so a cue the
    train fronts say little about stays near the prior rather than near 0. Kept at the
    ``prior``'s values: the label weights, every weight of a hypothesis without examples in
    ``y``, all but the bias of one with fewer than ``min_examples``, and the weights of the
    features that are 0 on every row (:func:`unseen_features`). Deterministic (float64 L-BFGS
    from zeros)."""
    if centre not in ("zero", "prior"):
        raise ValueError(f"fit: centre {centre!r} is not zero or prior")
    unseen = unseen_features(Xc, Xd)
    free_mask = torch.tensor([k not in LABEL_FEATURES for k in COMMON], dtype=torch.float64)
    family = [weight_set(h) for h in HYPOTHESES]
    n_of = {k: int(sum(int((y == i).sum()) for i, f in enumerate(family) if f == k)) for k in WEIGHT_SETS}
    seen = {k for k, n in n_of.items() if n > 0}
    few = {k for k, n in n_of.items() if 0 < n < min_examples}
    W, base, masks = {}, {}, {}
    for k in WEIGHT_SETS:
        names = COMMON + (DOOR_ONLY if k == "door" else ())
        W[k] = torch.zeros(len(names), dtype=torch.float64, requires_grad=True)
        keep = [f in LABEL_FEATURES or f in unseen or k not in seen or (k in few and f != "bias") for f in names]
        base[k] = torch.tensor([prior.get(k, {}).get(f, 0.0) if kp or centre == "prior" else 0.0
                                for f, kp in zip(names, keep)], dtype=torch.float64)
        masks[k] = torch.tensor([0.0 if kp else 1.0 for kp in keep], dtype=torch.float64)
    opt = torch.optim.LBFGS(list(W.values()), lr=1, max_iter=500, tolerance_grad=1e-9, line_search_fn="strong_wolfe")

    def full():
        return {k: base[k] + masks[k] * W[k] for k in WEIGHT_SETS}

    def closure():
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(scores(full(), Xc, Xd), y)
        pen = sum(((masks[k][:len(COMMON)] * free_mask) * W[k][:len(COMMON)]).pow(2).sum()
                  + (masks[k][len(COMMON):] * W[k][len(COMMON):]).pow(2).sum() for k in WEIGHT_SETS)
        loss = loss + lam * pen
        loss.backward()
        return loss

    if len(y):
        opt.step(closure)
    return {k: v.detach() for k, v in full().items()}


def as_dict(W: dict[str, torch.Tensor], ndigits: int = 4) -> dict[str, dict[str, float]]:
    """{set: {feature: weight}}, rounded to ``ndigits`` and without the weights that round to 0."""
    out = {}
    for k in WEIGHT_SETS:
        names = COMMON + (DOOR_ONLY if k == "door" else ())
        out[k] = {f: round(float(v), ndigits) for f, v in zip(names, W[k]) if round(float(v), ndigits) != 0.0}
    return out


@dataclass(frozen=True)
class FitResult:
    """The chosen ``weights``, the penalty ``lam``, the cross-validated accuracy of every penalty
    tried (``cv``: [(lam, accuracy)]), the train accuracy and confusion (rows: GT, columns:
    predicted, in the order of HYPOTHESES), the fronts per hypothesis, the kitchens, and the
    features no train front shows (``unseen``: their weights are the prior's)."""

    weights: dict[str, dict[str, float]]
    lam: float
    cv: list[tuple[float, float]]
    train_accuracy: float
    confusion: list[list[int]]
    counts: dict[str, int]
    kitchens: list[str]
    unseen: list[str]

    def record(self) -> dict:
        """The ``fit`` block of the weights file and the stage's metrics."""
        return {"lambda": self.lam, "cv_accuracy": dict((f"{lam:g}", round(a, 6)) for lam, a in self.cv),
                "train_accuracy": round(self.train_accuracy, 6), "fronts": self.counts,
                "n_fronts": int(sum(self.counts.values())), "kitchens": self.kitchens,
                "unseen_features_kept_prior": self.unseen,
                "confusion": {"hypotheses": list(HYPOTHESES), "rows_gt_cols_pred": self.confusion}}


def select_penalty(cv: Sequence[tuple[float, float]], n: int, rule: str = "one_se") -> float:
    """The penalty of ``cv`` = [(lambda, CV accuracy over ``n`` fronts)]: ``best``: the highest
    accuracy (ties: the larger penalty); ``one_se``: the largest penalty whose accuracy is within
    one binomial standard error sqrt(a (1 - a) / n) of the best accuracy a."""
    best_lam, best_acc = max(reversed(sorted(cv)), key=lambda t: t[1])
    if rule == "best":
        return best_lam
    if rule != "one_se":
        raise ValueError(f"select_penalty: rule {rule!r} is not one_se or best")
    se = float(np.sqrt(best_acc * (1.0 - best_acc) / max(n, 1)))
    return max(lam for lam, acc in cv if acc >= best_acc - se - 1e-12)


def fit_decisions(rows: Sequence[Row], prior: dict[str, dict[str, float]], lambdas: Sequence[float], folds: int,
                  min_examples: int, log: Callable[[int, float, float], None] | None = None,
                  select: str = "one_se", centre: str = "zero") -> FitResult:
    """Choose the penalty by leave-kitchens-out cross-validation (kitchen i of the sorted names
    in fold i mod ``folds``; :func:`select_penalty` with rule ``select``), then fit all
    ``rows`` with it (penalty towards ``centre``, :func:`fit`). ``log(i, lam, accuracy)`` after
    each penalty."""
    if not rows:
        raise InputError("fit_decisions: no labelled fronts with features in the train kitchens")
    if folds < 2 or not lambdas:
        raise InputError(f"fit_decisions: need folds >= 2 (got {folds}) and at least one lambda")
    Xc, Xd, y = tensors(rows)
    kitchens = sorted({r[0] for r in rows})
    fold_of = {k: i % folds for i, k in enumerate(kitchens)}
    fold = torch.tensor([fold_of[r[0]] for r in rows])
    cv = []
    for i, lam in enumerate(lambdas):
        correct = 0
        for f in range(folds):
            tr, te = fold != f, fold == f
            if te.sum() == 0:
                continue
            W = fit(Xc[tr], Xd[tr], y[tr], float(lam), prior, min_examples, centre)
            correct += int((scores(W, Xc[te], Xd[te]).argmax(-1) == y[te]).sum())
        cv.append((float(lam), correct / len(y)))
        if log is not None:
            log(i, float(lam), cv[-1][1])
    lam = select_penalty(cv, len(y), select)
    W = fit(Xc, Xd, y, lam, prior, min_examples, centre)
    pred = scores(W, Xc, Xd).argmax(-1)
    conf = np.zeros((len(HYPOTHESES), len(HYPOTHESES)), int)
    for t, p in zip(y.tolist(), pred.tolist()):
        conf[t, p] += 1
    return FitResult(as_dict(W), lam, cv, float((pred == y).double().mean()), conf.tolist(),
                     {h: int((y == i).sum()) for i, h in enumerate(HYPOTHESES)}, kitchens,
                     sorted(unseen_features(Xc, Xd)))


def run_fit(cfg: BenchConfig, ac: ArticulateConfig, bench: BenchPaths, run: StageRun) -> dict:
    """The ``fit_decisions`` stage's work: the labelled fronts of the train kitchens
    ``cfg.kitchens`` (each built by the ``bench_kitchen`` stage), the fit from ``ac.types.prior``,
    ``weights.json``, ``cv.csv`` and the hand-built cases with the fitted weights
    (:mod:`drawer_lib.bench.cases`, ``cases.json``) in ``run.dir``; returns the metrics."""
    rows: list[Row] = []
    for k in run.progress(cfg.kitchens, desc="train kitchens"):
        kp = bench.kitchen("train", k)
        gt = read_parts(kp.capture / capture_name("gt_parts"))
        rows += labelled_fronts(kp.scene, kp.file("articulate", "decisions"), gt)
    curve = run.curve(["lambda", "cv_accuracy"], name=bench_name("cv"))
    res = fit_decisions(rows, ac.types.prior, cfg.fit.lambdas, cfg.fit.folds, cfg.fit.min_examples,
                        log=lambda i, lam, acc: curve.log(i, **{"lambda": lam, "cv_accuracy": acc}),
                        select=cfg.fit.select, centre=cfg.fit.centre)
    rec = res.record()
    write_weights(run.dir / bench_name("weights"), res.weights, rec)
    cases = run_cases(ac, res.weights)
    write_json(run.dir / bench_name("cases"), cases)
    return {"lambda": res.lam, "cv_accuracy": dict(res.cv)[res.lam], "cv_accuracy_best": max(a for _, a in res.cv),
            "train_accuracy": res.train_accuracy,
            "n_fronts": rec["n_fronts"], "n_kitchens": len(res.kitchens), "n_unseen_features": len(res.unseen),
            **{f"n_{h}": n for h, n in res.counts.items()},
            "cases_passed": sum(c["passed"] for c in cases), "cases_total": len(cases)}
