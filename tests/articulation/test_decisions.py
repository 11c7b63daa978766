"""The score rule's machinery (features, scores, mirrored doors, the rail probe, checked weights)
and the hand-built hard cases (drawer_lib/bench/cases.py) with explicit weights: the prior,
and weights that type every front the same way. What the fitted weights do on the cases is a
figure of the pipeline (bench/fit/cases.json), not a test."""

import dataclasses
import math
from pathlib import Path


import numpy as np
import pytest
import yaml

from drawer_lib.articulation.config import ArticulateConfig, JointsConfig, TypesConfig
from drawer_lib.articulation.decide import decide_by_score
from drawer_lib.articulation.probes import TRACK_EDGE, TRACK_PLANE, rail_extent, rail_extents_moved, rail_run
from drawer_lib.articulation.scoring import Evidence, door_features, features, score
from drawer_lib.articulation.vocab import COMMON, DOOR_ONLY, HYPOTHESES, WEIGHT_SETS, Handle, prior_weights
from drawer_lib.bench.cases import CASES, Scene, run_cases, single_sliding_door
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Front

ROOT = Path(__file__).resolve().parents[2]
CFG = to_typed(ArticulateConfig, yaml.safe_load((ROOT / "conf/articulate/default.yaml").read_text()), "articulate")
PRIOR = CFG.types.prior
PRIOR_PASSES = {"full_height_door", "microwave_door_yaw_0", "microwave_door_yaw_30", "microwave_door_yaw_-40",
                "mirrored_wall_doors", "oven_door_top_bar", "knobless_drawer_stack", "sliding_without_partner",
                "push_to_open_door", "push_to_open_door_under_drawer", "shallow_drawer_off_centre_knob"}


def only(hypothesis: str) -> dict[str, dict[str, float]]:
    """Weights that score ``hypothesis`` 10 above every other hypothesis on any front (a door
    side: 10 + 5 x the handle's closeness to its free / hinge edge, for a handle by the right
    edge)."""
    w = {k: {} for k in WEIGHT_SETS}
    if hypothesis.startswith("door_"):
        w["door"] = {"bias": 10.0, "h_free" if hypothesis == "door_left" else "h_hinge": 5.0}
    else:
        w[hypothesis] = {"bias": 10.0}
    return w


def test_the_shipped_prior_is_the_hand_set_one():
    assert PRIOR == prior_weights()
    assert CFG.types.weights == "fitted"


def test_decisions_record_every_feature_and_score():
    (p,), rep, _ = Scene().front(0.0, 0.5, 0.1, 0.8, -0.6, (0.455, 0.7, "v")).run(CFG, PRIOR)
    row = next(r for r in rep if r.get("part") == p.id)
    assert set(row["features"]) == set(COMMON)
    assert set(row["door_features"]["left"]) == set(DOOR_ONLY)
    assert set(row["scores"]) == set(HYPOTHESES)
    assert max(row["scores"], key=row["scores"].get) == "door_left"
    assert p.kind == "revolute" and p.extra["hinge"] == "left"


def test_features_do_not_depend_on_the_weights():
    """What the fit learns from is the same whatever weights wrote decisions.json."""
    s = Scene().front(0.0, 0.5, 0.1, 0.33, -0.6, (0.25, 0.3, "h")).front(0.0, 0.5, 0.333, 0.8, -0.6, (0.455, 0.7, "v"))
    _, a, _ = s.run(CFG, PRIOR)
    _, b, _ = s.run(CFG, only("fixed"))
    assert [r["features"] for r in a] == [r["features"] for r in b]
    assert [r["door_features"] for r in a] == [r["door_features"] for r in b]
    assert [r["family"] for r in a] != [r["family"] for r in b]  # ... though the decisions differ


@pytest.mark.parametrize("hyp", HYPOTHESES)
def test_the_highest_score_wins(hyp):
    # a lone front has no track: sliding is ruled out unless the gate is off (tested on its own)
    cfg = CFG if hyp != "sliding" else dataclasses.replace(CFG, types=dataclasses.replace(CFG.types, sliding_needs_track=False))
    (p,), rep, _ = Scene().front(0.0, 0.5, 0.1, 0.8, -0.6, (0.455, 0.7, "v")).run(cfg, only(hyp))
    assert rep[0]["family"] == hyp.split("_")[0]
    if hyp == "fixed":
        assert p is None
    elif hyp.startswith(("door", "flap")):
        assert p.kind == "revolute" and p.extra["hinge"] == hyp.split("_")[1]
    else:
        assert p.kind == "prismatic"


