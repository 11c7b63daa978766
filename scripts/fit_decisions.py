#!/usr/bin/env python
"""Fit the weights of the type decision (drawer_lib/articulation/scoring.py) on the train split.

Reads the benchmark runs under ``--bench`` (scripts/bench_articulation.py --split train: each
kitchen's ``articulate/decisions.json`` records every front's features, and its capture holds
the GT), labels each front with the GT hypothesis it belongs to (drawer, door_left / door_right
by the side of the GT hinge, flap_top / flap_bottom, sliding, or fixed for a front no GT part
contains; fronts inside a GT ignore box, fixed fronts that look articulated, carry no label),
and fits a multinomial logistic model with an L2 penalty chosen by leave-kitchens-out
cross-validation. The label-vote weights (lab_drawer, lab_door) are not fitted (the split's
labels are generic) and keep their values from the current config. A hypothesis with fewer
than ``--min-examples`` train examples (``fixed`` on our splits: 4 fronts, every one a
stand-alone panel) gets only its bias fitted; its other weights are the hand-set ones of
``drawer_lib/articulation/config.py`` — four examples would otherwise teach it whatever they
happen to share (here: "no neighbour beside it").

    python scripts/fit_decisions.py --bench /tmp/bench_articulation/train            # report only
    python scripts/fit_decisions.py --bench /tmp/bench_articulation/train --write    # into conf/articulate/default.yaml

then ``python scripts/compose_params.py`` and re-run the benchmark with ``--reuse``.
"""

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from drawer_lib.articulation.scoring import COMMON, DOOR_ONLY, HYPOTHESES, WEIGHT_SETS  # noqa: E402
from drawer_lib.io.parts import Front, read_parts  # noqa: E402
from drawer_lib.paths import capture_name  # noqa: E402

FIXED_BY_HAND = ("lab_drawer", "lab_door")
CONF = ROOT / "conf" / "articulate" / "default.yaml"


def gt_label(front: Front, parts) -> str | None:
    """The hypothesis of the GT part whose front contains this front's centre (same plane
    within 5 cm, normals within 25 deg, sizes within a factor 1.5), None inside an ignore box,
    ``fixed`` otherwise."""
    c, n, u = np.asarray(front.center), np.asarray(front.normal), np.asarray(front.u)
    for p in parts.parts:
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
    if any(b.contains(c) for b in parts.ignore_boxes):
        return None
    return "fixed"


def load(bench: Path) -> list[tuple[str, dict, dict, str]]:
    """[(kitchen dir name, common features, door features {left, right}, label)]."""
    rows = []
    for d in sorted(bench.glob("k*_*")):
        dec_p = d / "articulate" / "decisions.json"
        if not dec_p.is_file():
            continue
        parts = read_parts(d / "capture" / capture_name("gt_parts"))
        for r in json.loads(dec_p.read_text())["segments"]:
            if "features" not in r:
                continue
            lab = gt_label(Front.from_json(r["front"], f"{dec_p}: front"), parts)
            if lab is not None:
                rows.append((d.name, r["features"], r["door_features"], lab))
    return rows


def tensors(rows):
    """X_common [N, C], X_door [N, 2, D] (left, right), y [N]."""
    Xc = torch.tensor([[f[k] for k in COMMON] for _, f, _, _ in rows], dtype=torch.float64)
    Xd = torch.tensor([[[df[s][k] for k in DOOR_ONLY] for s in ("left", "right")] for _, _, df, _ in rows],
                      dtype=torch.float64)
    y = torch.tensor([HYPOTHESES.index(lab) for *_, lab in rows])
    return Xc, Xd, y


def scores(W: dict[str, torch.Tensor], Xc, Xd) -> torch.Tensor:
    """[N, len(HYPOTHESES)] in the order of HYPOTHESES."""
    cols = []
    for h in HYPOTHESES:
        if h.startswith("door_"):
            s = 0 if h == "door_left" else 1
            cols.append(Xc @ W["door"][:len(COMMON)] + Xd[:, s] @ W["door"][len(COMMON):])
        else:
            cols.append(Xc @ W[h])
    return torch.stack(cols, -1)


