"""The fit of the decision weights (drawer_lib/bench/fit.py): the GT label of a detected front,
the fit recovering a known rule from features drawn for it, what it keeps from the prior, the
cross-validation, and the weights file it writes."""

import json

import numpy as np
import pytest
import torch

from drawer_lib.articulation.vocab import COMMON, DOOR_ONLY, HYPOTHESES, WEIGHT_SETS, prior_weights
from drawer_lib.articulation.weights import SCHEMA, read_weights, write_weights
from drawer_lib.bench import fit as fd
from drawer_lib.errors import InputError
from drawer_lib.io.parts import Axis, Front, IgnoreBox, Part, PartsFile

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


def draw(n: int, seed: int = 0, kitchens: int = 1) -> list:
    """Fronts labelled by a rule on two features (handle at the top -> drawer, a partner ->
    sliding, else a door hinged away from the handle, no handle -> fixed), spread over
    ``kitchens`` kitchen names."""
    g = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        f = dict.fromkeys(COMMON, 0.0)
        f["bias"] = 1.0
        d = {s: dict.fromkeys(DOOR_ONLY, 0.0) for s in ("left", "right")}
        kind = g.integers(4)
        name = f"k{i % kitchens}"
        if kind == 3:
            rows.append((name, f, d, "fixed"))
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
        rows.append((name, f, d, lab))
    return rows


def test_fit_recovers_a_rule_it_can_express():
    """The fit classifies held-out fronts of the rule it was fitted on."""
    tr, te = fd.tensors(draw(150)), fd.tensors(draw(100, seed=1))
    W = fd.fit(*tr, lam=0.001, prior={})
    acc = float((fd.scores(W, te[0], te[1]).argmax(-1) == te[2]).double().mean())
    assert acc > 0.97
    assert all(torch.isfinite(v).all() for v in W.values())
    assert len(HYPOTHESES) == fd.scores(W, te[0], te[1]).shape[1]


def test_fit_keeps_the_prior_where_the_data_cannot_speak():
    """Label weights stay the prior's; a hypothesis without examples keeps all its prior
    weights (flap_bottom, flap_top here); one with fewer than min_examples only gets its bias."""
    prior = prior_weights()
    rows = draw(200)
    Xc, Xd, y = fd.tensors(rows)
    W = fd.as_dict(fd.fit(Xc, Xd, y, lam=0.001, prior=prior, min_examples=0), ndigits=6)
    assert W["drawer"]["lab_drawer"] == prior["drawer"]["lab_drawer"] and W["door"]["lab_door"] == prior["door"]["lab_door"]
    assert W["flap_bottom"] == prior["flap_bottom"] and W["flap_top"] == prior["flap_top"]
    assert W["drawer"].get("h_top", 0.0) != prior["drawer"]["h_top"]  # fitted
    # no flap in the data: unpenalised, the biases of the others would rise together without bound
    # (a flap's probability falls at no cost) and a flap could never win again
    assert max(abs(w.get("bias", 0.0)) for w in W.values()) < 10.0  # was 17-23 with the biases unpenalised
    n_sliding = sum(r[3] == "sliding" for r in rows)
    few = fd.as_dict(fd.fit(Xc, Xd, y, lam=0.001, prior=prior, min_examples=n_sliding + 1), ndigits=6)
    assert {k: v for k, v in few["sliding"].items() if k != "bias"} == prior["sliding"]
    assert few["sliding"].get("bias", 0.0) != prior["sliding"].get("bias", 0.0)


