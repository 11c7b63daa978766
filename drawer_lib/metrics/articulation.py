"""Articulation metrics (paper Tab. 4/5; docs/formats.md): front matching, precision / recall, EA-score.

Matching: a predicted articulated part and a GT one are candidates when their front normals are
within 45 deg and the predicted front's centre lies within 5 cm of the GT front plane; their
overlap is the IoU of the two rectangles in the GT front plane (the predicted one projected
orthogonally onto it). Pairs with IoU >= 0.5 are matched greedily by IoU, one to one.
correct = matched and same kind; precision = correct / predicted, where a prediction that matches
nothing and whose front centre lies in a GT ``ignore_boxes`` region is not counted;
recall = correct / GT.

EA-score (Zhao et al. 2021, as 3DOI): for a correct revolute part and a view, both hinge axes
are drawn as the segment of the axis line that spans the part's front, projected, clipped to the
image and normalised to the unit square; S_theta = 1 - angle / (pi / 2) (lines, angle folded to
[0, pi / 2]), S_d = max(0, 1 - |midpoint_pred - midpoint_gt|); EA = (S_theta S_d)^2, averaged
over the views where both segments are visible, then over parts.
"""

from dataclasses import dataclass, field

import numpy as np
from jaxtyping import Float

from drawer_lib.geometry.camera import Camera
from drawer_lib.io.parts import Front, Part, PartsFile

IOU_MIN = 0.5
NORMAL_MAX_DEG = 45.0
PLANE_MAX_M = 0.05


def polygon_area(p: Float[np.ndarray, "N 2"]) -> float:
    """Signed area (counter-clockwise positive) of a simple polygon."""
    if len(p) < 3:
        return 0.0
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _ccw(p: np.ndarray) -> np.ndarray:
    return p if polygon_area(p) >= 0 else p[::-1]


def clip_convex(subject: Float[np.ndarray, "N 2"], clip: Float[np.ndarray, "M 2"]) -> np.ndarray:
    """Sutherland–Hodgman: the intersection of convex polygons (vertices [K, 2], maybe K = 0)."""
    out = _ccw(np.asarray(subject, np.float64))
    cl = _ccw(np.asarray(clip, np.float64))
    for i in range(len(cl)):
        if len(out) == 0:
            break
        a, b = cl[i], cl[(i + 1) % len(cl)]
        e = b - a
        side = e[0] * (out[:, 1] - a[1]) - e[1] * (out[:, 0] - a[0])  # >= 0: inside (left of a->b)
        res = []
        for j in range(len(out)):
            p, q = out[j], out[(j + 1) % len(out)]
            sp, sq = side[j], side[(j + 1) % len(out)]
            if sp >= 0:
                res.append(p)
            if (sp >= 0) != (sq >= 0):
                t = sp / (sp - sq)
                res.append(p + t * (q - p))
        out = np.asarray(res).reshape(-1, 2)
    return out


def convex_iou(a: np.ndarray, b: np.ndarray) -> float:
    ia = abs(polygon_area(a)) + abs(polygon_area(b))
    inter = abs(polygon_area(clip_convex(a, b)))
    union = ia - inter
    return inter / union if union > 0 else 0.0


def front_overlap(pred: Front, gt: Front) -> float:
    """IoU of the two fronts in the GT front plane, 0 when the normals differ by more than 45
    deg or the predicted centre is farther than 5 cm from the GT plane."""
    n_g, n_p = np.asarray(gt.normal), np.asarray(pred.normal)
    if np.dot(n_g, n_p) < np.cos(np.deg2rad(NORMAL_MAX_DEG)):
        return 0.0
    c_g = np.asarray(gt.center)
    if abs(np.dot(np.asarray(pred.center) - c_g, n_g)) > PLANE_MAX_M:
        return 0.0
    u, v = np.asarray(gt.u), gt.v
    to2d = lambda P: np.stack([(P - c_g) @ u, (P - c_g) @ v], -1)  # noqa: E731
    return convex_iou(to2d(pred.corners()), to2d(gt.corners()))


