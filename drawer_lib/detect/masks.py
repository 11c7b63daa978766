"""Instance masks -> the capture format's detections (docs/formats.md#capture): a 16-bit label map
with ids local to the frame and ``[{"id", "label", "score"}]``."""

from dataclasses import dataclass

import numpy as np
from jaxtyping import Bool


@dataclass(frozen=True)
class Detection:
    mask: Bool[np.ndarray, "H W"]
    label: str  # front | drawer | door | handle | object
    score: float


def paint_detections(dets: list[Detection], shape: tuple[int, int]) -> tuple[np.ndarray, list[dict]]:
    """(uint16 [H, W] label map, rows): the largest mask painted first, so a handle stays on
    top of the front it sits on; a mask that keeps no pixel after the others is dropped. Ids
    1..n in painting order."""
    order = sorted(range(len(dets)), key=lambda i: (-int(dets[i].mask.sum()), i))
    lab = np.zeros(shape, np.uint16)
    for k, i in enumerate(order, start=1):
        lab[dets[i].mask] = k
    rows, remap = [], np.zeros(len(order) + 1, np.uint16)
    present = np.unique(lab)
    for k, i in enumerate(order, start=1):
        if k in present:
            remap[k] = len(rows) + 1
            rows.append({"id": len(rows) + 1, "label": dets[i].label, "score": round(float(dets[i].score), 4)})
    return remap[lab], rows
