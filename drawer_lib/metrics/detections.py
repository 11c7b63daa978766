"""2D detections against the truth: a detector's front masks matched to the true fronts of a
view (instance ids per pixel)."""

import numpy as np


def match_fronts(pred: list[np.ndarray], true_ids: np.ndarray, min_true_px: int, iou: float) -> tuple[int, int, int]:
    """(true positives, predicted, true) of one view: a predicted front mask matches the true
    front (``true_ids`` [H, W], id + 1 per pixel, 0 elsewhere) it overlaps with IoU >= ``iou``,
    each at most once; true fronts smaller than ``min_true_px`` are not counted (nor are
    predictions matching them)."""
    ids, areas = np.unique(true_ids[true_ids > 0], return_counts=True)
    big = {int(i) for i, a in zip(ids, areas) if a >= min_true_px}
    used: set[int] = set()
    tp = n_pred = 0
    for m in pred:
        t, c = np.unique(true_ids[m], return_counts=True)
        best, best_iou = None, 0.0
        for i, inter in zip(t, c):
            if i == 0 or int(i) in used:
                continue
            u = m.sum() + (true_ids == i).sum() - inter
            if inter / u > best_iou:
                best, best_iou = int(i), inter / u
        if best is not None and best_iou >= iou:
            used.add(best)
            if best in big:
                tp += 1
                n_pred += 1
        else:
            n_pred += 1
    return tp, n_pred, len(big)
