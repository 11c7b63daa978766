"""What the ``evaluate`` stage does: ``parts.json`` against the capture's ``gt/parts.json`` ->
precision, recall, EA-score (docs/formats.md#metric-definitions), the motion EMD of the simulated twin (from the
simulate stage's tracks), the rigid objects' precision / recall (3D box IoU >= 0.25) and which
prediction matched which GT part."""

from pathlib import Path

import numpy as np

from drawer_lib.errors import InputError
from drawer_lib.io.capture import Capture
from drawer_lib.io.images import write_json
from drawer_lib.io.overlay import capture_manifest
from drawer_lib.io.parts import read_parts
from drawer_lib.metrics.articulation import articulation_metrics, match_parts, rigid_metrics
from drawer_lib.metrics.motion import motion_emd
from drawer_lib.paths import capture_name, stage_name
from drawer_lib.runner import StageRun


def run_evaluate(cap: Capture, parts_path: Path, run: StageRun, tracks_path: Path | None = None) -> dict:
    """Score the predicted parts at ``parts_path`` (and their simulated motion, ``tracks_path``:
    ``simulate/tracks.npz``, when given); scenes without ground truth record the skip."""
    if not parts_path.is_file():
        raise InputError(f"{parts_path}: missing (run the articulate stage first)")
    manifest = capture_manifest(cap)
    pred = read_parts(parts_path)
    m: dict = {"n_pred": sum(p.articulated for p in pred.parts)}
    if not run.needs(manifest, "articulation", "gt"):
        write_json(run.out("matches"), {"parts": [], "skipped": run.skipped["articulation"]})
        return m
    gt = read_parts(cap.root / capture_name("gt_parts"))
    res, details = articulation_metrics(pred, gt, cap.cameras(cap.test))
    if res["n_pred"] - res["n_ignored"] == 0:
        run.skip("precision", "no articulated part predicted")
        res.pop("precision")
    if res["n_gt"] == 0:
        run.skip("recall", "the ground truth has no articulated part")
        res.pop("recall")
    if "ea_score" not in res:
        run.skip("ea_score", "no correctly predicted revolute part is visible in a test view")
    rig, rig_details = rigid_metrics(pred, gt)
    if "rigid_precision" not in rig:
        run.skip("rigid_precision", "no rigid object predicted")
    if "rigid_recall" not in rig:
        run.skip("rigid_recall", "the ground truth has no rigid object")
    motion: list[dict] = []
    if tracks_path is None:
        run.skip("emd", f"no simulated tracks given (the simulate stage's {stage_name('simulate', 'tracks')})")
    elif not tracks_path.is_file():
        raise InputError(f"{tracks_path}: missing (run the simulate stage first)")
    elif not len(cap.test):
        run.skip("emd", "the capture has no test view to project the tracks into")
    else:
        match = match_parts(pred, gt)
        with np.load(tracks_path) as tracks:
            emd, motion = motion_emd(match.pred, match.gt, [(i, j) for i, j, _ in match.correct], tracks,
                                     cap.cameras([cap.test[0]])[0])
        if not emd:
            run.skip("emd", "no correctly predicted part" if not motion else "no correct part's track is in view")
        res.update(emd)
    write_json(run.out("matches"), {"parts": details, "rigid": rig_details, "motion": motion})
    m.update(res)
    m.update(rig)
    return m
