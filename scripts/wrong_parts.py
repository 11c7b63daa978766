#!/usr/bin/env python
"""Why the parts a ``scripts/bench_detect.py`` run predicted wrongly are wrong, from the outputs
it left (nothing is rerun): for each predicted articulated part that precision counts against,
one of ``wrong_kind`` (on a true front, another joint kind), ``off_front`` (touching one true
front, IoU under the match threshold: split from it or mis-sized), ``merged`` (touching two or
more) or ``no_front`` (:func:`drawer_lib.metrics.articulation.wrong_parts`), and the commonest
(true kind -> predicted kind) pairs of the wrongly typed. Look only at kitchens you tune on.

    python scripts/wrong_parts.py OUT/train --tag swa                  # by_detector/builtin-swa/
    python scripts/wrong_parts.py OUT1/train OUT2/train --model capture
"""

import argparse
import collections
import json
from pathlib import Path

from bench_detect import variant  # the folder bench_detect writes a model's parts to
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.articulation import WRONG_WHY, match_parts, wrong_parts
from drawer_lib.paths import ScenePaths, capture_name


def split_rows(split_dir: Path, folder: str) -> list[dict]:
    """The wrong parts of every built kitchen of ``split_dir`` scored from ``by_detector/<folder>``,
    each with its ``kitchen``."""
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
        rows += [{"kitchen": k.name, **r} for r in wrong_parts(m)]
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("splits", nargs="+", type=Path, help="bench_detect --out DIR's split folders (DIR/train, ...)")
    ap.add_argument("--model", default="builtin", help="the --detect model (default builtin)")
    ap.add_argument("--tag", default="", help="the bench_detect --tag of the run")
    ap.add_argument("--top", type=int, default=10, help="how many (true -> predicted) pairs to list")
    ap.add_argument("--json", type=Path, help="also write every wrong part here")
    a = ap.parse_args()
    folder = variant(a.model, a.tag)
    everything = []
    for d in a.splits:
        rows = split_rows(d, folder)
        c = collections.Counter(r["why"] for r in rows)
        print(f"{d} ({folder}): {len(rows)} wrong: " + ", ".join(f"{w} {c[w]}" for w in WRONG_WHY))
        everything += [{"split": str(d), **r} for r in rows]
    typed = collections.Counter((r["gt_kind"], r["pred_kind"]) for r in everything if r["why"] == "wrong_kind")
    print(f"all: {len(everything)} wrong, {sum(typed.values())} of them wrongly typed; true -> predicted:")
    for (g, p), n in typed.most_common(a.top):
        print(f"  {n:3d}  {g} -> {p}")
    if a.json:
        a.json.write_text(json.dumps(everything, indent=1))


if __name__ == "__main__":
    main()