@dataclass
class Matching:
    pairs: list[tuple[int, int, float]]  # (pred index, gt index, IoU) into the articulated lists
    pred: list[Part]
    gt: list[Part]
    ignored: list[int] = field(default_factory=list)  # unmatched predictions inside an ignore box

    @property
    def correct(self) -> list[tuple[int, int, float]]:
        return [(i, j, o) for i, j, o in self.pairs if self.pred[i].kind == self.gt[j].kind]


def match_parts(pred: PartsFile, gt: PartsFile) -> Matching:
    P = [p for p in pred.parts if p.articulated]
    G = [g for g in gt.parts if g.articulated]
    cands = sorted(((front_overlap(p.front, g.front), i, j) for i, p in enumerate(P) for j, g in enumerate(G)),
                   reverse=True)
    used_p, used_g, pairs = set(), set(), []
    for o, i, j in cands:
        if o < IOU_MIN:
            break
        if i in used_p or j in used_g:
            continue
        used_p.add(i)
        used_g.add(j)
        pairs.append((i, j, o))
    ignored = [i for i, p in enumerate(P) if i not in used_p and any(b.contains(p.front.center) for b in gt.ignore_boxes)]
    return Matching(pairs, P, G, ignored)


def hinge_side(part: Part) -> str | None:
    """The edge of a revolute part's front its axis runs along (``left``, ``right``, ``top``,
    ``bottom``: left / right along the front's u, bottom / top along v), from the axis alone;
    None for another kind or an axis along the normal."""
    if part.kind != "revolute" or part.front is None or part.axis is None:
        return None
    f = part.front
    d, rel = np.asarray(part.axis.direction), np.asarray(part.axis.origin) - np.asarray(f.center)
    along_u, along_v = abs(d @ np.asarray(f.u)), abs(d @ f.v)
    if max(along_u, along_v) < 0.5:
        return None
    if along_v >= along_u:  # a vertical hinge line: left or right edge
        return "left" if rel @ np.asarray(f.u) < 0 else "right"
    return "bottom" if rel @ f.v < 0 else "top"


def part_kind(part: Part | None) -> str:
    """A part's kind as the benchmark's confusion matrix and the decision-stability check name
    it: its family (``door``, ``drawer``, ...; the joint kind without one) with the hinge side
    of a door or flap from its axis (``door_left``, ``flap_top``: ground truth and prediction
    alike); ``missed`` for None."""
    if part is None:
        return "missed"
    fam = str(part.extra.get("family", part.kind))
    side = hinge_side(part) if fam in ("door", "flap") else None
    return f"{fam}_{side}" if side else fam


WRONG_WHY = ("wrong_kind", "off_front", "merged", "no_front")
TOUCH_IOU = 0.05  # a predicted front overlapping a true one by more than this touches it


def wrong_parts(m: Matching) -> list[dict]:
    """Why each predicted articulated part of the matching ``m`` that precision counts against
    (not correct, not ignored) is wrong, in the order of ``m.pred``: ``why`` is ``wrong_kind``
    (matched to a true part at IoU >= IOU_MIN, another joint kind), ``merged`` (unmatched,
    touching two or more true fronts: IoU > TOUCH_IOU), ``off_front`` (unmatched, touching one:
    split from it or mis-sized) or ``no_front`` (touching none); with ``pred_kind`` and, for the
    first three, ``gt_kind`` (:func:`part_kind` names; of the best-overlapping true front when
    unmatched) and ``iou`` to it; ``part`` is the predicted part's id."""
    matched = {i: (j, o) for i, j, o in m.pairs}
    skip = set(m.ignored) | {i for i, _, _ in m.correct}
    out = []
    for i, p in enumerate(m.pred):
        if i in skip:
            continue
        row = {"part": p.id, "pred_kind": part_kind(p)}
        if i in matched:
            j, o = matched[i]
            row.update(why="wrong_kind", gt_kind=part_kind(m.gt[j]), iou=float(o))
        else:
            ious = _overlaps(p.front, m.gt)
            touched = int((ious > TOUCH_IOU).sum())
            if touched == 0:
                row.update(why="no_front")
            else:
                j = int(ious.argmax())
                row.update(why="merged" if touched > 1 else "off_front", gt_kind=part_kind(m.gt[j]), iou=float(ious[j]))
        out.append(row)
    return out


