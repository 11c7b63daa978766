"""Two settings of ``scripts/bench_detect.py`` compared on the same kitchens: each one's pooled
parts precision / recall / F1 (found / predicted), its mean EA-score, and the change with a 90 %
interval from resampling the kitchens (paired: both settings on the same draws;
``drawer_lib.bench.resample``). Pairs of summaries, each ``BASE OTHER`` (the ``summary-TAG.json``
files bench_detect writes) on the same kitchens, are compared one by one and then pooled (their
kitchens together, still paired).

    python scripts/compare_detect.py OUT/gapdense/train/summary-cur.json OUT/gapdense/train/summary-g1.json
    python scripts/compare_detect.py A/summary-cur.json A/summary-g1.json B/summary-cur.json B/summary-g1.json --json out.json

Settings fitted more than once (a detector from several seeds), each fit's summary on the same
kitchens: ``--base`` and ``--other`` take the fits of each side. Each side is pooled over its
fits and kitchens, each fit's own figures are printed beside it (how far two fits of one setting
lie apart), and the change's interval draws the fits as well as the kitchens
(``drawer_lib.bench.resample.resample_fits``):

    python scripts/compare_detect.py --base OUT/ht/hand_tune/summary-d0.json OUT/ht/hand_tune/summary-d1.json \
        --other OUT/ht/hand_tune/summary-c0.json OUT/ht/hand_tune/summary-c1.json
"""

import argparse
import json
from pathlib import Path

import numpy as np

from drawer_lib.bench.resample import pooled_prf, resample_fits, resample_kitchens


def counts(path: Path, model: str) -> tuple[list[int], np.ndarray, list[float]]:
    """(kitchens, [K, 3] found / predicted / true, EA-scores) of ``model`` in a bench_detect summary."""
    try:
        summ = json.loads(path.read_text())
        rows = [(r["kitchen"], r[model]) for r in summ["rows"]]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise SystemExit(f"error: {path}: not a bench_detect summary with model {model!r} ({e.__class__.__name__}: {e})")
    c = np.array([[m["n_correct"], m["n_pred"], m["n_gt"]] for _, m in rows], dtype=np.int64).reshape(-1, 3)
    return [k for k, _ in rows], c, [m["ea_score"] for _, m in rows if m.get("ea_score") is not None]


def _side(c: np.ndarray, ea: list[float], interval: dict) -> dict:
    """One setting's pooled figures over the counts ``c`` [..., 3] (kitchens, or fits x kitchens)."""
    p, r, f1 = pooled_prf(c.reshape(-1, 3))
    return {"precision": float(p), "recall": float(r), "f1": float(f1), "found": int(c[..., 0].sum()),
            "predicted": int(c[..., 1].sum()), "true": int(c[..., 2].sum()),
            "ea_mean": float(np.mean(ea)) if ea else None, "interval": interval}


def _with_change(base: dict, other: dict, interval: dict) -> dict:
    change = {k: other[k] - base[k] for k in ("precision", "recall", "f1")}
    return {"base": base, "other": other, "change": {**change, "interval": interval}}


def compare(base: np.ndarray, other: np.ndarray, ea: tuple[list[float], list[float]], draws: int, seed: int) -> dict:
    iv = resample_kitchens(base, other, draws=draws, seed=seed)
    out = _with_change(_side(base, ea[0], iv["base"]), _side(other, ea[1], iv["other"]), iv["change"])
    out["kitchens"] = len(base)
    return out


def compare_fits(base: list[np.ndarray], other: list[np.ndarray], ea: tuple[list[float], list[float]], draws: int,
                 seed: int) -> dict:
    """:func:`compare` of two settings fitted several times (each a list of per-fit [K, 3]
    counts on the same kitchens): each side pooled over its fits, found / predicted / true summed
    over them too, each fit's own precision / recall / F1 under ``fits``, and intervals from
    :func:`~drawer_lib.bench.resample.resample_fits`."""
    a, b = np.stack(base), np.stack(other)
    iv = resample_fits(a, b, draws=draws, seed=seed)
    sides = []
    for name, c, e in (("base", a, ea[0]), ("other", b, ea[1])):
        sides.append({**_side(c, e, iv[name]),
                      "fits": [dict(zip(("precision", "recall", "f1"), map(float, pooled_prf(f)))) for f in c]})
    out = _with_change(*sides, iv["change"])
    out["kitchens"], out["fits"] = a.shape[1], [len(a), len(b)]
    return out