def test_tall_and_bare_stack_features():
    """``tall`` ramps from 0 at drawer_max_height to 2 at 20 cm above it; ``bare_stack`` is
    ``stacked`` for a front without a handle and 0 with one; ``bare_lone`` is 1 for a front
    with neither a handle nor a stacked neighbour, unless it is flanked (a patch of wall)."""

    def ev(h, stacked, handle, flanked=False):
        return Evidence(handle=Handle(0.5, 0.9, "horizontal", 30, "masks") if handle else None, size=(0.6, h),
                        z_mid=0.5, stacked=stacked, beside_left=False, beside_right=False, partner=False, rail=0.0,
                        carcass=0.5, labels={}, support=30, flanked=flanked)

    tall = [features(ev(h, 0, True), [], [], True, drawer_max_height=0.45)["tall"] for h in (0.2, 0.45, 0.5, 0.6, 0.65, 2.0)]
    assert tall == pytest.approx([0.0, 0.0, 0.5, 1.5, 2.0, 2.0])
    assert features(ev(0.6, 0, True), [], [], True, drawer_max_height=0.7)["tall"] == 0.0
    assert [features(ev(0.2, st, False), [], [], True)["bare_stack"] for st in (0, 1, 2, 5)] == [0.0, 0.5, 1.0, 1.0]
    assert features(ev(0.2, 2, True), [], [], True)["bare_stack"] == 0.0
    assert [features(ev(0.2, st, False), [], [], True)["bare_lone"] for st in (0, 1, 2)] == [1.0, 0.0, 0.0]
    assert features(ev(0.2, 0, True), [], [], True)["bare_lone"] == 0.0
    assert features(ev(0.2, 0, False, flanked=True), [], [], True)["bare_lone"] == 0.0
    with pytest.raises(ConfigError, match="drawer_max_height = 0.0"):
        TypesConfig(drawer_max_height=0.0)


def test_bare_tall_is_a_stacked_front_without_a_handle_taller_than_a_drawer():
    """``bare_tall`` is min(1, ``tall``) for a front without a handle sharing its top or bottom
    edge with another front, 0 with a handle or with no such neighbour; being flanked does not
    turn it off (a front that shares an edge with a front is no patch of wall)."""

    def ev(h, stacked, handle, flanked=False):
        return Evidence(handle=Handle(0.5, 0.9, "horizontal", 30, "masks") if handle else None, size=(0.6, h),
                        z_mid=0.5, stacked=stacked, beside_left=False, beside_right=False, partner=False, rail=0.0,
                        carcass=0.5, labels={}, support=30, flanked=flanked)

    got = [features(ev(h, 1, False), [], [], True)["bare_tall"] for h in (0.2, 0.45, 0.5, 0.55, 0.7, 2.0)]
    assert got == pytest.approx([0.0, 0.0, 0.5, 1.0, 1.0, 1.0])
    assert features(ev(0.7, 0, False), [], [], True)["bare_tall"] == 0.0  # lone: bare_lone's
    assert features(ev(0.7, 2, True), [], [], True)["bare_tall"] == 0.0
    assert features(ev(0.7, 1, False, flanked=True), [], [], True)["bare_tall"] == 1.0
    assert features(ev(0.7, 1, False), [], [], True, drawer_max_height=0.7)["bare_tall"] == 0.0


