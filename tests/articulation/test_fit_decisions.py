"""scripts/fit_decisions.py: the GT label of a detected front, and the fit recovering a known
rule from features drawn for it."""

import importlib.util
from pathlib import Path

import numpy as np
import torch

from drawer_lib.articulation.scoring import COMMON, DOOR_ONLY, HYPOTHESES
from drawer_lib.io.parts import Axis, Front, IgnoreBox, Part, PartsFile

SPEC = importlib.util.spec_from_file_location("fit_decisions", Path(__file__).resolve().parents[2] / "scripts/fit_decisions.py")
fd = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(fd)

N, U = (0.0, -1.0, 0.0), (1.0, 0.0, 0.0)


def front(x, z, w=0.5, h=0.7, y=-0.6):
    return Front((x, y, z), N, U, (w, h))


def test_gt_label_of_each_kind():
    door_l = Part("d0", "revolute", Axis((0.0, -0.6, 0.45), (0, 0, -1.0)), (0, 1.5), front(0.25, 0.45))
    door_r = Part("d1", "revolute", Axis((1.0, -0.6, 0.45), (0, 0, 1.0)), (0, 1.5), front(0.75, 0.45))
    flap = Part("f0", "revolute", Axis((1.5, -0.6, 0.1), (1.0, 0, 0)), (0, 1.5), front(1.5, 0.45))
    drawer = Part("w0", "prismatic", Axis((2.25, -0.6, 0.45), N), (0, 0.4), front(2.25, 0.45))
    slide = Part("s0", "prismatic", Axis((2.75, -0.6, 0.45), U), (0, 0.4), front(2.75, 0.45))
    ign = IgnoreBox("a0", ((3.0, -0.7, 0.0), (3.5, -0.5, 0.9)), front(3.25, 0.45), 9)
    gt = PartsFile((door_l, door_r, flap, drawer, slide), (ign,))
    assert fd.gt_label(front(0.26, 0.44), gt) == "door_left"
    assert fd.gt_label(front(0.74, 0.46), gt) == "door_right"
    assert fd.gt_label(front(1.5, 0.45), gt) == "flap_bottom"
    assert fd.gt_label(front(2.25, 0.45), gt) == "drawer"
    assert fd.gt_label(front(2.75, 0.45), gt) == "sliding"
    assert fd.gt_label(front(3.25, 0.45), gt) is None  # a fixed front that looks articulated: no label
    assert fd.gt_label(front(5.0, 0.45), gt) == "fixed"  # no part there
    assert fd.gt_label(front(0.5, 0.45, w=1.0), gt) == "fixed"  # two doors merged: neither
    assert fd.gt_label(front(0.25, 0.45, y=-0.75), gt) == "fixed"  # 15 cm off the plane


def test_fit_recovers_a_rule_it_can_express():
    """Fronts labelled by a rule on two features (handle at the top -> drawer, a partner ->
    sliding, else a door hinged away from the handle, no handle -> fixed): the fit classifies
    held-out fronts of the same rule."""
    g = np.random.default_rng(0)

    def draw(n):
        rows = []
        for _ in range(n):
            f = dict.fromkeys(COMMON, 0.0)
            f["bias"] = 1.0
            d = {s: dict.fromkeys(DOOR_ONLY, 0.0) for s in ("left", "right")}
            kind = g.integers(4)
            if kind == 3:
                rows.append(("k", f, d, "fixed"))
                continue
            f["handle"] = 1.0
            if kind == 0:
                f["h_top"] = g.uniform(0.6, 1.0)
                lab = "drawer"
            elif kind == 1:
                f["partner"] = 1.0
                f["h_side"] = g.uniform(0.5, 1.0)
                lab = "sliding"
            else:
                f["h_side"] = g.uniform(0.5, 1.0)
                side = ["left", "right"][g.integers(2)]
                d[side]["h_free"] = f["h_side"]
                d["right" if side == "left" else "left"]["h_hinge"] = f["h_side"]
                lab = f"door_{side}"
            rows.append(("k", f, d, lab))
        return rows

    tr, te = fd.tensors(draw(150)), fd.tensors(draw(100))
    W = fd.fit(*tr, lam=0.001, fixed={})
    acc = float((fd.scores(W, te[0], te[1]).argmax(-1) == te[2]).double().mean())
    assert acc > 0.97
    assert all(torch.isfinite(v).all() for v in W.values())
    assert len(HYPOTHESES) == fd.scores(W, te[0], te[1]).shape[1]