MISSED_WHY = ("wrong_kind", "off_front", "merged", "no_part")


def missed_parts(m: Matching) -> list[dict]:
    """Why each true articulated part of the matching ``m`` that recall counts as not found has
    no correct prediction, in the order of ``m.gt``: ``why`` is ``wrong_kind`` (matched to a
    predicted part at IoU >= IOU_MIN, another joint kind), ``merged`` (unmatched; the predicted
    front overlapping it most, IoU > TOUCH_IOU, also touches another true front: joined with a
    neighbour), ``off_front`` (unmatched; that front touches it alone: split from it or
    mis-sized) or ``no_part`` (no predicted articulated front touches it: never detected, or its
    front was typed fixed or dropped); with ``gt_kind`` (:func:`part_kind`), and for the first
    three ``pred_kind`` and ``iou`` of that prediction; ``part`` is the true part's id."""
    matched = {j: (i, o) for i, j, o in m.pairs}
    found = {j for _, j, _ in m.correct}
    out = []
    for j, g in enumerate(m.gt):
        if j in found:
            continue
        row = {"part": g.id, "gt_kind": part_kind(g)}
        if j in matched:
            i, o = matched[j]
            row.update(why="wrong_kind", pred_kind=part_kind(m.pred[i]), iou=float(o))
        else:
            ious = np.array([front_overlap(p.front, g.front) for p in m.pred]) if m.pred else np.zeros(0)
            if not (ious > TOUCH_IOU).any():
                row.update(why="no_part")
            else:
                i = int(ious.argmax())
                touched = int((_overlaps(m.pred[i].front, m.gt) > TOUCH_IOU).sum())
                row.update(why="merged" if touched > 1 else "off_front", pred_kind=part_kind(m.pred[i]),
                           iou=float(ious[i]))
        out.append(row)
    return out


def precision_by_flag(m: Matching, flag: str = "low_margin") -> dict[bool, tuple[int, int]]:
    """Precision of the matching ``m`` split by a flag each predicted part carries in its extra
    fields (``low_margin``: articulate's "check this one first"): {flagged: (correct, counted)}
    for True and False, over the predictions precision counts (ignored ones left out). A flag
    worth reading has a clearly lower precision on its True side."""
    right = {i for i, _, _ in m.correct}
    out = {True: [0, 0], False: [0, 0]}
    for i, p in enumerate(m.pred):
        if i in m.ignored:
            continue
        side = out[bool(p.extra.get(flag, False))]
        side[0] += i in right
        side[1] += 1
    return {k: (v[0], v[1]) for k, v in out.items()}


def _overlaps(front: Front, gt: list[Part]) -> np.ndarray:
    """[len(gt)] :func:`front_overlap` of a predicted ``front`` with each true part's front."""
    return np.array([front_overlap(front, g.front) for g in gt]) if gt else np.zeros(0)


def axis_segment(part: Part) -> np.ndarray:
    """[2, 3] the stretch of a part's axis line that spans its front."""
    o, d = np.asarray(part.axis.origin), np.asarray(part.axis.direction)
    t = (part.front.corners() - o) @ d
    return np.stack([o + t.min() * d, o + t.max() * d])


