#!/usr/bin/env python
"""Why the parts a ``scripts/bench_detect.py`` run predicted wrongly are wrong, from the outputs
it left (nothing is rerun): for each predicted articulated part that precision counts against,
one of ``wrong_kind`` (on a true front, another joint kind), ``off_front`` (touching one true
front, IoU under the match threshold: split from it or mis-sized), ``merged`` (touching two or
more) or ``no_front`` (:func:`drawer_lib.metrics.articulation.wrong_parts`), and the commonest
(true kind -> predicted kind) pairs of the wrongly typed. With ``--decisions``, each wrongly typed
part is listed with what articulate recorded for its front in ``decisions.json``: its size (m),
the score margin over the runner-up, the handle's orientation, the hypotheses excluded, the
reason. Each split's line is followed by the precision of the parts articulate flagged
``low_margin`` and of the others (:func:`drawer_lib.metrics.articulation.precision_by_flag`):
what the flag is worth as "check this one first". With ``--missed``, the other side: each true part recall counts as not found, and why
(``wrong_kind``, ``merged`` into a front that touches a neighbour too, ``off_front``, or
``no_part``: no predicted articulated front touches it;
:func:`drawer_lib.metrics.articulation.missed_parts`), by its true kind. Look only at kitchens
you tune on.

    python scripts/wrong_parts.py OUT/train --tag swa                  # by_detector/builtin-swa/
    python scripts/wrong_parts.py OUT1/train OUT2/train --model capture
    python scripts/wrong_parts.py OUT/train --tag swa --decisions      # and why each wrong type won
    python scripts/wrong_parts.py OUT/train --tag swa --missed         # and why each true part was not found
"""

import argparse
import collections
import json
from pathlib import Path

from bench_detect import variant  # the folder bench_detect writes a model's parts to
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.articulation import (MISSED_WHY, WRONG_WHY, match_parts, missed_parts, precision_by_flag,
                                             wrong_parts)
from drawer_lib.paths import ScenePaths, capture_name


def decision_fields(segment: dict | None) -> dict:
    """What a front's entry in articulate's ``decisions.json`` says about its type: ``size``
    ([w, h] m), ``margin`` (its score over the runner-up's), ``runner_up``, ``handle`` (the
    handle's orientation, None without one), ``excluded`` (the hypotheses ruled out) and
    ``reason``; ``{"decision": None}`` when the part has no entry."""
    if segment is None:
        return {"decision": None}
    return {"size": segment.get("size"), "margin": segment.get("margin"), "runner_up": segment.get("runner_up"),
            "handle": (segment.get("handle") or {}).get("orientation"),
            "excluded": sorted(segment.get("excluded") or {}), "reason": segment.get("reason")}


def flag_line(flags: dict) -> str:
    """``flags`` ({True: [correct, counted], False: [...]}) as the line printed after a split's."""
    return "; ".join(f"{name} {r}/{n} right ({r / n:.3f})" if n else f"{name} none"
                     for name, (r, n) in (("flagged low_margin", flags[True]), ("the others", flags[False])))


