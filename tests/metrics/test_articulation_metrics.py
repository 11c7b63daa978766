"""Articulation metrics (docs/formats.md): rectangle IoU in the GT plane, matching with its gates and
ignore boxes, precision / recall, EA-score and its clipping."""

import numpy as np
import pytest

from drawer_lib.geometry.camera import Camera, Intrinsics
from drawer_lib.io.parts import Axis, Front, IgnoreBox, Part, PartsFile
from drawer_lib.metrics.articulation import (articulation_metrics, clip_convex, convex_iou, ea_pair, front_overlap,
                                             match_parts, missed_parts, precision_by_flag, project_segment,
                                             wrong_parts)

N = (0.0, -1.0, 0.0)
U = (1.0, 0.0, 0.0)


def front(cx=0.0, cz=0.5, w=0.5, h=0.7, n=N, u=U, y=-0.6):
    return Front((cx, y, cz), n, u, (w, h))


def door(pid, fr, kind="revolute"):
    edge = np.asarray(fr.center) - np.asarray(fr.u) * fr.size[0] / 2
    return Part(pid, kind, Axis(tuple(edge), (0.0, 0.0, -1.0)), (0.0, 1.57), fr)


def test_convex_clip_and_iou_of_squares():
    a = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    b = a + [0.5, 0.0]
    inter = clip_convex(a, b)
    assert np.allclose(np.sort(inter[:, 0]), [0.5, 0.5, 1.0, 1.0])
    assert convex_iou(a, b) == pytest.approx(0.5 / 1.5)
    assert convex_iou(a, a[::-1]) == pytest.approx(1.0)  # orientation does not matter
    assert convex_iou(a, a + 5) == 0.0


def test_front_overlap_gates():
    g = front()
    assert front_overlap(g, g) == pytest.approx(1.0)
    assert front_overlap(front(cx=0.25), g) == pytest.approx(0.25 / 0.75)
    assert front_overlap(front(y=-0.66), g) == 0.0  # 6 cm off the GT plane
    assert front_overlap(front(y=-0.64), g) == pytest.approx(1.0)  # within 5 cm
    tilted = (0.0, -np.cos(np.deg2rad(50)), np.sin(np.deg2rad(50)))
    assert front_overlap(Front(g.center, tilted, U, g.size), g) == 0.0  # normals 50 deg apart
    # a rotated rectangle is projected, not matched by its centre
    r = Front(g.center, N, (0.0, 0.0, 1.0), (0.7, 0.5))
    assert front_overlap(r, g) == pytest.approx(1.0)


def test_matching_is_one_to_one_and_kind_aware_with_ignore_boxes():
    g1, g2 = front(cx=0.0), front(cx=0.6)
    gt = PartsFile((door("d0", g1), door("d1", g2, "prismatic")),
                   (IgnoreBox("oven", ((1.0, -0.7, 0.0), (1.6, -0.5, 1.0))),))
    pred = PartsFile((door("a", front(cx=0.01)), door("b", front(cx=0.02)), door("c", front(cx=0.6)),
                      door("oven_front", front(cx=1.3))))
    m = match_parts(pred, gt)
    assert sorted((i, j) for i, j, _ in m.pairs) == [(0, 0), (2, 1)]  # "a" overlaps d0 best, "b" is left over
    assert m.ignored == [3]
    res, details = articulation_metrics(pred, gt, [])
    # correct: a (revolute = revolute); c is revolute against a prismatic GT
    assert res["n_correct"] == 1 and res["recall"] == 0.5
    assert res["precision"] == pytest.approx(1 / 3)  # a, b, c count; the oven front does not
    assert details[1]["correct"] is False