@pytest.mark.parametrize("height, hinged_min, excluded", [
    (0.15, 0.2, True), (0.199, 0.2, True), (0.2, 0.2, False), (0.6, 0.2, False), (0.15, None, False), (0.15, 0.1, False),
])
def test_a_front_too_shallow_for_hinges_is_no_door_nor_top_hinged_flap(height, hinged_min, excluded):
    """``types.hinged_min_height`` excludes the side-hinged doors and the top-hinged flap of a
    shallower front, with why; the bottom-hinged flap (a tilt-out) and the rest stay; null: off."""
    types = dataclasses.replace(CFG.types, hinged_min_height=hinged_min)
    ev = Evidence(handle=Handle(0.92, 0.5, "round", 30, "colour"), size=(0.6, height), z_mid=0.8, stacked=1,
                  beside_left=False, beside_right=False, partner=False, rail=0.0, carcass=0.5, labels={}, support=30)
    dec, rec = decide_by_score(ev, types, PRIOR)
    hinged = {"door_left", "door_right", "flap_top"}
    assert (hinged <= set(rec["excluded"])) == excluded
    assert "flap_bottom" not in rec["excluded"] and "drawer" not in rec["excluded"]
    if excluded:
        assert "no room for hinges" in rec["excluded"]["door_left"] and dec.family == "drawer"
    else:
        assert not hinged & set(rec["excluded"])
    if hinged_min is None and height == 0.15:
        assert dec.family == "door"  # the knob by the right edge, as the prior reads it without the rule
    with pytest.raises(ConfigError, match="hinged_min_height = -0.1"):
        TypesConfig(hinged_min_height=-0.1)


def test_door_hypotheses_mirror_exactly():
    """Left and right doors share one weight vector on side-relative features: a mirrored front
    scores the mirrored hypothesis the same."""

    def ev(a_u, left, right):
        return Evidence(handle=Handle(a_u, 0.6, "vertical", 30, "masks"), size=(0.45, 0.7), z_mid=0.9, stacked=0,
                        beside_left=left, beside_right=right, partner=False, rail=0.0, carcass=0.5, labels={},
                        support=30)

    w = {k: {f: 0.37 * (i + 1) * (-1) ** i for i, f in enumerate(COMMON + (DOOR_ONLY if k == "door" else ()))}
         for k in WEIGHT_SETS}  # every weight non-zero
    for a_u, left, right in ((0.1, False, True), (0.85, True, False), (0.5, True, True)):
        e, m = ev(a_u, left, right), ev(1 - a_u, right, left)
        se = score(features(e, [], [], True), {s: door_features(e, s) for s in ("left", "right")}, w)
        sm = score(features(m, [], [], True), {s: door_features(m, s) for s in ("left", "right")}, w)
        assert se["door_left"] == pytest.approx(sm["door_right"]) and se["door_right"] == pytest.approx(sm["door_left"])
        assert se["drawer"] == pytest.approx(sm["drawer"])


def test_evidence_is_built_by_keyword():
    with pytest.raises(TypeError):
        Evidence(None, (0.5, 0.5), 0.5, 0, False, False, False, 0.0, None, {}, 1)  # the old positional form


def test_rail_extent_finds_a_track_and_not_a_counter():
    f = Front((0.25, -0.6, 0.5), (0, -1.0, 0), (1.0, 0, 0), (0.5, 0.6))
    g = np.random.default_rng(0)
    # a rail strip 1 m long just above the front, facing outward, 1 cm proud
    rail = np.stack([g.uniform(-0.25, 0.75, 400), np.full(400, -0.61), g.uniform(0.81, 0.84, 400)], -1)
    out = np.tile([0, -1.0, 0], (400, 1))
    assert rail_extent(f, rail, out) == pytest.approx(2.0, abs=0.1)  # twice the front's width
    # the same strip with a counter top behind it: no track
    top = np.stack([g.uniform(-0.25, 0.75, 400), g.uniform(-0.6, 0.0, 400), np.full(400, 0.84)], -1)
    up = np.tile([0, 0, 1.0], (400, 1))
    assert rail_extent(f, np.concatenate([rail, top]), np.concatenate([out, up])) == 0.0
    # the underside of a cabinet's top seen through its open half (facing down): still a track
    assert rail_extent(f, np.concatenate([rail, top]), np.concatenate([out, -up])) == pytest.approx(2.0, abs=0.1)
    assert rail_extent(f, np.zeros((0, 3)), np.zeros((0, 3))) == 0.0
    # the pulls of the fronts above and beside it, with gaps between them: no track
    pulls = rail[(np.abs(rail[:, 0] - 0.25) > 0.06) & (np.abs(rail[:, 0] - 0.25) < 0.2)]
    assert rail_extent(f, pulls, out[: len(pulls)]) == 0.0