def test_a_feature_no_train_front_shows_keeps_its_prior_weight():
    """bare_tall is 0 on every drawn front: the fit keeps the prior's +1 for a door (the penalty
    alone would take it to 0) and says so; once some fronts show it, it is fitted."""
    prior = prior_weights()
    rows = draw(200)
    Xc, Xd, y = fd.tensors(rows)
    assert "bare_tall" in fd.unseen_features(Xc, Xd) and "handle" not in fd.unseen_features(Xc, Xd)
    assert "h_free" not in fd.unseen_features(Xc, Xd)  # a door feature seen on one side only is seen
    W = fd.as_dict(fd.fit(Xc, Xd, y, lam=0.01, prior=prior), ndigits=6)
    assert W["door"]["bare_tall"] == prior["door"]["bare_tall"] == 1.0
    res = fd.fit_decisions(rows, prior, [1e-2], folds=2, min_examples=0)
    assert "bare_tall" in res.unseen and res.record()["unseen_features_kept_prior"] == res.unseen
    assert res.weights["door"]["bare_tall"] == 1.0
    # the same fronts, the fixed ones now tall and stacked without a handle: the data speak
    for _, f, _, lab in rows:
        if lab == "fixed":
            f["bare_tall"] = 1.0
    Xc, Xd, y = fd.tensors(rows)
    assert "bare_tall" not in fd.unseen_features(Xc, Xd)
    W = fd.as_dict(fd.fit(Xc, Xd, y, lam=0.01, prior=prior), ndigits=6)
    assert W["door"].get("bare_tall", 0.0) < 1.0 and W["fixed"].get("bare_tall", 0.0) > 0.0
    empty = fd.unseen_features(Xc[:0], Xd[:0])
    assert empty == frozenset(COMMON) | frozenset(DOOR_ONLY)


def test_a_penalty_centred_on_the_prior_pulls_towards_it():
    """A huge penalty: centred on zero every fitted weight but the biases' spread goes to 0;
    centred on the prior every weight stays at the prior's. A small one: both fit the data."""
    prior = prior_weights()
    rows = draw(200)
    Xc, Xd, y = fd.tensors(rows)
    big_zero = fd.as_dict(fd.fit(Xc, Xd, y, lam=1e6, prior=prior), ndigits=3)
    big_prior = fd.as_dict(fd.fit(Xc, Xd, y, lam=1e6, prior=prior, centre="prior"), ndigits=3)
    assert big_zero["door"].get("handle", 0.0) == 0.0 != prior["door"]["handle"]
    for k in big_prior:
        for f, w in prior.get(k, {}).items():
            assert abs(big_prior[k].get(f, 0.0) - w) < 1e-2, (k, f)
    small_zero = fd.fit(Xc, Xd, y, lam=1e-6, prior=prior)
    small_prior = fd.fit(Xc, Xd, y, lam=1e-6, prior=prior, centre="prior")
    acc = lambda W: float((fd.scores(W, Xc, Xd).argmax(-1) == y).double().mean())
    assert acc(small_prior) > 0.9 and abs(acc(small_prior) - acc(small_zero)) < 0.03
    with pytest.raises(ValueError, match="centre 'one'"):
        fd.fit(Xc, Xd, y, lam=1.0, prior=prior, centre="one")


def test_cross_validation_picks_the_penalty_and_is_deterministic():
    rows = draw(240, kitchens=6)
    log = []
    a = fd.fit_decisions(rows, prior_weights(), [1e-4, 1e-2, 10.0], folds=3, min_examples=5,
                         log=lambda i, lam, acc: log.append((i, lam, acc)))
    b = fd.fit_decisions(rows, prior_weights(), [1e-4, 1e-2, 10.0], folds=3, min_examples=5)
    assert a.weights == b.weights and a.lam == b.lam and a.cv == b.cv
    assert [x[:2] for x in log] == [(0, 1e-4), (1, 1e-2), (2, 10.0)]
    assert a.cv[2][1] < max(acc for _, acc in a.cv)  # a penalty of 10 cannot fit the rule
    assert a.lam in (1e-4, 1e-2) and a.train_accuracy > 0.97
    assert a.kitchens == [f"k{i}" for i in range(6)] and sum(a.counts.values()) == 240
    assert np.asarray(a.confusion).sum() == 240 and np.trace(np.asarray(a.confusion)) >= 0.97 * 240
    with pytest.raises(InputError, match="no labelled fronts"):
        fd.fit_decisions([], prior_weights(), [1e-3], 3, 5)


