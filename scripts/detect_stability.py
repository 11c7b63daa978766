#!/usr/bin/env python
"""Do a split's parts hold when the built-in detector's probabilities, or the mesh decompose
reads, move by what another machine's numerics could change? Compares ``scripts/bench_detect.py``
runs of the same kitchens whose detections were decoded from log-probabilities jittered by
``detect.builtin.logit_jitter``, or whose mesh was jittered by ``decompose.mesh_jitter``
(``--model capture``: the simulated detections; each run with its own tag) against the run
without (``--ref``), from the outputs they left
(nothing is rerun). Per tag: the kitchens whose ``parts.json`` is byte-identical to the
reference's, the reference's parts kept (same front, same kind), retyped and lost, the parts
added (:func:`drawer_lib.articulation.robustness.stability_counts`), how many of the parts
that moved the reference had flagged ``low_margin``, the frames whose
detections changed (a mask cut, joined or moved by a pixel) and the share of pixels whose front /
handle / object label changed, and the run's precision / recall.
Also the reference's decoding decisions near their thresholds (its ``detect`` metrics).

    python scripts/bench_detect.py --split hand_tune --detect builtin --out OUT --tag j0 --set detect.builtin.logit_jitter=0
    python scripts/bench_detect.py --split hand_tune --detect builtin --out OUT --tag j3 --set detect.builtin.logit_jitter=1e-3
    python scripts/detect_stability.py OUT/hand_tune --ref j0 --tags j3 [--json rows.json]
    python scripts/detect_stability.py OUT/train --ref nh --ref-detect gd --tags j4   # nh: --from-tag gd
    python scripts/bench_detect.py --split hand_tune --detect capture --out OUT --tag m6 --set decompose.mesh_jitter=1e-6
    python scripts/detect_stability.py OUT/hand_tune --model capture --ref j0 --tags m6

``--numerics CAPTURE...`` with ``--weights``: how far the network's float32 log-probabilities
lie from float64 on every ``--every``-th view of those captures
(:func:`drawer_lib.detect.builtin.float32_error`), the scale of jitter that matches another
machine's last bits:

    python scripts/detect_stability.py --numerics OUT/hand_tune/kitchen_0/capture --weights W/gd.pt
"""

import argparse
import json
from pathlib import Path

import numpy as np

from bench_detect import variant  # the folder bench_detect writes a model's outputs to
from drawer_lib.articulation.robustness import stability_counts
from drawer_lib.io.images import read_json, read_u16
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.articulation import compare_parts
from drawer_lib.paths import ScenePaths

COUNTS = ("n_ref", "n_other", "kept", "retyped", "lost", "added", "n_flagged", "moved_flagged")


def frame_detections(d: ScenePaths, stem: str) -> tuple[np.ndarray, np.ndarray]:
    """A frame's detections, read once, in two forms that compare across runs whatever ids they
    wrote: labels (0 none, 1 front, 2 handle, 3 object) and instance ids renumbered in the
    order they first appear (row-major)."""
    lab = read_u16(d.file("detect", "detections") / f"{stem}.png").astype(np.int64)
    rows = read_json(d.file("detect", "detections") / f"{stem}.json")
    code = np.zeros(int(lab.max()) + 1, np.uint8)
    for r in rows:
        code[r["id"]] = {"handle": 2, "object": 3}.get(r["label"], 1)
    ids, first = np.unique(lab.ravel(), return_index=True)
    order = np.zeros(int(ids.max()) + 1, np.int64)
    fg = ids > 0
    order[ids[fg]] = np.argsort(np.argsort(first[fg])) + 1
    return code[lab], order[lab]


def changed_detections(a: ScenePaths, b: ScenePaths) -> dict:
    """Over the frames both detection folders hold: pixels whose label (front, handle, object)
    differs, and frames whose instances differ (a mask cut or joined otherwise, or a pixel moved)."""
    stems = sorted(p.stem for p in a.file("detect", "detections").glob("*.png"))
    diff = total = frames = 0
    for s in stems:
        (x, xi), (y, yi) = frame_detections(a, s), frame_detections(b, s)
        diff += int((x != y).sum())
        total += x.size
        frames += not np.array_equal(xi, yi)
    return {"pixels_changed": diff, "pixels": total, "frames_changed": frames, "frames": len(stems)}