def test_a_track_inside_the_fronts_edge_is_found_when_looked_for_there():
    # the front's mask spilt onto its track: the track lies 0.5 .. 2.5 cm inside the top edge
    f = Front((0.25, -0.6, 0.5), (0, -1.0, 0), (1.0, 0, 0), (0.5, 0.6))
    g = np.random.default_rng(1)
    out = np.tile([0, -1.0, 0], (400, 1))
    rail = np.stack([g.uniform(-0.25, 0.75, 400), np.full(400, -0.61), g.uniform(0.775, 0.795, 400)], -1)
    assert rail_extent(f, rail, out) == 0.0
    assert rail_extent(f, rail, out, inside=0.03) == pytest.approx(2.0, abs=0.1)
    lo, hi = rail_run(f, rail, out, inside=0.03)  # along u from the front's centre: 25 cm past each side
    assert lo == pytest.approx(-0.5, abs=0.03) and hi == pytest.approx(0.5, abs=0.03)
    # the front's own surface there, and a pull 30 cm long near its top: no track
    face = np.stack([g.uniform(0.0, 0.5, 400), np.full(400, -0.6), g.uniform(0.77, 0.8, 400)], -1)
    assert rail_extent(f, face, out, inside=0.03) == 0.0
    bar = rail[np.abs(rail[:, 0] - 0.25) < 0.15]
    assert rail_extent(f, bar, out[: len(bar)], inside=0.03) == 0.0
    # a frame-and-panel door whose plane is its panel: rails and stiles 6 cm wide, 1 cm proud
    fx, fz = g.uniform(0.0, 0.5, 6000), g.uniform(0.2, 0.8, 6000)
    frame = (fx < 0.06) | (fx > 0.44) | (fz < 0.26) | (fz > 0.74)
    shaker = np.stack([fx, np.where(frame, -0.61, -0.6), fz], -1)
    assert rail_extent(f, shaker, np.tile([0, -1.0, 0], (6000, 1)), inside=0.03) == 0.0
    with pytest.raises(ConfigError, match="rail_inside"):
        JointsConfig(rail_inside=-0.01)


def test_the_moved_fronts_tracks_are_those_of_the_moved_fronts():
    """rail_extents_moved reads only the points near the front; each of its six lengths is
    rail_extent of the front moved (the slow reference: every point)."""
    f = Front((0.25, -0.6, 0.5), (0, -1.0, 0), (1.0, 0, 0), (0.5, 0.6))
    g = np.random.default_rng(2)
    # a rail 5 mm proud along the top edge, and clutter all around
    rail = np.stack([g.uniform(-0.25, 0.75, 600), np.full(600, -0.605), g.uniform(0.805, 0.84, 600)], -1)
    clutter = g.uniform([-2.0, -1.0, -0.5], [2.5, 0.2, 2.0], (3000, 3))
    pts = np.concatenate([rail, clutter])
    nrm = np.concatenate([np.tile([0, -1.0, 0], (600, 1)), g.normal(size=(3000, 3))])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    got = rail_extents_moved(f, pts, nrm, inside=0.03)
    c, n = np.array(f.center), np.array(f.normal)
    moved = [dataclasses.replace(f, center=tuple(c + s * TRACK_PLANE * n)) for s in (1.0, -1.0)]
    moved += [dataclasses.replace(f, size=(0.5 + s * 2 * TRACK_EDGE, 0.6)) for s in (1.0, -1.0)]
    moved += [dataclasses.replace(f, size=(0.5, 0.6 + s * 2 * TRACK_EDGE)) for s in (1.0, -1.0)]
    assert got == [rail_extent(m, pts, nrm, inside=0.03) for m in moved]
    # 5 mm proud: the front's own test finds the track, its plane 2 mm out does not (3 mm proud)
    assert rail_extent(f, pts, nrm, inside=0.03) == pytest.approx(2.0, abs=0.1)
    assert got[0] == 0.0 and got[1] == pytest.approx(2.0, abs=0.1)


@pytest.mark.parametrize("proud, near", [(0.005, True), (0.012, False)])
def test_a_track_near_its_bound_is_reported_near_track(proud, near):
    """A single sliding door whose track stands 5 mm proud (1 mm over the test's 4 mm) is
    typed sliding, and is listed near_track and low_margin: its plane 2 mm out loses the track
    and the door. 12 mm proud, nothing another machine's mesh does turns it."""
    (p,), rep, _ = single_sliding_door(proud).run(CFG, PRIOR)
    row = next(r for r in rep if r.get("part") == p.id)
    assert p.extra["family"] == "sliding" and row["features"]["rail"] > 0.9
    assert ("near_track" in row) is near and row["low_margin"] is near and p.extra["low_margin"] is near
    if near:
        assert row["near_track"]["other"] == 0.0 and row["near_track"]["as"] != "sliding"


