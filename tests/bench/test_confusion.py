"""The benchmark's kinds: a part's label (family and hinge side from its axis) and the split's
confusion matrix."""

import numpy as np

from drawer_lib.articulation.joints import hinge_axis
from drawer_lib.bench.evaluate import confusion_matrix
from drawer_lib.io.parts import Axis, Front, Part
from drawer_lib.metrics.articulation import hinge_side, part_kind

FRONT = Front((1.0, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.6, 0.7))


def _revolute(hinge: str, family: str = "door", flip: bool = False) -> Part:
    ax = hinge_axis(FRONT, hinge)
    d = tuple(-x for x in ax.direction) if flip else ax.direction
    return Part(f"{family}_0", "revolute", Axis(ax.origin, d), (0.0, 1.57), FRONT, extra={"family": family})


def test_hinge_side_from_the_axis():
    for side in ("left", "right", "top", "bottom"):
        assert hinge_side(_revolute(side)) == side
        assert hinge_side(_revolute(side, flip=True)) == side  # the axis' sign does not name the edge
    slider = Part("drawer_0", "prismatic", Axis(FRONT.center, (0.0, -1.0, 0.0)), (0.0, 0.4), FRONT)
    assert hinge_side(slider) is None
    along_normal = Part("door_0", "revolute", Axis(FRONT.center, (0.0, 1.0, 0.0)), (0.0, 1.0), FRONT)
    assert hinge_side(along_normal) is None


def test_part_kinds():
    assert part_kind(_revolute("left")) == "door_left"
    assert part_kind(_revolute("top", "flap")) == "flap_top"
    assert part_kind(None) == "missed"
    slider = Part("drawer_0", "prismatic", Axis(FRONT.center, (0.0, -1.0, 0.0)), (0.0, 0.4), FRONT,
                  extra={"family": "drawer"})
    assert part_kind(slider) == "drawer"


def test_confusion_matrix_counts_and_order():
    rows = [{"fitted": {"confusion": [["drawer", "drawer"], ["door_left", "door_right"], ["drawer", "missed"]]}},
            {"fitted": {"confusion": [["none", "drawer"], ["drawer", "drawer"]]}}]
    g, p, c = confusion_matrix(rows, "fitted")
    assert g == ["door_left", "drawer", "none"] and p == ["door_right", "drawer", "missed"]
    assert c.tolist() == [[1, 0, 0], [0, 2, 1], [0, 1, 0]]
    assert int(np.sum(c)) == 5