def split_rows(split_dir: Path, folder: str, decisions: bool = False, missed: list | None = None,
               flags: dict | None = None) -> list[dict]:
    """The wrong parts of every built kitchen of ``split_dir`` scored from ``by_detector/<folder>``,
    each with its ``kitchen``; with ``decisions``, the wrongly typed ones with
    :func:`decision_fields` of their front. ``missed``: a list that the true parts not found
    (:func:`missed_parts`, each with its ``kitchen``) are appended to. ``flags``: {True: [correct,
    counted], False: [...]}, to which each kitchen's :func:`precision_by_flag` is added."""
    kitchens = sorted(split_dir.glob("kitchen_*"), key=lambda p: int(p.name.split("_")[-1]))
    if not kitchens:
        raise SystemExit(f"error: {split_dir}: no kitchen_* folders (a bench_detect --out DIR writes DIR/<split>/)")
    rows = []
    for k in kitchens:
        sp = ScenePaths(k.parent, k.name)
        pred = ScenePaths(k / "by_detector", folder).parts
        if not pred.is_file():
            raise SystemExit(f"error: {pred}: missing (was bench_detect run with this --tag and model?)")
        m = match_parts(read_parts(pred), read_parts(sp.capture / capture_name("gt_parts")))
        found = [{"kitchen": k.name, **r} for r in wrong_parts(m)]
        if flags is not None:
            for side, (right, n) in precision_by_flag(m).items():
                flags[side][0] += right
                flags[side][1] += n
        if missed is not None:
            missed += [{"kitchen": k.name, **r} for r in missed_parts(m)]
        if decisions and any(r["why"] == "wrong_kind" for r in found):
            path = ScenePaths(k / "by_detector", folder).file("articulate", "decisions")
            if not path.is_file():
                raise SystemExit(f"error: {path}: missing (--decisions reads articulate's record of each front)")
            try:
                by_part = {s["part"]: s for s in json.loads(path.read_text())["segments"] if s.get("part")}
            except (ValueError, KeyError, TypeError, AttributeError) as e:
                raise SystemExit(f"error: {path}: not an articulation decisions file ({e!r})") from None
            found = [{**r, **decision_fields(by_part.get(r["part"]))} if r["why"] == "wrong_kind" else r for r in found]
        rows += found
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("splits", nargs="+", type=Path, help="bench_detect --out DIR's split folders (DIR/train, ...)")
    ap.add_argument("--model", default="builtin", help="the --detect model (default builtin)")
    ap.add_argument("--tag", default="", help="the bench_detect --tag of the run")
    ap.add_argument("--top", type=int, default=10, help="how many (true -> predicted) pairs to list")
    ap.add_argument("--json", type=Path, help="also write every wrong part here")
    ap.add_argument("--decisions", action="store_true",
                    help="list each wrongly typed part with what decisions.json recorded for its front")
    ap.add_argument("--missed", action="store_true", help="also count why each true part was not found")
    a = ap.parse_args()
    folder = variant(a.model, a.tag)
    everything, not_found = [], []
    pooled = {True: [0, 0], False: [0, 0]}
    for d in a.splits:
        missed = [] if a.missed else None
        flags = {True: [0, 0], False: [0, 0]}
        rows = split_rows(d, folder, a.decisions, missed, flags)
        c = collections.Counter(r["why"] for r in rows)
        print(f"{d} ({folder}): {len(rows)} wrong: " + ", ".join(f"{w} {c[w]}" for w in WRONG_WHY))
        print(f"{d} ({folder}): {flag_line(flags)}")
        for side in (True, False):
            pooled[side][0] += flags[side][0]
            pooled[side][1] += flags[side][1]
        everything += [{"split": str(d), **r} for r in rows]
        if missed is not None:
            c = collections.Counter(r["why"] for r in missed)
            print(f"{d} ({folder}): {len(missed)} true parts not found: " + ", ".join(f"{w} {c[w]}" for w in MISSED_WHY))
            not_found += [{"split": str(d), **r} for r in missed]
    if len(a.splits) > 1:
        print(f"all: {flag_line(pooled)}")
    typed = collections.Counter((r["gt_kind"], r["pred_kind"]) for r in everything if r["why"] == "wrong_kind")
    print(f"all: {len(everything)} wrong, {sum(typed.values())} of them wrongly typed; true -> predicted:")
    for (g, p), n in typed.most_common(a.top):
        print(f"  {n:3d}  {g} -> {p}")
    if a.decisions:
        print("wrongly typed, by true -> predicted kind:")
        for r in sorted((r for r in everything if r["why"] == "wrong_kind"), key=lambda r: (r["gt_kind"], r["pred_kind"])):
            where = f"  {r['gt_kind']} -> {r['pred_kind']}  {r['split']} {r['kitchen']} {r['part']}:"
            if "reason" not in r:  # decision_fields found no entry for it
                print(f"{where} no decision recorded")
                continue
            w, h = r["size"] or (float("nan"), float("nan"))
            print(f"{where} {w:.2f} x {h:.2f} m, margin {r['margin']:.2f} over {r['runner_up']}, handle {r['handle']}"
                  + (f", excluded {', '.join(r['excluded'])}" if r["excluded"] else "") + f"; {r['reason']}")
    if a.missed:
        print(f"all: {len(not_found)} true parts not found; by true kind and why:")
        by_kind = collections.Counter((r["gt_kind"], r["why"]) for r in not_found)
        for (g, w), n in sorted(by_kind.items(), key=lambda kv: (-kv[1], kv[0])):
            print(f"  {n:3d}  {g}: {w}")
    if a.json:
        a.json.write_text(json.dumps(everything + [{"missed": True, **r} for r in not_found], indent=1))


if __name__ == "__main__":
    main()