def test_weights_are_checked():
    w = {k: dict(v) for k, v in PRIOR.items()}
    w["door"]["h_sideways"] = 1.0
    with pytest.raises(ConfigError, match="articulate.types.prior.door: unknown feature 'h_sideways'"):
        TypesConfig(prior=w)
    with pytest.raises(ConfigError, match="missing hypotheses"):
        TypesConfig(prior={"drawer": {}})
    for bad in (math.nan, math.inf, "1.0", True):
        with pytest.raises(ConfigError, match="not a finite number"):
            TypesConfig(prior={**PRIOR, "fixed": {"bias": bad}})
    with pytest.raises(ConfigError, match="weights = 'learned' must be fitted or prior"):
        TypesConfig(weights="learned")


def test_the_hard_cases_with_the_prior():
    """The prior gets the cases a handle decides, an oven's top bar (too tall a front for a
    drawer), knobless drawers (a stack of handle-less fronts), a lone sliding door (its
    track) and a lone push-to-open door; a wall door's bar at its bottom corner (a flap's
    place) it gets wrong."""
    got = {r["name"]: r["passed"] for r in run_cases(CFG, PRIOR)}
    assert set(got) == {c.name for c in CASES}
    assert {n for n, ok in got.items() if ok} == PRIOR_PASSES


def test_every_hard_case_can_fail():
    """Typing every front the same way fails every case but the one of that type."""
    assert not any(r["passed"] for r in run_cases(CFG, only("fixed")))
    assert [r["name"] for r in run_cases(CFG, only("drawer")) if r["passed"]] == ["knobless_drawer_stack",
                                                                                "shallow_drawer_off_centre_knob"]


def test_cases_follow_the_config():
    """Without label votes and with the handle rule the microwave is still a left-hinged door."""
    cfg = dataclasses.replace(CFG, types=dataclasses.replace(CFG.types, rule="handle", use_labels=False))
    got = {r["name"]: r["passed"] for r in run_cases(cfg, PRIOR)}
    assert got["microwave_door_yaw_30"] and got["full_height_door"]


def test_object_share_of_label_votes():
    t = TypesConfig()
    assert t.object_share({}) == 0.0  # no votes (the geometric path): not an object
    assert t.object_share({"drawer": 3, "door": 2, "front": 1, "Cabinet Door ": 1}) == 0.0
    assert t.object_share({"box": 4}) == 1.0
    assert t.object_share({"object": 1, "front": 3}) == 0.25
    assert TypesConfig(front_labels=[]).object_share({"front": 2, "drawer": 2}) == 0.5


@pytest.mark.parametrize("window, threshold, excluded", [
    (0.35, 0.15, True), (0.15, 0.15, True), (0.149, 0.15, False), (0.02, 0.15, False), (None, 0.15, False),
    (0.35, None, False),
])
def test_a_glazed_front_is_no_drawer(window, threshold, excluded):
    """``types.window_contrast``: an oven door with its bar along the top and no label (a drawer
    on the prior weights) is excluded from the drawers once its window stands the threshold off
    its frame, and then typed the bottom-hinged flap it is; no image (None) or null: off."""
    types = dataclasses.replace(CFG.types, window_contrast=threshold, glazed_low=None)  # the window alone
    ev = Evidence(handle=Handle(0.5, 0.92, "horizontal", 60, "images"), size=(0.6, 0.45), z_mid=0.55, stacked=1,
                  beside_left=True, beside_right=True, partner=False, rail=0.0, carcass=0.5, labels={}, support=30,
                  window=window)
    dec, rec = decide_by_score(ev, types, PRIOR)
    assert ("drawer" in rec["excluded"]) == excluded
    if excluded:
        assert "a window" in rec["excluded"]["drawer"] and (dec.family, dec.hinge) == ("flap", "bottom")
    else:
        assert dec.family == "drawer"
    with pytest.raises(ConfigError, match="window_contrast"):
        TypesConfig(window_contrast=1.5)