def test_the_penalty_within_one_standard_error_of_the_best_is_the_largest():
    cv = [(1e-5, 0.778), (3e-5, 0.797), (1e-4, 0.802), (3e-4, 0.792), (1e-3, 0.773), (1e-2, 0.749)]
    assert fd.select_penalty(cv, 207, "best") == 1e-4
    # se = sqrt(0.802 * 0.198 / 207) = 0.0277: 0.792 is within it, 0.773 is not
    assert fd.select_penalty(cv, 207, "one_se") == 3e-4
    assert fd.select_penalty(cv, 10**6, "one_se") == 1e-4  # many fronts: a tiny se, the best
    assert fd.select_penalty([(1e-3, 0.9), (1e-2, 0.9)], 50, "best") == 1e-2  # ties: the larger
    with pytest.raises(ValueError, match="rule"):
        fd.select_penalty(cv, 207, "median")


def test_labelled_fronts_read_decisions_and_skip_what_has_no_label(tmp_path):
    gt = PartsFile((Part("w0", "prismatic", Axis((0.25, -0.6, 0.45), N), (0, 0.4), front(0.25, 0.45)),),
                   (IgnoreBox("a0", ((3.0, -0.7, 0.0), (3.5, -0.5, 0.9)), front(3.25, 0.45), 9),))
    f0 = dict.fromkeys(COMMON, 0.0)
    d0 = {s: dict.fromkeys(DOOR_ONLY, 0.0) for s in ("left", "right")}
    segs = [{"segment": 0, "front": front(0.25, 0.45).to_json(), "features": f0, "door_features": d0},
            {"segment": 1, "front": front(3.25, 0.45).to_json(), "features": f0, "door_features": d0},  # ignored
            {"segment": 2, "front": front(5.0, 0.45).to_json(), "features": f0, "door_features": d0},  # no part
            {"segment": 3, "front": front(1.0, 0.45).to_json(), "family": "fixed"},  # no features
            {"segment": 4, "front": front(0.25, 0.45).to_json(), "features": f0, "door_features": d0,
             "pair": {"side": "left"}}]  # a door of a pair: the whole front's features, not its own
    p = tmp_path / "decisions.json"
    p.write_text(json.dumps({"estimator": "geometric", "segments": segs}))
    rows = fd.labelled_fronts("k7", p, gt)
    assert [(r[0], r[3]) for r in rows] == [("k7", "drawer"), ("k7", "fixed")]
    p.write_text("{not json")
    with pytest.raises(InputError, match="decisions.json: not an articulation decisions file"):
        fd.labelled_fronts("k7", p, gt)


def test_the_weights_file_round_trips_and_names_what_is_wrong(tmp_path):
    w = fd.fit_decisions(draw(120, kitchens=4), prior_weights(), [1e-3], 2, 5).weights
    p = tmp_path / "weights.json"
    write_weights(p, w, {"lambda": 1e-3})
    assert read_weights(p) == w
    assert set(read_weights(p)) == set(WEIGHT_SETS)
    with pytest.raises(InputError, match="no decision weights .*dvc repro fit_decisions"):
        read_weights(tmp_path / "missing.json")
    d = json.loads(p.read_text())
    p.write_text(json.dumps({**d, "schema": "other/1"}))
    with pytest.raises(InputError, match="schema 'other/1', expected " + repr(SCHEMA)):
        read_weights(p)
    d["weights"]["door"]["h_free"] = float("nan")
    p.write_text(json.dumps(d))  # json writes NaN: the reader must refuse it
    with pytest.raises(InputError, match=r"door.h_free = nan is not a finite number"):
        read_weights(p)