def compare_kitchen(root: Path, model: str, ref: str, tag: str, ref_detect: str | None = None) -> dict:
    """One kitchen folder's run tagged ``tag`` against its run tagged ``ref`` (whose detections
    are those of the run tagged ``ref_detect`` when it reran articulate alone, ``--from-tag``)."""
    a, b = (ScenePaths(root / "by_detector", variant(model, t)) for t in (ref, tag))
    ad = own_detections(root, model, ref if ref_detect is None else ref_detect)
    for p in (a.parts, b.parts, ad.metrics("detect")):
        if not p.is_file():
            raise SystemExit(f"error: {p}: missing; run bench_detect with that tag first")
    pa, pb = read_parts(a.parts), read_parts(b.parts)
    rows = compare_parts(pa, pb)
    return {"split": root.parent.name, "kitchen": root.name, "identical": a.parts.read_bytes() == b.parts.read_bytes(),
            **stability_counts(pa, pb, rows), "moved": [r["part"] for r in rows if not r["kept"]],
            **changed_detections(ad, own_detections(root, model, tag))}


def own_detections(root: Path, model: str, tag: str) -> ScenePaths:
    """The detections the run tagged ``tag`` read: its own, or the model's untagged ones when it
    decoded none (a tag that varied decompose or articulate only, ``decompose.mesh_jitter``)."""
    d, u = ScenePaths(root / "by_detector", variant(model, tag)), ScenePaths(root / "by_detector", model)
    return u if not d.metrics("detect").is_file() and u.metrics("detect").is_file() else d  # neither: the tag's is missing