@pytest.mark.parametrize("z_mid, handle, expected", [
    (0.45, None, ("flap", "bottom")),                                       # a bare oven door under the counter
    (0.45, Handle(0.5, 0.92, "horizontal", 60, "images"), ("flap", "bottom")),
    (0.45, Handle(0.05, 0.5, "vertical", 60, "images"), ("flap", "bottom")),  # even with a pull at a side
    (1.05, None, ("door", "left")),                                          # a bare microwave: a door, the tie's side
    (1.05, Handle(0.95, 0.5, "vertical", 60, "images"), ("door", "left")),    # pull on the right: hinged left
    (1.9, Handle(0.05, 0.5, "vertical", 60, "images"), ("door", "right")),    # a glass wall door
])
def test_a_glazed_front_low_is_an_oven_door_and_high_a_door(z_mid, handle, expected):
    """``types.glazed_low`` (with ``window_contrast``): a glazed front centred below it has only
    the bottom-hinged flap left; above it it is a hinged door, never a fixed panel (the hinge side
    from the pull); an opaque front and ``glazed_low: null`` keep the old decision."""
    types = dataclasses.replace(CFG.types, window_contrast=0.15, glazed_low=0.75)
    ev = Evidence(handle=handle, size=(0.6, 0.45) if z_mid < 1 else (0.4, 0.7), z_mid=z_mid, stacked=int(z_mid < 1),
                  beside_left=True, beside_right=True, partner=False, rail=0.0, carcass=0.5, labels={}, support=30,
                  window=0.35)
    dec, rec = decide_by_score(ev, types, PRIOR)
    assert (dec.family, dec.hinge) == expected
    assert "fixed" in rec["excluded"] and "glazed_low" in rec["excluded"]["fixed"]
    opaque = dataclasses.replace(ev, window=0.02)
    assert not {"fixed", "drawer"} & set(decide_by_score(opaque, types, PRIOR)[1]["excluded"])
    off = dataclasses.replace(types, glazed_low=None)
    assert set(decide_by_score(ev, off, PRIOR)[1]["excluded"]) - {"sliding"} == {"drawer"}
    if handle is None and z_mid < 1:  # a bare oven door over its drawer, glazed_low off: the old decision, fixed
        assert decide_by_score(ev, off, PRIOR)[0].family == "fixed"
    # a low glazed front that the interaction test keeps from swinging down: nothing left but fixed
    dec, rec = decide_by_score(dataclasses.replace(ev, z_mid=0.45), types, PRIOR,
                               blocked={"flap_bottom": "no room to swing"})
    assert dec.family == "fixed" and "fixed" not in rec["excluded"]
    with pytest.raises(ConfigError, match="glazed_low"):
        TypesConfig(glazed_low=-1.0)


def test_a_glazed_decision_near_its_thresholds_is_marked():
    """``glazed_near``: a window contrast within WINDOW_BAND of ``window_contrast`` (either side),
    or a glazed front's centre within GLAZED_BAND of ``glazed_low``, is a decision another
    machine's last bits could flip; clear of both, or with the rules off, it is not."""
    from drawer_lib.articulation.decide import GLAZED_BAND, WINDOW_BAND, glazed_near

    types = dataclasses.replace(CFG.types, window_contrast=0.15, glazed_low=0.75)
    ev = Evidence(handle=None, size=(0.6, 0.45), z_mid=0.45, stacked=1, beside_left=True, beside_right=True,
                  partner=False, rail=0.0, carcass=0.5, labels={}, support=30, window=0.35)

    def at(z: float = 0.45, **kw) -> bool:
        return glazed_near(dataclasses.replace(ev, **kw), types, z)

    assert not at() and not at(window=0.02) and not at(window=None)
    assert at(window=0.15 + WINDOW_BAND / 2) and at(window=0.15 - WINDOW_BAND / 2)
    assert at(z=0.75 - GLAZED_BAND / 2) and at(z=0.75 + GLAZED_BAND / 2)
    assert not at(window=0.02, z=0.75)  # an opaque front's height decides nothing
    assert not glazed_near(ev, dataclasses.replace(types, window_contrast=None), 0.75)
    assert decide_by_score(ev, types, PRIOR)[1]["glazed_near"] is False
    assert decide_by_score(dataclasses.replace(ev, window=0.16), types, PRIOR)[1]["glazed_near"] is True