def project_segment(seg: np.ndarray, cam: Camera, near: float = 1e-3) -> np.ndarray | None:
    """[2, 2] the segment [2, 3] seen by ``cam``, clipped to z > near and to the image, in
    normalised [0, 1]^2 coordinates; None when nothing of it is visible."""
    w2c, W, H = cam.w2c, cam.width, cam.height
    pc = seg @ w2c[:3, :3].T + w2c[:3, 3]
    a, b = pc[0], pc[1]
    if a[2] <= near and b[2] <= near:
        return None
    if a[2] <= near or b[2] <= near:  # clip to the near plane
        t = (near - a[2]) / (b[2] - a[2])
        m = a + t * (b - a)
        a, b = (m, b) if a[2] <= near else (a, m)
    fx, fy, cx, cy = cam.intrinsics.params
    pa = np.array([fx * a[0] / a[2] + cx, fy * a[1] / a[2] + cy]) / (W, H)
    pb = np.array([fx * b[0] / b[2] + cx, fy * b[1] / b[2] + cy]) / (W, H)
    # Liang–Barsky against [0, 1]^2
    d = pb - pa
    t0, t1 = 0.0, 1.0
    for p, q in ((-d[0], pa[0]), (d[0], 1 - pa[0]), (-d[1], pa[1]), (d[1], 1 - pa[1])):
        if p == 0:
            if q < 0:
                return None
            continue
        r = q / p
        if p < 0:
            t0 = max(t0, r)
        else:
            t1 = min(t1, r)
    if t0 >= t1:
        return None
    return np.stack([pa + t0 * d, pa + t1 * d])


def ea_pair(pred2d: np.ndarray, gt2d: np.ndarray) -> float:
    """EA-score of two normalised 2D segments [2, 2]."""
    dp, dg = pred2d[1] - pred2d[0], gt2d[1] - gt2d[0]
    ang = abs(np.arctan2(dp[1], dp[0]) - np.arctan2(dg[1], dg[0])) % np.pi
    ang = min(ang, np.pi - ang)
    s_t = 1 - ang / (np.pi / 2)
    s_d = max(0.0, 1 - float(np.linalg.norm(pred2d.mean(0) - gt2d.mean(0))))
    return (s_t * s_d) ** 2


def ea_score(pred: Part, gt: Part, views: list[Camera]) -> float | None:
    """Mean EA over the cameras ``views`` where both axes are visible; None when there is no
    such view."""
    sp, sg = axis_segment(pred), axis_segment(gt)
    vals = []
    for cam in views:
        a, b = project_segment(sp, cam), project_segment(sg, cam)
        if a is not None and b is not None and np.linalg.norm(a[1] - a[0]) > 1e-6 and np.linalg.norm(b[1] - b[0]) > 1e-6:
            vals.append(ea_pair(a, b))
    return float(np.mean(vals)) if vals else None


def articulation_metrics(pred: PartsFile, gt: PartsFile, views: list[Camera]) -> tuple[dict, list[dict]]:
    """(flat metrics, per-GT-part details). Metrics: ``precision``, ``recall``, ``ea_score``
    (absent with no correct revolute part visible in a view), counts."""
    m = match_parts(pred, gt)
    correct = m.correct
    n_pred = len(m.pred) - len(m.ignored)
    eas = []
    details = []
    by_gt = {j: (i, o) for i, j, o in m.pairs}
    for j, g in enumerate(m.gt):
        row: dict = {"gt": g.id, "kind": g.kind}
        if j in by_gt:
            i, o = by_gt[j]
            p = m.pred[i]
            row.update({"pred": p.id, "pred_kind": p.kind, "iou": round(o, 4), "correct": p.kind == g.kind})
            if p.kind == g.kind == "revolute":
                e = ea_score(p, g, views)
                row["ea_score"] = e
                if e is not None:
                    eas.append(e)
        else:
            row.update({"pred": None, "correct": False})
        details.append(row)
    out = {"precision": len(correct) / n_pred if n_pred > 0 else 0.0, "recall": len(correct) / len(m.gt) if m.gt else 0.0,
           "n_pred": len(m.pred), "n_gt": len(m.gt), "n_correct": len(correct), "n_ignored": len(m.ignored),
           "n_revolute_scored": len(eas)}
    if eas:
        out["ea_score"] = float(np.mean(eas))
        out["ea_score_min"] = float(np.min(eas))
    return out, details