def fit(Xc, Xd, y, lam: float, fixed: dict[str, dict[str, float]], min_examples: int = 0) -> dict[str, torch.Tensor]:
    """Weights minimising the mean cross-entropy + lam * sum of squared fitted weights; the
    hand-set label weights, and every weight of a hypothesis without examples in ``y``, stay
    at ``fixed`` (the config's); a hypothesis with fewer than ``min_examples`` gets only its
    bias fitted, its other weights from :func:`_default_weights` (hand-set)."""
    from drawer_lib.articulation.config import _default_weights

    hand = _default_weights()
    free_mask = torch.tensor([k not in FIXED_BY_HAND and k != "bias" for k in COMMON], dtype=torch.float64)
    family = [h.split("_")[0] if h.startswith("door_") else h for h in HYPOTHESES]
    n_of = {k: int(sum(int((y == i).sum()) for i, f in enumerate(family) if f == k)) for k in WEIGHT_SETS}
    seen = {k for k, n in n_of.items() if n > 0}
    few = {k for k, n in n_of.items() if 0 < n < min_examples}
    W, base, masks = {}, {}, {}
    for k in WEIGHT_SETS:
        names = COMMON + (DOOR_ONLY if k == "door" else ())
        W[k] = torch.zeros(len(names), dtype=torch.float64, requires_grad=True)
        keep = [f in FIXED_BY_HAND or k not in seen or (k in few and f != "bias") for f in names]
        base[k] = torch.tensor([(hand[k].get(f, 0.0) if k in few and f not in FIXED_BY_HAND else fixed.get(k, {}).get(f, 0.0))
                                if kp else 0.0 for f, kp in zip(names, keep)], dtype=torch.float64)
        masks[k] = torch.tensor([0.0 if kp else 1.0 for kp in keep], dtype=torch.float64)
    opt = torch.optim.LBFGS(list(W.values()), lr=1, max_iter=500, tolerance_grad=1e-9, line_search_fn="strong_wolfe")

    def full():
        return {k: base[k] + masks[k] * W[k] for k in WEIGHT_SETS}

    def closure():
        opt.zero_grad()
        Wf = full()
        loss = torch.nn.functional.cross_entropy(scores(Wf, Xc, Xd), y)
        pen = sum(((masks[k][:len(COMMON)] * free_mask) * W[k][:len(COMMON)]).pow(2).sum()
                  + (masks[k][len(COMMON):] * W[k][len(COMMON):]).pow(2).sum() for k in WEIGHT_SETS)
        loss = loss + lam * pen
        loss.backward()
        return loss

    opt.step(closure)
    return {k: v.detach() for k, v in full().items()}


def current_weights() -> dict[str, dict[str, float]]:
    import yaml

    return yaml.safe_load(CONF.read_text())["types"]["weights"]


def yaml_block(W: dict[str, torch.Tensor]) -> str:
    lines = ["  weights:                      # fitted by scripts/fit_decisions.py on the train split (see its docstring)"]
    for k in WEIGHT_SETS:
        names = COMMON + (DOOR_ONLY if k == "door" else ())
        items = ", ".join(f"{f}: {float(v):.3f}" for f, v in zip(names, W[k]) if abs(float(v)) >= 5e-4)
        lines.append(f"    {k}: {{{items}}}")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bench", type=Path, required=True, help="a train-split benchmark folder (…/train)")
    ap.add_argument("--lams", default="0.00001,0.00003,0.0001,0.0003,0.001,0.003,0.01,0.03,0.1")
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--min-examples", type=int, default=10,
                    help="hypotheses with fewer train examples: only the bias is fitted (the rest hand-set)")
    ap.add_argument("--write", action="store_true", help="replace the weights block of conf/articulate/default.yaml")
    a = ap.parse_args()
    if a.bench.name != "train":
        sys.exit(f"--bench {a.bench}: fit on the train split only (a folder named train)")
    rows = load(a.bench)
    if not rows:
        sys.exit(f"{a.bench}: no decisions.json with features (run scripts/bench_articulation.py --split train)")
    fixed = current_weights()
    Xc, Xd, y = tensors(rows)
    kitchens = sorted({r[0] for r in rows})
    fold_of = {k: i % a.folds for i, k in enumerate(kitchens)}
    fold = torch.tensor([fold_of[r[0]] for r in rows])
    counts = {h: int((y == i).sum()) for i, h in enumerate(HYPOTHESES)}
    print(f"{len(rows)} fronts from {len(kitchens)} kitchens: {counts}")
    best = None
    for lam in map(float, a.lams.split(",")):
        correct = 0
        for f in range(a.folds):
            tr, te = fold != f, fold == f
            if te.sum() == 0:
                continue
            W = fit(Xc[tr], Xd[tr], y[tr], lam, fixed, a.min_examples)
            correct += int((scores(W, Xc[te], Xd[te]).argmax(-1) == y[te]).sum())
        acc = correct / len(y)
        print(f"lambda {lam:g}: leave-kitchens-out accuracy {acc:.4f} ({correct}/{len(y)})")
        if best is None or acc >= best[1] - 1e-12:  # ties go to the larger penalty
            best = (lam, acc)
    W = fit(Xc, Xd, y, best[0], fixed, a.min_examples)
    pred = scores(W, Xc, Xd).argmax(-1)
    print(f"chosen lambda {best[0]:g}; train accuracy {float((pred == y).double().mean()):.4f}")
    conf = np.zeros((len(HYPOTHESES), len(HYPOTHESES)), int)
    for t, p in zip(y.tolist(), pred.tolist()):
        conf[t, p] += 1
    print("confusion (rows: GT, columns: predicted):\n" + " " * 12 + " ".join(f"{h[:10]:>10s}" for h in HYPOTHESES))
    for i, h in enumerate(HYPOTHESES):
        print(f"{h:>12s}" + " ".join(f"{v:10d}" for v in conf[i]))
    block = yaml_block(W)
    print(block)
    if a.write:
        text = CONF.read_text()
        new, n = re.subn(r"  weights:.*?\n(?=\S)", block, text, count=1, flags=re.S)
        if n != 1:
            sys.exit(f"{CONF}: no weights block under types to replace")
        CONF.write_text(new)
        print(f"wrote {CONF}")


if __name__ == "__main__":
    main()