def test_pair_of_doors_needs_a_vertical_pull_near_the_middle_room_and_both_doors():
    from drawer_lib.articulation.decide import pair_of_doors

    cfg = TypesConfig(pair_pull=0.1, pair_min_width=0.25)
    v = Handle(0.55, 0.5, "vertical", 50, "images")
    why, near = pair_of_doors(v, (0.8, 0.7), {}, cfg)
    assert "pair of doors" in why and near is False
    assert pair_of_doors(v, (0.8, 0.7), {}, TypesConfig(pair_pull=0.0)) is None  # off
    assert pair_of_doors(None, (0.8, 0.7), {}, cfg) is None
    for o in ("horizontal", "round"):
        assert pair_of_doors(dataclasses.replace(v, orientation=o), (0.8, 0.7), {}, cfg) is None
    assert pair_of_doors(dataclasses.replace(v, a_u=0.61), (0.8, 0.7), {}, cfg) is None
    assert pair_of_doors(dataclasses.replace(v, a_u=0.39), (0.8, 0.7), {}, cfg) is None
    assert pair_of_doors(v, (0.49, 0.7), {}, cfg) is None
    assert pair_of_doors(v, (0.8, 0.7), {"door_right": "blocked"}, cfg) is None
    assert pair_of_doors(v, (0.8, 0.7), {"sliding": "no track", "drawer": "a window"}, cfg) is not None
    # within 0.02 of a bound (of the width, or m): a decision another machine could make otherwise
    assert pair_of_doors(dataclasses.replace(v, a_u=0.59), (0.8, 0.7), {}, cfg)[1] is True
    assert pair_of_doors(v, (0.51, 0.7), {}, cfg)[1] is True
    assert pair_of_doors(v, (0.53, 0.7), {}, cfg)[1] is False


def test_a_pull_cut_at_the_middle_goes_to_its_half():
    from drawer_lib.articulation.decide import half_handle

    h = Handle(0.55, 0.3, "vertical", 50, "images", (0.02, 0.15))
    assert half_handle(h, "left") is None
    r = half_handle(h, "right")
    assert r.a_u == pytest.approx(0.1) and r.a_v == 0.3 and r.size == h.size and r.source == "images"
    assert half_handle(dataclasses.replace(h, a_u=0.5), "left").a_u == pytest.approx(1.0)
    assert half_handle(dataclasses.replace(h, a_u=0.0), "left").a_u == 0.0
    assert half_handle(dataclasses.replace(h, a_u=1.0), "right").a_u == pytest.approx(1.0)


@pytest.mark.parametrize("t", [0.5, 0.3, 1e-6, 1 - 1e-6])
def test_a_front_cut_across_u_keeps_its_plane_and_its_width(t):
    from drawer_lib.articulation.fronts import cut_u

    s = 1 / np.sqrt(2)
    f = Front((2.0, 1.0, 0.9), (s, -s, 0.0), (s, s, 0.0), (1.2, 0.7))
    a, b = cut_u(f, t)
    assert a.size[0] + b.size[0] == pytest.approx(1.2) and a.size[1] == b.size[1] == 0.7
    assert a.size[0] == pytest.approx(1.2 * t)
    assert a.normal == b.normal == f.normal and a.u == b.u == f.u
    # the outer corners are the front's, and the pieces meet
    assert np.allclose(a.corners()[[0, 3]], f.corners()[[0, 3]]) and np.allclose(b.corners()[[1, 2]], f.corners()[[1, 2]])
    assert np.allclose(a.corners()[[1, 2]], b.corners()[[0, 3]])
    for bad in (0.0, 1.0, -0.2, float("nan")):
        with pytest.raises(ValueError, match="cut_u"):
            cut_u(f, bad)


@pytest.mark.parametrize("key, value", [("pair_pull", -0.1), ("pair_pull", 0.5), ("pair_min_width", 0.0),
                                        ("pair_min_width", float("nan"))])
def test_the_pair_rule_keys_are_checked(key, value):
    with pytest.raises(ConfigError, match=f"articulate.types.{key}"):
        TypesConfig(**{key: value})