RIGID_IOU_MIN = 0.25


def box_iou_3d(a: Float[np.ndarray, "N 2 3"], b: Float[np.ndarray, "M 2 3"]) -> Float[np.ndarray, "N M"]:
    """IoU of axis-aligned boxes given as (min corner, max corner) in metres; 0 for empty boxes."""
    a, b = np.asarray(a, np.float64).reshape(-1, 2, 3), np.asarray(b, np.float64).reshape(-1, 2, 3)
    lo = np.maximum(a[:, None, 0], b[None, :, 0])
    hi = np.minimum(a[:, None, 1], b[None, :, 1])
    inter = np.clip(hi - lo, 0.0, None).prod(-1)
    va = np.clip(a[:, 1] - a[:, 0], 0.0, None).prod(-1)
    vb = np.clip(b[:, 1] - b[:, 0], 0.0, None).prod(-1)
    union = va[:, None] + vb[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def rigid_metrics(pred: PartsFile, gt: PartsFile, iou_min: float = RIGID_IOU_MIN) -> tuple[dict, list[dict]]:
    """Rigid objects (beyond the paper): a predicted and a GT rigid part match when the IoU of
    their axis-aligned ``bounds`` is >= ``iou_min``, greedy by IoU, one to one; precision =
    matched / predicted, recall = matched / GT. Keys ``rigid_precision`` (absent with no
    prediction), ``rigid_recall`` (absent with no GT object), counts; and per-GT-object details."""
    P = [p for p in pred.parts if p.kind == "rigid" and p.bounds is not None]
    G = [g for g in gt.parts if g.kind == "rigid" and g.bounds is not None]
    iou = box_iou_3d(np.array([p.bounds for p in P]).reshape(-1, 2, 3), np.array([g.bounds for g in G]).reshape(-1, 2, 3))
    pairs, used_p, used_g = {}, set(), set()
    for flat in np.argsort(-iou, axis=None):
        i, j = np.unravel_index(flat, iou.shape)
        if iou[i, j] < iou_min:
            break
        if i in used_p or j in used_g:
            continue
        used_p.add(i)
        used_g.add(j)
        pairs[int(j)] = (int(i), float(iou[i, j]))
    out: dict = {"n_rigid_pred": len(P), "n_rigid_gt": len(G), "n_rigid_matched": len(pairs)}
    if P:
        out["rigid_precision"] = len(pairs) / len(P)
    if G:
        out["rigid_recall"] = len(pairs) / len(G)
    details = [{"gt": g.id, "pred": P[pairs[j][0]].id if j in pairs else None,
                "iou": round(pairs[j][1], 4) if j in pairs else None} for j, g in enumerate(G)]
    return out, details


def compare_parts(ref: PartsFile, other: PartsFile) -> list[dict]:
    """Per articulated part of ``ref``: its kind, the kind of the part of ``other`` on the same
    front (front overlap, as the articulation metrics match) or ``missed``, whether it kept it,
    and ``ref``'s margin."""
    m = match_parts(other, ref)
    by_ref = {j: i for i, j, _ in m.pairs}
    rows = []
    for j, g in enumerate(m.gt):
        k_ref = part_kind(g)
        k_new = part_kind(m.pred[by_ref[j]]) if j in by_ref else "missed"
        rows.append({"part": g.id, "kind": k_ref, "now": k_new, "kept": k_ref == k_new,
                     "margin": g.extra.get("margin")})
    return rows