def numerics(captures: list[Path], weights: list[Path] | None, every: int) -> None:
    """Print the float32 network's distance from float64 over every ``every``-th view."""
    import yaml

    from drawer_lib.config.typed import to_typed
    from drawer_lib.detect.builtin import float32_error, load_detector
    from drawer_lib.detect.config import BuiltinDetectConfig
    from drawer_lib.io.capture import load_capture

    if not weights or not all(w.is_file() for w in weights):
        raise SystemExit(f"error: --numerics needs --weights, the built-in detector's files (got {weights})")
    root = Path(__file__).resolve().parent.parent
    dc = to_typed(BuiltinDetectConfig, yaml.safe_load((root / "params.yaml").read_text())["detect"]["builtin"],
                  "detect.builtin")
    model, _ = load_detector(weights if len(weights) > 1 else weights[0])
    rows = []
    for c in captures:
        cap = load_capture(c, check_files=False)
        rows += [float32_error(model, cap.image(i), dc.working_size) for i in range(0, len(cap.frames), max(every, 1))]
    sd = float(np.mean([r["logp_sd"] for r in rows]))
    print(f"float32 against float64 over {len(rows)} views: log-probabilities {sd:.2e} in standard deviation "
          f"(mean over views), {max(r['logp_max'] for r in rows):.2e} at most; probabilities "
          f"{max(r['p_max'] for r in rows):.2e} at most")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("splits", type=Path, nargs="*", help="bench_detect split folders (OUT/<split>)")
    ap.add_argument("--ref", help="the tag of the run without jitter")
    ap.add_argument("--ref-detect", default=None, metavar="TAG",
                    help="the tag whose detections --ref's run read, when it reran articulate alone (--from-tag)")
    ap.add_argument("--tags", nargs="+", default=[], help="the tags of the jittered runs")
    ap.add_argument("--model", default="builtin")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    ap.add_argument("--numerics", type=Path, nargs="+", default=[], metavar="CAPTURE",
                    help="capture folders whose views measure float32 against float64 (needs --weights)")
    ap.add_argument("--weights", type=Path, nargs="+", default=None, help="the built-in detector's weights")
    ap.add_argument("--every", type=int, default=15, help="with --numerics: every N-th view")
    a = ap.parse_args()
    if a.numerics:
        numerics(a.numerics, a.weights, a.every)
        if not a.splits:
            return
    if not a.splits or not a.ref or not a.tags:
        ap.error("split folders, --ref and --tags are needed (or --numerics alone)")
    kitchens = {split: sorted(split.glob("kitchen_*"), key=lambda p: int(p.name.split("_")[1])) for split in a.splits}
    for split, ks in kitchens.items():
        if not ks:
            raise SystemExit(f"error: {split}: no kitchen_* folders (a bench_detect --out <dir>/<split>)")
    out: dict = {"ref": a.ref, "near": {}, "tags": {}}
    near = {"merge": 0, "merge_band": 0, "score": 0}
    frames = near_frames = unrecorded = 0
    for ks in kitchens.values():
        for k in ks:
            mp = own_detections(k, a.model, a.ref_detect or a.ref).metrics("detect")
            if not mp.is_file():
                raise SystemExit(f"error: {mp}: missing; run bench_detect with --tag {a.ref} first")
            m = read_json(mp)
            if "near_decisions" not in m:  # detections made before the stage counted them
                unrecorded += 1
                continue
            for step in near:
                near[step] += m.get("near_decisions", {}).get(step, 0)
            frames += m["n_frames"]
            near_frames += m.get("near_frames", 0)
    out["near"] = {"decisions": near, "frames": frames, "frames_with_one": near_frames, "unrecorded": unrecorded}
    if a.model == "builtin":  # the other models decode nothing
        print(f"reference {a.ref}: {sum(near.values())} decoding decisions within 0.001 of their thresholds "
              f"({near}) in {near_frames} of {frames} frames"
              + (f"; not recorded for {unrecorded} kitchens (their detections predate the count)" if unrecorded else ""))
    print("\n| tag | jitter | kitchens with identical parts | parts kept | retyped | lost | added "
          "| of the moved, flagged low_margin "
          "| frames whose detections changed | their pixels changed | precision / recall |\n|---|---|---|---|---|---|---|---|---|---|---|")
    for tag in a.tags:
        rows = [compare_kitchen(k, a.model, a.ref, tag, a.ref_detect) for ks in kitchens.values() for k in ks]
        tot = {c: sum(r[c] for r in rows) for c in COUNTS + ("pixels_changed", "pixels", "frames_changed", "frames")}
        sets, pr = [], []
        for split in a.splits:
            summ = json.loads((split / f"summary-{tag}.json").read_text())
            sets += summ["set"]
            s = summ["by_model"][a.model]
            pr.append(f"{s['precision_pooled']:.3f} / {s['recall_pooled']:.3f}")
        jit = [x.split("=", 1)[1] for x in sets if x.split("=", 1)[0].endswith("_jitter")]  # logit_jitter, mesh_jitter
        print(f"| {tag} | {', '.join(sorted(set(jit))) or '–'} | {sum(r['identical'] for r in rows)} / {len(rows)} "
              f"| {tot['kept']} / {tot['n_ref']} | {tot['retyped']} | {tot['lost']} | {tot['added']} "
              f"| {tot['moved_flagged']} / {tot['retyped'] + tot['lost']} "
              f"| {tot['frames_changed']} / {tot['frames']} | {tot['pixels_changed'] / max(tot['pixels'], 1):.2e} "
              f"| {'; '.join(pr)} |")
        for r in rows:
            if not r["identical"]:
                print(f"    {r['kitchen']}: kept {r['kept']} / {r['n_ref']}, retyped {r['retyped']}, lost {r['lost']}, "
                      f"added {r['added']}, frames changed {r['frames_changed']}, pixels changed {r['pixels_changed']}")
        out["tags"][tag] = {"logit_jitter": jit, "total": tot, "rows": rows, "precision_recall": pr}
    distinct = {(str(r["split"]), r["kitchen"], p) for t in out["tags"].values() for r in t["rows"] for p in r["moved"]}
    print(f"\ndistinct parts of the reference moved (retyped or lost) over the tags: {len(distinct)}")
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