def test_wrong_parts_say_why_each_counted_prediction_is_wrong():
    """One prediction of each kind of wrong next to a right one and an ignored one: the reasons,
    the true kind of the front each lies on, and nothing for what precision does not count."""
    g1, g2, g3, g4 = front(cx=0.0), front(cx=0.6), front(cx=-0.6, w=0.3), front(cx=-1.0, w=0.3)
    gt = PartsFile((door("d0", g1), door("d1", g2, "prismatic"), door("d2", g3), door("d3", g4)),
                   (IgnoreBox("oven", ((1.0, -0.7, 0.0), (1.6, -0.5, 1.0))),))
    pred = PartsFile((door("right", front(cx=0.01)),                    # d0, revolute: correct
                      door("typed", front(cx=0.6), "prismatic"),        # d1 is prismatic: correct
                      door("sliding_as_door", front(cx=0.59)),          # second on d1: unmatched, one front
                      door("merged", front(cx=-0.8, w=0.7)),            # over d2 and d3
                      door("nowhere", front(cx=0.0, cz=3.0)),           # above every front
                      door("oven_front", front(cx=1.3))))               # in the ignore box
    m = match_parts(pred, gt)
    rows = wrong_parts(m)
    assert [r["why"] for r in rows] == ["off_front", "merged", "no_front"]
    assert [r["part"] for r in rows] == ["sliding_as_door", "merged", "nowhere"]
    assert rows[0]["gt_kind"] == "prismatic" and rows[0]["iou"] == pytest.approx(front_overlap(front(cx=0.59), g2))
    assert rows[1]["gt_kind"] == "revolute" and "gt_kind" not in rows[2]
    res, _ = articulation_metrics(pred, gt, [])
    assert len(rows) == res["n_pred"] - res["n_ignored"] - res["n_correct"]  # what precision counts against
    swapped = PartsFile((door("as_drawer", front(cx=0.0), "prismatic"),), ())
    (r,) = wrong_parts(match_parts(swapped, gt))
    assert r["why"] == "wrong_kind" and r["gt_kind"] == "revolute" and r["pred_kind"] == "prismatic" and r["iou"] == pytest.approx(1.0)
    assert [r["why"] for r in wrong_parts(match_parts(pred, PartsFile((), ())))] == ["no_front"] * 6  # no ground truth at all


def test_precision_by_flag_splits_the_counted_predictions():
    """Right and wrong predictions with and without ``low_margin``: each side's (correct,
    counted); an ignored prediction counts on neither side, and the two sides add up to the
    precision articulation_metrics reports."""
    from dataclasses import replace

    g1, g2 = front(cx=0.0), front(cx=0.6)
    gt = PartsFile((door("d0", g1), door("d1", g2, "prismatic")),
                   (IgnoreBox("oven", ((1.0, -0.7, 0.0), (1.6, -0.5, 1.0))),))
    flagged = lambda p: replace(p, extra={"low_margin": True})  # noqa: E731
    pred = PartsFile((flagged(door("right", front(cx=0.01))),                 # correct, flagged
                      door("typed", front(cx=0.6), "prismatic"),              # correct
                      flagged(door("nowhere", front(cx=0.0, cz=3.0))),        # wrong, flagged
                      flagged(door("twice", front(cx=0.59))),                 # wrong, flagged
                      door("unflagged_wrong", front(cx=-2.0)),                # wrong
                      flagged(door("oven_front", front(cx=1.3)))))            # ignored
    m = match_parts(pred, gt)
    by = precision_by_flag(m)
    assert by == {True: (1, 3), False: (1, 2)}
    res, _ = articulation_metrics(pred, gt, [])
    assert (by[True][0] + by[False][0]) / (by[True][1] + by[False][1]) == pytest.approx(res["precision"])
    assert precision_by_flag(m, "no_such_flag") == {True: (0, 0), False: (2, 5)}
    assert precision_by_flag(match_parts(PartsFile((), ()), gt)) == {True: (0, 0), False: (0, 0)}


def test_missed_parts_say_why_each_true_part_was_not_found():
    """One true part of each kind of miss beside a found one: the reasons, the prediction each
    names, and a row for exactly the parts recall counts as not found."""
    fs = [front(cx=0.0), front(cx=0.6), front(cx=-0.6, w=0.3), front(cx=-1.0, w=0.3), front(cx=1.4, w=0.4),
          front(cx=2.2, w=0.6)]
    gt = PartsFile(tuple(door(f"g{k}", f) for k, f in enumerate(fs)), ())
    pred = PartsFile((door("right", front(cx=0.01)),                    # g0: found
                      door("as_drawer", front(cx=0.6), "prismatic"),    # g1: wrongly typed
                      door("merged", front(cx=-0.8, w=0.7)),            # over g2 and g3
                      door("half", front(cx=1.5, w=0.2))))              # half of g4; g5: nothing
    m = match_parts(pred, gt)
    rows = missed_parts(m)
    assert [(r["part"], r["why"]) for r in rows] == [("g1", "wrong_kind"), ("g2", "merged"), ("g3", "merged"),
                                                      ("g4", "off_front"), ("g5", "no_part")]
    assert rows[0]["pred_kind"] == "prismatic" and rows[0]["iou"] == pytest.approx(1.0)
    assert rows[3]["iou"] == pytest.approx(front_overlap(front(cx=1.5, w=0.2), fs[4])) and "pred_kind" not in rows[4]
    res, _ = articulation_metrics(pred, gt, [])
    assert len(rows) == res["n_gt"] - res["n_correct"]  # what recall counts as not found
    assert [r["why"] for r in missed_parts(match_parts(PartsFile((), ()), gt))] == ["no_part"] * 6  # nothing predicted