def line(label: str, r: dict, parts: int | None = None) -> str:
    """One table row of a comparison ``r``; ``parts``: the true parts shown (default: the base's)."""
    def one(s: dict) -> str:
        ea = "–" if s["ea_mean"] is None else f"{s['ea_mean']:.2f}"
        each = "" if "fits" not in s else "; fits " + ", ".join(f"{f['recall']:.3f} / F1 {f['f1']:.3f}" for f in s["fits"])
        return (f"{s['precision']:.3f} / {s['recall']:.3f} ({s['found']} / {s['predicted']}), F1 {s['f1']:.3f}, EA {ea}{each}")
    c, iv = r["change"], r["change"]["interval"]
    ch = "; ".join(f"{k} {c[k]:+.3f} [{iv[k][0]:+.3f}, {iv[k][1]:+.3f}]" for k in ("precision", "recall", "f1"))
    return f"| {label} | {r['base']['true'] if parts is None else parts} | {one(r['base'])} | {one(r['other'])} | {ch} |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("summaries", type=Path, nargs="*", help="BASE OTHER [BASE OTHER ...]")
    ap.add_argument("--base", type=Path, nargs="+", help="several fits of the base setting (instead of pairs)")
    ap.add_argument("--other", type=Path, nargs="+", help="several fits of the other setting, on the same kitchens")
    ap.add_argument("--model", default="builtin", help="the --detect model compared (default: builtin)")
    ap.add_argument("--draws", type=int, default=5000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    a = ap.parse_args()
    if a.base or a.other:
        if a.summaries or not (a.base and a.other):
            raise SystemExit("error: --base and --other go together, and without BASE OTHER pairs")
        sides = [[counts(p, a.model) for p in group] for group in (a.base, a.other)]
        kitchens = {tuple(k) for side in sides for k, _, _ in side}
        if len(kitchens) != 1:
            raise SystemExit(f"error: the summaries score different kitchens ({sorted(kitchens)}): compare the same kitchens")
        r = compare_fits([c for _, c, _ in sides[0]], [c for _, c, _ in sides[1]],
                         (sum((e for _, _, e in sides[0]), []), sum((e for _, _, e in sides[1]), [])), a.draws, a.seed)
        print("| fits | parts | base: precision / recall (found / predicted, all fits), F1, EA; each fit's recall / F1 | other "
              "| change, 90 % interval over kitchens and fits |\n|---|---|---|---|---|")
        print(line(f"{len(a.base)} against {len(a.other)}", r, parts=int(sides[0][0][1][:, 2].sum())))
        if a.json:
            a.json.write_text(json.dumps(r, indent=2))
        return
    if not a.summaries or len(a.summaries) % 2:
        raise SystemExit(f"error: {len(a.summaries)} summaries; pairs BASE OTHER are needed")
    pairs, results = [], {}
    for b, o in zip(a.summaries[::2], a.summaries[1::2]):
        kb, cb, eb = counts(b, a.model)
        ko, co, eo = counts(o, a.model)
        if kb != ko:
            raise SystemExit(f"error: {b} scores kitchens {kb}, {o} {ko}: compare the same kitchens")
        pairs.append((cb, co, eb, eo))
        results[f"{b} -> {o}"] = compare(cb, co, (eb, eo), a.draws, a.seed)
    print("| summaries | parts | base: precision / recall (found / predicted), F1, EA | other | change, 90 % interval |\n"
          "|---|---|---|---|---|")
    for label, r in results.items():
        print(line(label, r))
    if len(pairs) > 1:
        cat = [np.concatenate([p[i] for p in pairs]) for i in (0, 1)]
        results["pooled"] = compare(cat[0], cat[1], (sum((p[2] for p in pairs), []), sum((p[3] for p in pairs), [])),
                                    a.draws, a.seed)
        print(line("pooled", results["pooled"]))
    if a.json:
        a.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