def test_ea_score_extremes():
    a = np.array([[0.2, 0.1], [0.2, 0.9]])
    assert ea_pair(a, a) == pytest.approx(1.0)
    assert ea_pair(a, a[::-1]) == pytest.approx(1.0)  # a line has no direction
    b = np.array([[0.1, 0.5], [0.3, 0.5]])  # perpendicular, same midpoint
    assert ea_pair(a, b) == pytest.approx(0.0)
    c = a + [0.1, 0.0]
    assert ea_pair(a, c) == pytest.approx(0.9**2)


def test_projection_clips_to_near_plane_and_image():
    cam = Camera(Intrinsics(100.0, 100.0, 50.0, 50.0, 100, 100), np.eye(4))
    seg = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 5.0]])
    p = project_segment(seg, cam)
    assert p is not None and np.allclose(p, [[0.5, 0.5], [0.5, 0.5]])  # along the optical axis: a point
    seg = np.array([[-5.0, 0.0, 1.0], [5.0, 0.0, 1.0]])
    p = project_segment(seg, cam)
    assert np.allclose(np.sort(p[:, 0]), [0.0, 1.0]) and np.allclose(p[:, 1], 0.5)  # clipped to the image
    assert project_segment(np.array([[0, 0, -1.0], [0, 0, -2.0]]), cam) is None  # behind
    seg = np.array([[0.0, 0.1, -1.0], [0.0, 0.1, 1.0]])  # crosses the camera plane: finite, clipped
    p = project_segment(seg, cam)
    assert p is not None and np.all(np.isfinite(p))


def rigid(pid, lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return Part(pid, "rigid", center=tuple(((lo + hi) / 2).tolist()), bounds=(tuple(lo.tolist()), tuple(hi.tolist())))


def test_box_iou_3d_against_a_slow_reference():
    from drawer_lib.metrics.articulation import box_iou_3d

    rng = np.random.default_rng(0)
    a = np.sort(rng.uniform(0, 1, (7, 2, 3)), axis=1)
    b = np.sort(rng.uniform(0, 1, (5, 2, 3)), axis=1)
    b[0, 1] = b[0, 0]  # an empty (flat) box
    ref = np.zeros((7, 5))
    for i in range(7):
        for j in range(5):
            inter = np.prod([max(0.0, min(a[i, 1, k], b[j, 1, k]) - max(a[i, 0, k], b[j, 0, k])) for k in range(3)])
            union = np.prod(a[i, 1] - a[i, 0]) + np.prod(b[j, 1] - b[j, 0]) - inter
            ref[i, j] = inter / union if union > 0 else 0.0
    np.testing.assert_allclose(box_iou_3d(a, b), ref, atol=1e-12)
    assert box_iou_3d(a[:1], a[:1])[0, 0] == pytest.approx(1.0)
    assert box_iou_3d(np.zeros((0, 2, 3)), b).shape == (0, 5)


def test_rigid_metrics_match_one_to_one_at_iou_quarter():
    from drawer_lib.metrics.articulation import rigid_metrics

    gt = PartsFile((rigid("cup_0", (0, 0, 0), (0.1, 0.1, 0.1)), rigid("pot_0", (1, 0, 0), (1.2, 0.2, 0.2)),
                    rigid("jar_0", (2, 0, 0), (2.1, 0.1, 0.1))))
    pred = PartsFile((rigid("object_0", (0.01, 0, 0), (0.11, 0.1, 0.1)),       # IoU 0.82 with the cup
                      rigid("object_1", (0.0, 0, 0), (0.1, 0.1, 0.1)),         # a duplicate of the cup: unmatched
                      rigid("object_2", (1.1, 0, 0), (1.3, 0.2, 0.2)),         # IoU 1/3 with the pot
                      rigid("object_3", (2.07, 0, 0), (2.17, 0.1, 0.1))))      # IoU 0.18 with the jar: too low
    m, details = rigid_metrics(pred, gt)
    assert m["n_rigid_matched"] == 2 and m["rigid_precision"] == pytest.approx(2 / 4)
    assert m["rigid_recall"] == pytest.approx(2 / 3)
    assert [d["pred"] for d in details] == ["object_1", "object_2", None]  # the exact duplicate wins the cup
    m0, _ = rigid_metrics(PartsFile(()), gt)
    assert "rigid_precision" not in m0 and m0["rigid_recall"] == 0.0
