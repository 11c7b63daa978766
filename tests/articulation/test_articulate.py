"""Articulation from geometry on tiny analytic fixtures: one cabinet front (outer face at
y = -0.6, facing -y) in front of a wall, with a handle box where a drawer, a left-hinged door or
a bottom-hinged flap carries it. Type, axis and limits must come out within stated tolerances."""

import dataclasses

import numpy as np
import pytest
import trimesh

from drawer_lib.articulation.config import ArticulateConfig, FrontsConfig, HandlesConfig, TypesConfig
from drawer_lib.articulation.estimators import get_estimator
from drawer_lib.articulation.fronts import edge_moves, refine_with_masks, share_edges
from drawer_lib.articulation.handles import (RUNNER_UP_NEAR, describe_handle, handle_candidates, handle_clusters,
                                             heaviest, rect_distance, resolve_split_pulls, resolve_stacked_pulls,
                                             runner_up)
from drawer_lib.articulation.infer import infer_parts
from drawer_lib.articulation.decide import decide_by_handle
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.geometry.camera import Camera, Intrinsics
from drawer_lib.perception.decompose import Segment, face_geometry

HC = HandlesConfig()

CAMS = np.array([[0.3, -2.5, 1.0], [-0.5, -2.0, 1.2], [1.0, -2.2, 0.8]])
X0, X1, Z0, Z1, Y = 0.0, 0.5, 0.1, 0.8, -0.6   # the front rectangle (m)
# the analytic front is 0.7 m tall, taller than real drawers (the score rule's `tall` feature
# makes such a front with a central pull a flap); the tests of a drawer's joint move it past it
DRAWER_TYPES = TypesConfig(drawer_max_height=0.8)


def box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))


def scene(handle: str | None):
    """(mesh, face ids of the front's outer face). ``handle``: center | right | bottom | top | None,
    or middle: a vertical bar 2 cm right of the middle (where a pair of doors meets)."""
    panel = box([X0, Y, Z0], [X1, Y + 0.019, Z1]).subdivide().subdivide().subdivide()
    wall = box([-0.5, 0.0, 0.0], [1.0, 0.02, 1.2])  # the wall behind: 0.6 m carcass depth
    parts = [panel, wall]
    hc = {"center": (0.25, 0.45, "h"), "top": (0.25, 0.74, "h"), "right": (0.455, 0.7, "v"),
          "bottom": (0.25, 0.16, "h"), "middle": (0.27, 0.45, "v")}.get(handle)
    if hc is not None:
        x, z, along = hc
        half = (0.08, 0.006) if along == "h" else (0.006, 0.08)
        parts.append(box([x - half[0], Y - 0.035, z - half[1]], [x + half[0], Y - 0.023, z + half[1]]).subdivide())
    mesh = trimesh.util.concatenate(parts)
    n = np.asarray(mesh.face_normals)
    c = np.asarray(mesh.triangles_center)
    outer = np.nonzero((n[:, 1] < -0.99) & (np.abs(c[:, 1] - Y) < 1e-6))[0]
    return mesh, outer


def segment(mesh, faces, labels=None) -> Segment:
    nrm, area, cen, frac = face_geometry(mesh, faces, 30.0)
    return Segment(0, faces, 1.0, 10, labels or {}, frac > 0.6, nrm, area, cen)


def run(handle, labels=None, cfg=ArticulateConfig(types=DRAWER_TYPES)):
    mesh, outer = scene(handle)
    return infer_parts(mesh, [segment(mesh, outer, labels)], CAMS, cfg)


def check_front(p):
    f = p.front
    assert np.allclose(f.normal, [0, -1, 0], atol=1e-6) and np.allclose(f.u, [1, 0, 0], atol=1e-6)
    assert np.allclose(f.center, [0.25, Y, 0.45], atol=0.01)  # 1 cm
    assert np.allclose(f.size, [0.5, 0.7], atol=0.02)  # 2 cm


def test_drawer_with_central_handle_pulls_out_by_the_carcass_depth():
    parts, rep = run("center")
    (p,) = parts
    assert p.kind == "prismatic" and p.extra["family"] == "drawer"
    check_front(p)
    assert np.allclose(p.axis.direction, [0, -1, 0], atol=1e-6)  # outward: positive q opens
    assert p.extra["carcass_depth"] == pytest.approx(0.6, abs=0.02)
    assert p.limits == pytest.approx((0.0, 0.8 * 0.6), abs=0.02)
    assert rep[0]["handle"]["orientation"] == "horizontal"
    # with the default types, a 0.7 m front is too tall for a drawer: its central pull makes a flap
    (q,), _ = run("center", cfg=ArticulateConfig())
    assert q.kind == "revolute" and q.extra["family"] == "flap"


def test_door_with_handle_on_the_right_is_hinged_left():
    (p,), rep = run("right")
    assert p.kind == "revolute" and p.extra["hinge"] == "left"
    check_front(p)
    assert np.allclose(p.axis.origin, [X0, Y, 0.45], atol=0.015)  # on the left edge
    assert np.allclose(p.axis.direction, [0, 0, -1], atol=1e-6)  # right-hand rule opens outward
    assert p.limits == pytest.approx((0.0, np.pi / 2))
    # opening by a small angle moves the free edge outward (toward the cameras, -y)
    from drawer_lib.geometry.joints import apply_transform, joint_transform

    free = np.array([[X1, Y, 0.45]])
    moved = apply_transform(joint_transform("revolute", np.array(p.axis.origin), np.array(p.axis.direction), 0.1), free)
    assert moved[0, 1] < Y - 0.01


def opens_outward(p) -> bool:
    """Whether opening ``p`` by a small angle moves its front's far corners toward the cameras (-y)."""
    from drawer_lib.geometry.joints import apply_transform, joint_transform

    corners = p.front.corners()
    moved = apply_transform(joint_transform("revolute", np.array(p.axis.origin), np.array(p.axis.direction), 0.1),
                            corners)
    return bool((moved[:, 1] <= corners[:, 1] + 1e-9).all() and (moved[:, 1] < Y - 0.01).any())


PAIR = ArticulateConfig(types=TypesConfig(pair_pull=0.1, pair_min_width=0.2))


def test_a_vertical_pull_at_the_middle_of_a_front_makes_a_pair_of_doors():
    """Two doors a detector joined into one front, read off the pull at its middle
    (``types.pair_pull``): each half a door hinged on its outer edge, opening outward; the pull
    goes to the half it lies on; both rows record the pair and the whole front's decision."""
    (_one,), _ = run("middle", cfg=ArticulateConfig(types=TypesConfig(pair_pull=0.0)))  # off: one front
    parts, rep = run("middle", cfg=PAIR)
    assert [p.extra["family"] for p in parts] == ["door", "door"]
    left, right = sorted(parts, key=lambda p: p.front.center[0])
    assert left.extra["hinge"] == "left" and right.extra["hinge"] == "right"
    assert np.allclose(left.axis.origin[0], X0, atol=0.015) and np.allclose(right.axis.origin[0], X1, atol=0.015)
    for p, cx in ((left, 0.125), (right, 0.375)):
        assert np.allclose(p.front.size, [0.25, 0.7], atol=0.02) and np.allclose(p.front.center[0], cx, atol=0.01)
        assert opens_outward(p)
    assert "handle" not in left.extra and right.extra["handle"]["a_u"] == pytest.approx(0.08, abs=0.03)
    rows = [r for r in rep if r.get("part")]
    assert [r["pair"]["side"] for r in rows] == ["left", "right"]
    assert all(r["pair"]["width"] == pytest.approx(0.5, abs=0.02) and not r["pair"]["near"] for r in rows)
    assert all("a pair of doors" in r["reason"] and r["low_margin"] is False for r in rows)
    assert rows[0]["features"] == rows[1]["features"]  # the whole front's evidence


@pytest.mark.parametrize("handle, types", [
    ("center", TypesConfig(pair_pull=0.1, pair_min_width=0.2)),    # a horizontal bar there is a drawer's or a flap's
    ("right", TypesConfig(pair_pull=0.1, pair_min_width=0.2)),     # a pull at an edge is one door's
    ("middle", TypesConfig(pair_pull=0.1, pair_min_width=0.3)),    # too narrow for two doors
    ("middle", TypesConfig(pair_pull=0.01, pair_min_width=0.2)),   # the pull is 0.04 of the width off the middle
    ("middle", TypesConfig(pair_pull=0.1, pair_min_width=0.2, hinged_min_height=0.8)),  # no room for hinges
])
def test_a_front_stays_one_unless_its_pull_says_pair(handle, types):
    parts, rep = run(handle, cfg=ArticulateConfig(types=types))
    assert len(parts) == 1 and not any("pair" in r for r in rep)


def test_a_pair_decided_near_its_bounds_is_marked():
    """A width within 2 cm of 2 x ``pair_min_width`` could be decided otherwise elsewhere: low_margin."""
    parts, rep = run("middle", cfg=ArticulateConfig(types=TypesConfig(pair_pull=0.1, pair_min_width=0.245)))
    assert len(parts) == 2 and all(p.extra["low_margin"] for p in parts)
    assert all(r["pair"]["near"] and r["low_margin"] for r in rep if r.get("part"))


def test_flap_with_handle_at_the_bottom_is_hinged_at_the_top():
    (p,), _ = run("bottom")
    assert p.kind == "revolute" and p.extra["hinge"] == "top"
    assert np.allclose(p.axis.origin, [0.25, Y, Z1], atol=0.015)
    assert np.allclose(p.axis.direction, [-1, 0, 0], atol=1e-6)


def test_handle_rule_top_handle_is_a_drawer_unless_the_labels_say_door():
    """The earlier rule (``types.rule: handle``), kept for comparison."""
    rule = ArticulateConfig(types=TypesConfig(rule="handle"))
    (p,), _ = run("top", cfg=rule)
    assert p.extra["family"] == "drawer"
    (p,), _ = run("top", labels={"door": 9, "drawer": 2}, cfg=rule)
    assert p.extra["family"] == "flap" and p.extra["hinge"] == "bottom"
    (p,), _ = run("top", labels={"door": 9}, cfg=ArticulateConfig(types=TypesConfig(rule="handle", use_labels=False)))
    assert p.extra["family"] == "drawer"  # labels are hints only, and can be switched off


def test_a_front_without_a_handle_narrower_than_a_filler_is_fixed():
    """``types.filler_width``: a handle-less front narrower than it is a fixed panel (a filler
    or a sliver), with the reason; one with a handle, a wider one, or the rule off: typed."""
    wide = dataclasses.replace(DRAWER_TYPES, filler_width=0.55)  # the analytic front is 0.5 m wide
    parts, rep = run(None, cfg=ArticulateConfig(types=wide))
    assert parts == [] and rep[0]["family"] == "fixed" and "filler" in rep[0]["reason"]
    (p,), _ = run("center", cfg=ArticulateConfig(types=wide))
    assert p.extra["family"] == "drawer"
    for types in (dataclasses.replace(DRAWER_TYPES, filler_width=0.45), dataclasses.replace(DRAWER_TYPES, filler_width=None)):
        (p,), rep = run(None, cfg=ArticulateConfig(types=types))
        assert rep[0]["family"] == "door"
    with pytest.raises(ConfigError, match="filler_width = -0.1"):
        TypesConfig(filler_width=-0.1)


def test_a_lone_front_without_a_handle_is_a_door_and_degenerate_segments_are_reported():
    """A lone front without a handle that can swing is a push-to-open door; which edge it
    hinges on is a guess (both sides score alike), so the decision is flagged. Without the
    prior's ``bare_lone`` weight it is a fixed panel."""
    (p,), rep = run(None)
    assert p.kind == "revolute" and rep[0]["family"] == "door" and rep[0]["low_margin"]
    assert rep[0]["features"]["bare_lone"] == 1.0
    door = {k: v for k, v in DRAWER_TYPES.prior["door"].items() if k != "bare_lone"}
    types = dataclasses.replace(DRAWER_TYPES, prior={**DRAWER_TYPES.prior, "door": door})
    parts, rep = run(None, cfg=ArticulateConfig(types=types))
    assert parts == [] and rep[0]["family"] == "fixed"
    mesh, outer = scene("center")
    one = segment(mesh, outer[:1])
    parts, rep = infer_parts(mesh, [one], CAMS, ArticulateConfig())
    assert parts == [] and "size" in rep[0]["reason"]  # a single face is far below min_size
    # a horizontal panel (a counter top) is not a front
    top = np.nonzero(np.asarray(mesh.face_normals)[:, 2] > 0.99)[0]
    parts, rep = infer_parts(mesh, [segment(mesh, top)], CAMS, ArticulateConfig())
    assert parts == [] and rep[0]["reason"] == "not vertical"


def test_handles_between_two_fronts_go_to_the_one_they_reach_into():
    from drawer_lib.io.parts import Front

    upper = Front((0.25, Y, 0.6), (0, -1, 0), (1, 0, 0), (0.5, 0.2))
    lower = Front((0.25, Y, 0.38), (0, -1, 0), (1, 0, 0), (0.5, 0.25))  # 2.5 cm too tall: overlaps upper
    g = np.random.default_rng(0)
    own_upper = np.array([0.25, Y - 0.01, 0.6]) + g.normal(0, 0.003, (20, 3))
    edge_pull_lower = np.array([0.25, Y - 0.01, 0.475]) + g.normal(0, 0.003, (20, 3))  # at lower's top edge
    pts = np.concatenate([own_upper, edge_pull_lower])
    assert len(handle_clusters(pts, 0.015, 6)) == 2
    got = heaviest(handle_candidates([upper, lower], pts, HC, 0.015, 6))
    assert np.allclose(got[0].mean(0), own_upper.mean(0)) and np.allclose(got[1].mean(0), edge_pull_lower.mean(0))


def test_mask_fringe_on_a_neighbour_weighs_less_than_the_fronts_own_pull():
    """Two doors side by side (3 mm gap at x = 0.5). The left door's own pull sits at its left
    edge (masks hold it in 60 % of the views); the right door's pull, at its own left edge, is
    smeared by ragged masks onto the left door's right edge: more faces there, each held in only
    15 % of the views. By count the left door would take the fringe (hinge on the wrong side);
    weighted by the rate the masks hold each face, it keeps its own pull."""
    from drawer_lib.io.parts import Front

    left = Front((0.2485, Y, 0.45), (0, -1, 0), (1, 0, 0), (0.497, 0.7))
    right = Front((0.7515, Y, 0.45), (0, -1, 0), (1, 0, 0), (0.497, 0.7))
    g = np.random.default_rng(1)

    def strip(x0, x1, n):  # a vertical strip of face centroids on the front plane
        return np.stack([g.uniform(x0, x1, n), np.full(n, Y - 0.005), g.uniform(0.55, 0.7, n)], -1)

    own = strip(0.005, 0.03, 40)
    fringe = strip(0.47, 0.498, 60)
    other = strip(0.503, 0.53, 50)  # the right door's pull on its own side
    pts = np.concatenate([own, fringe, other])
    w = np.concatenate([np.full(40, 0.6), np.full(60, 0.15), np.full(50, 0.6)])
    by_count = heaviest(handle_candidates([left, right], pts, HC, 0.015, 3))
    by_rate = heaviest(handle_candidates([left, right], pts, HC, 0.015, 3, weights=w))
    assert by_count[0].mean(0)[0] > 0.45  # the trap the weights avoid
    assert by_rate[0].mean(0)[0] < 0.05 and by_rate[1].mean(0)[0] > 0.5
    h = describe_handle(left, by_rate[0], "masks", HC)
    assert h.a_u < 0.1 and decide_by_handle(h, {}, TypesConfig()).hinge == "right"
    with pytest.raises(ValueError, match="weights"):
        handle_candidates([left, right], pts, HC, 0.015, 3, weights=-w)
    with pytest.raises(ConfigError, match="evidence"):
        HandlesConfig(evidence="votes")


def test_a_pull_between_stacked_fronts_goes_to_the_lower_one():
    # two stacked drawers (z 0.25-0.50 and 0.503-0.70), each with a lip pull on its top edge; the
    # lower one's pull, smeared by ragged masks, reaches over the gap onto the upper front, where
    # it outweighs the upper front's own pull
    from drawer_lib.io.parts import Front

    upper = Front((0.25, Y, 0.6015), (0, -1, 0), (1, 0, 0), (0.5, 0.197))
    lower = Front((0.25, Y, 0.375), (0, -1, 0), (1, 0, 0), (0.5, 0.25))
    g = np.random.default_rng(0)

    def bar(z0, z1, n):  # a horizontal bar of face centroids 3 cm in front of the plane
        return np.stack([g.uniform(0.15, 0.35, n), np.full(n, Y - 0.03), g.uniform(z0, z1, n)], -1)

    own_upper = bar(0.685, 0.698, 30)
    smear = bar(0.505, 0.53, 75)  # on the upper front, above the gap
    own_lower = bar(0.47, 0.497, 30)  # the lower front's pull below the gap
    pts = np.concatenate([own_upper, smear, own_lower])
    cfg, tc = HC, TypesConfig()
    R = 0.04  # the linkage radius infer_parts uses on a mesh of ~3 cm faces (1.5 x the spacing)
    cands = handle_candidates([upper, lower], pts, cfg, R, 3)
    assert cands[0][0][1] == 75  # the smear is the upper front's heaviest candidate: a "flap"
    assert decide_by_handle(describe_handle(upper, cands[0][0][0], "masks", cfg), {}, tc).family == "flap"
    got, gave_up = resolve_stacked_pulls([upper, lower], cands, tc.edge_frac, cfg.max_gap)
    assert gave_up == [(0, 1)]
    assert decide_by_handle(describe_handle(upper, got[0], "masks", cfg), {}, tc).family == "drawer"
    assert decide_by_handle(describe_handle(lower, got[1], "masks", cfg), {}, tc).family == "drawer"
    # side by side (no stack), or the upper front with no other candidate: nothing changes
    side = Front((0.75, Y, 0.375), (0, -1, 0), (1, 0, 0), (0.5, 0.25))
    sc = handle_candidates([upper, side], pts, cfg, R, 3)
    got, gave_up = resolve_stacked_pulls([upper, side], sc, tc.edge_frac, cfg.max_gap)
    assert gave_up == [] and got[0] is sc[0][0][0]
    # a third drawer on top whose choice is the smear of the middle one's pull: once the middle
    # front has given up the lower one's pull for its own, the top one gives that up in turn
    top = Front((0.25, Y, 0.8045), (0, -1, 0), (1, 0, 0), (0.5, 0.203))
    three = np.concatenate([bar(0.89, 0.9, 25), bar(0.706, 0.73, 60), own_upper, smear, own_lower])
    c3 = handle_candidates([top, upper, lower], three, cfg, R, 3)
    got, gave_up = resolve_stacked_pulls([top, upper, lower], c3, tc.edge_frac, cfg.max_gap)
    assert sorted(gave_up) == [(0, 1), (1, 2)]
    fam = [decide_by_handle(describe_handle(f, p, "masks", cfg), {}, tc).family for f, p in zip([top, upper, lower], got)]
    assert fam == ["drawer"] * 3, fam
    # vertical bars either side of the gap (a tall door over a door) are two handles
    vbar = lambda z0, z1, n: np.stack([g.uniform(0.46, 0.47, n), np.full(n, Y - 0.03), g.uniform(z0, z1, n)], -1)  # noqa: E731
    vc = handle_candidates([upper, lower], np.concatenate([own_upper, vbar(0.505, 0.56, 75), vbar(0.44, 0.497, 30)]),
                           cfg, R, 3)
    got, gave_up = resolve_stacked_pulls([upper, lower], vc, tc.edge_frac, cfg.max_gap)
    assert gave_up == [] and got[0] is vc[0][0][0]
    lone = handle_candidates([upper, lower], np.concatenate([smear, own_lower]), cfg, R, 3)
    got, gave_up = resolve_stacked_pulls([upper, lower], lone, tc.edge_frac, cfg.max_gap)
    assert gave_up == [] and got[0] is lone[0][0][0]


def test_rect_distance_is_signed_and_exact_on_a_rectangle():
    from drawer_lib.io.parts import Front

    f = Front((0.0, 0.0, 1.0), (0, -1, 0), (1, 0, 0), (0.4, 0.2))  # x -0.2..0.2, z 0.9..1.1
    pts = np.array([[0, 0, 1.0], [0.15, 0, 1.0], [0.3, 0, 1.0], [0.3, 0, 1.2], [0.2, 0, 1.1], [0, -0.5, 0.95]])
    np.testing.assert_allclose(rect_distance(f, pts), [-0.1, -0.05, 0.1, np.hypot(0.1, 0.1), 0.0, -0.05], atol=1e-12)


def test_a_pull_split_between_side_by_side_fronts_goes_whole_to_the_front_it_reaches_into():
    """A vertical bar by the left edge of the right front (a sliding panel's pull beside a flap)
    is read on both fronts' rectified masks; the cells in the gap and the left front's margin go
    to the left front, which then holds "a vertical bar at its very right edge" (a door hinged
    left). The pull reaches 2.5 cm into the right front and not into the left one: it goes to
    the right front whole. Two knobs either side of a gap reach as far into each: both stay."""
    from drawer_lib.io.parts import Front

    left = Front((0.25, Y, 0.45), (0, -1, 0), (1, 0, 0), (0.5, 0.7))    # x 0.00-0.50
    right = Front((0.735, Y, 0.45), (0, -1, 0), (1, 0, 0), (0.45, 0.7))  # x 0.51-0.96
    def bar(x0, x1, z0, z1):  # rectified cells (4 mm) 2 cm in front of the plane
        x, z = np.meshgrid(np.arange(x0, x1, 0.004), np.arange(z0, z1, 0.004))
        return np.stack([x.ravel(), np.full(x.size, Y - 0.02), z.ravel()], -1)

    pull = bar(0.4965, 0.535, 0.12, 0.3)
    R = 0.006  # the linkage of rectified cells (1.5 x 4 mm)
    cands = handle_candidates([left, right], pull, HC, R, 3)
    assert cands[0] and cands[1]  # split at the gap's middle
    h_left = describe_handle(left, heaviest(cands)[0], "images", HC)
    assert h_left.a_u > 0.95 and h_left.orientation == "vertical"  # the left front's "own" bar at its edge
    out, moves = resolve_split_pulls([left, right], cands, HC.max_gap, HC.split_margin)
    assert out[0] == [] and len(out[1]) == 1 and len(out[1][0][0]) == len(pull)
    assert [(a, b) for a, b, _ in moves] == [(0, 1)] and moves[0][2] >= HC.split_margin
    assert describe_handle(right, out[1][0][0], "images", HC).a_u < 0.1
    # with a margin above the reach difference nothing moves
    same, none = resolve_split_pulls([left, right], cands, HC.max_gap, 0.05)
    assert none == [] and [len(c) for c in same] == [len(c) for c in cands]
    # two knobs 3 cm apart across the gap, 2 cm into each front: each keeps its own
    knobs = np.concatenate([bar(0.47, 0.49, 0.4, 0.42), bar(0.52, 0.54, 0.4, 0.42)])
    kc = handle_candidates([left, right], knobs, HC, 0.015, 3)
    out, moves = resolve_split_pulls([left, right], kc, HC.max_gap, HC.split_margin)
    assert moves == [] and [len(c) for c in out] == [1, 1]
    # the same case through front_handles: the left front has no handle, the right one the bar
    from drawer_lib.articulation.handles import front_handles

    hs, gave = front_handles([left, right], np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), 0.02, HC,
                             0.3, 0.03, image_cells=(pull, np.full(len(pull), 0.5), R, 3))
    assert hs[0] is None and hs[1].a_u < 0.1 and [(a, b) for a, b, _ in gave] == [(0, 1)]
    assert "deeper" in gave[0][2].format(7) and "segment 7" in gave[0][2].format(7)


def test_a_second_pull_nearly_as_heavy_elsewhere_on_the_front_is_listed():
    """``runner_up``: the candidate after the chosen one, listed when it weighs at least
    RUNNER_UP_NEAR of it and lies more than a quarter of the front away (another hinge side);
    a lighter one, or a piece of the same pull, is not."""
    from drawer_lib.io.parts import Front

    f = Front((0.25, Y, 0.45), (0, -1, 0), (1, 0, 0), (0.5, 0.7))  # x 0.00-0.50
    right_bar = np.array([[0.46, Y - 0.02, z] for z in np.linspace(0.4, 0.55, 10)])
    left_bar = right_bar * [0, 1, 1] + [0.04, 0, 0]
    near_piece = right_bar + [0, 0, 0.1]  # the same edge, 10 cm higher: 0.14 of the height away
    for other, w, want in ((left_bar, RUNNER_UP_NEAR + 0.05, True), (left_bar, RUNNER_UP_NEAR - 0.05, False),
                           (near_piece, 0.95, False)):
        cands = [(right_bar, 1.0), (other, w)]
        r = runner_up(f, cands, right_bar)
        assert (r is not None) == want
        if want:
            assert r == {"ratio": pytest.approx(w, abs=1e-3), "a_u": 0.08, "a_v": pytest.approx(0.536, abs=1e-3)}
    assert runner_up(f, [(right_bar, 1.0)], right_bar) is None  # no second candidate
    assert runner_up(f, [(left_bar, 1.0), (right_bar, 0.9)], right_bar) is None  # the last one was chosen
    assert runner_up(f, [(right_bar, 1.0), (left_bar, 0.9)], None) is None


@pytest.mark.parametrize("left_hits, near", [(7, True), (4, False)])
def test_a_front_whose_pull_was_chosen_over_one_nearly_as_heavy_is_marked_low_margin(left_hits, near):
    """Two vertical bars, at the right edge (in 8 of 10 views' handle masks) and at the left
    edge (in 7, or 4): the right one is the pull (hinged left) either way; with 7 the choice
    had no margin (7/8 of the weight), and the front is listed ``near_handle`` and flagged."""
    panel = box([X0, Y, Z0], [X1, Y + 0.019, Z1]).subdivide().subdivide().subdivide()
    wall = box([-0.5, 0.0, 0.0], [1.0, 0.02, 1.2])
    bars = [box([x - 0.006, Y - 0.035, 0.62], [x + 0.006, Y - 0.023, 0.78]).subdivide().subdivide().subdivide()
            for x in (0.455, 0.045)]  # fine enough that each bar's faces are one cluster
    mesh = trimesh.util.concatenate([panel, wall, *bars])
    n, fc = np.asarray(mesh.face_normals), np.asarray(mesh.triangles_center)
    outer = np.nonzero((n[:, 1] < -0.99) & (np.abs(fc[:, 1] - Y) < 1e-6))[0]
    proud = fc[:, 1] < Y - 0.02
    hits = np.where(proud & (fc[:, 0] > 0.25), 8, np.where(proud, left_hits, 0))
    parts, rep = infer_parts(mesh, [segment(mesh, outer)], CAMS, ArticulateConfig(), hits,
                             face_views=np.full(len(fc), 10))
    (p,), row = parts, next(r for r in rep if r.get("part") == parts[0].id)
    assert p.kind == "revolute" and p.extra["hinge"] == "left"
    assert ("near_handle" in row) == near and (not near or row["low_margin"] and p.extra["low_margin"])
    if near:
        assert row["near_handle"]["ratio"] == pytest.approx(7 / 8, abs=0.02) and row["near_handle"]["a_u"] < 0.2


def test_view_rate_evidence_needs_the_views_and_matches_count_on_a_clean_handle():
    mesh, outer = scene("right")
    seg = segment(mesh, outer)
    fc = np.asarray(mesh.triangles_center)
    # "handle" masks cover the handle box's faces in 8 of 10 views
    hits = np.where(fc[:, 1] < Y - 0.02, 8, 0)
    views = np.full(len(fc), 10)
    count = ArticulateConfig(handles=HandlesConfig(evidence="count"))
    by_count, _ = infer_parts(mesh, [seg], CAMS, count, hits)
    by_rate, _ = infer_parts(mesh, [seg], CAMS, ArticulateConfig(), hits, face_views=views)
    assert by_count[0].extra["hinge"] == by_rate[0].extra["hinge"] == "left"
    with pytest.raises(InputError, match="face_views"):
        infer_parts(mesh, [seg], CAMS, ArticulateConfig(), hits)


def test_rectangle_from_masks_ignores_sides_cut_by_the_image_border():
    from drawer_lib.io.parts import Front

    # camera at y = -2 looking +y (OpenCV: x right, y down, z forward)
    w2c = np.array([[1, 0, 0, 0], [0, 0, -1, 0.45], [0, 1, 0, 2.0], [0, 0, 0, 1]], float)
    K = (200.0, 200.0, 100.0, 100.0)
    H = W = 200
    cam = Camera(Intrinsics(*K, W, H), w2c)
    yy, xx = np.mgrid[0:H, 0:W]

    def mask(x0, x1, z0, z1):  # the rectangle's image, pixels whose centres fall inside
        X = (xx + 0.5 - K[2]) / K[0] * 1.4  # depth to the plane: 2 - 0.6 = 1.4 m
        Z = 0.45 - (yy + 0.5 - K[3]) / K[1] * 1.4
        return (X >= x0) & (X <= x1) & (Z >= z0) & (Z <= z1)

    rough = Front((0.0, Y, 0.45), (0, -1, 0), (1, 0, 0), (0.4, 0.5))
    full = [(mask(-0.25, 0.25, 0.1, 0.8), cam)] * 3
    f, used = refine_with_masks(rough, full, FrontsConfig())
    assert used == 3 and np.allclose(f.size, [0.5, 0.7], atol=0.01) and np.allclose(f.center, [0, Y, 0.45], atol=0.005)
    f2, _ = refine_with_masks(rough, [(mask(-0.25, 2.0, 0.1, 0.8), cam)] * 3, FrontsConfig())  # off the right border
    assert f2.size[0] == pytest.approx(0.25 + 0.2, abs=0.01)  # left edge from the masks, right edge kept


def test_abutting_fronts_share_one_boundary():
    """Two doors side by side whose masks put the shared edge at x = 0.49 and 0.51 (truth 0.50)
    both end at 0.50; a drawer stacked on the right door shares its bottom edge likewise; a
    front a track (10 mm) behind (a sliding pair) and one 5 cm away keep their edges."""
    from drawer_lib.io.parts import Front

    def front(x0, x1, z0, z1, y=Y):
        return Front(((x0 + x1) / 2, y, (z0 + z1) / 2), (0, -1, 0), (1, 0, 0), (x1 - x0, z1 - z0))

    def edges(f):
        return (f.center[0] - f.size[0] / 2, f.center[0] + f.size[0] / 2, f.center[2] - f.size[1] / 2,
                f.center[2] + f.size[1] / 2)

    a, b = front(0.0, 0.49, 0.1, 0.8), front(0.51, 1.0, 0.1, 0.6)
    top = front(0.51, 1.0, 0.612, 0.8)  # the gap above b: 12 mm, truth at 0.606
    slide = front(1.005, 1.5, 0.1, 0.8, y=Y - 0.010)
    far = front(-0.55, -0.05, 0.1, 0.8)
    got = share_edges([a, b, top, slide, far], max_gap=0.025, plane_tol=0.006)
    ea, eb, et, es, ef = (edges(f) for f in got)
    assert ea[1] == pytest.approx(0.50) and eb[0] == pytest.approx(0.50)
    assert eb[3] == pytest.approx(0.606) and et[2] == pytest.approx(0.606)
    assert et[0] == pytest.approx(0.50)  # the drawer's left edge also abuts the left door
    assert eb[1] == pytest.approx(1.0) and es == pytest.approx(edges(slide)) and ef == pytest.approx(edges(far))
    assert ea[0] == pytest.approx(0.0) and ea[2:] == pytest.approx((0.1, 0.8))
    assert share_edges([a, b], max_gap=0.0) == [a, b]  # off
    with pytest.raises(ConfigError, match="shared_edge_gap"):
        FrontsConfig(shared_edge_gap=-0.01)


def test_coplanar_fronts_that_run_into_each_other_share_one_edge_where_their_surfaces_part():
    """Masks that spill onto the neighbour put a door over 0.404..0.696 m and the front below it
    over 0.109..0.461 m: 57 mm of one plane claimed twice, so the door cannot swing past the
    front below. Within ``max_cross`` (0.3 x the shorter height, 88 mm) both end at the
    overlap's middle, 0.4325, or, given each front's surface points, where the two surfaces
    part (0.404, the lower front's masks having spilt); without it, or past it, or a track
    apart, nothing moves; a rectangle over most of another (a repeat, not a neighbour) is never
    cut."""
    from drawer_lib.io.parts import Front

    def front(x0, x1, z0, z1, y=Y):
        return Front(((x0 + x1) / 2, y, (z0 + z1) / 2), (0, -1, 0), (1, 0, 0), (x1 - x0, z1 - z0))

    def z_edges(f):
        return (f.center[2] - f.size[1] / 2, f.center[2] + f.size[1] / 2)

    upper, lower = front(0.58, 1.03, 0.404, 0.696), front(0.60, 1.02, 0.109, 0.461)
    up, lo = share_edges([upper, lower], max_gap=0.025, plane_tol=0.006, max_cross=0.3)
    assert z_edges(up) == pytest.approx((0.4325, 0.696)) and z_edges(lo) == pytest.approx((0.109, 0.4325))
    assert up.size[0] == pytest.approx(upper.size[0]) and lo.size[0] == pytest.approx(lower.size[0])
    assert edge_moves(upper, up) == pytest.approx({"left": 0, "right": 0, "bottom": 0.0285, "top": 0}, abs=1e-9)
    assert edge_moves(lower, lo) == pytest.approx({"left": 0, "right": 0, "bottom": 0, "top": 0.0285}, abs=1e-9)
    assert share_edges([upper, lower], max_gap=0.025, plane_tol=0.006) == [upper, lower]  # max_cross = 0
    # the lower front's masks spilt: its surface ends at 0.404, where the upper one's begins
    rng = np.random.default_rng(0)

    def surface(x0, x1, z0, z1, n=400):
        return np.stack([rng.uniform(x0, x1, n), np.full(n, Y), rng.uniform(z0, z1, n)], -1)

    pts = [surface(0.58, 1.03, 0.404, 0.696), surface(0.60, 1.02, 0.109, 0.404)]
    up, lo = share_edges([upper, lower], max_gap=0.025, plane_tol=0.006, max_cross=0.3, points=pts)
    assert z_edges(up)[0] == pytest.approx(0.404, abs=0.004) and z_edges(lo)[1] == pytest.approx(z_edges(up)[0])
    up2, lo2 = share_edges([upper, lower], max_gap=0.025, plane_tol=0.006, max_cross=0.3, points=[pts[0], None])
    assert z_edges(up2)[0] == pytest.approx(0.4325)  # one without points: the overlap's middle
    a, b = front(0.0, 0.49, 0.1, 0.8), front(0.51, 1.0, 0.1, 0.8)  # a gap: the masks' midpoint, points or not
    ga, gb = share_edges([a, b], max_gap=0.025, plane_tol=0.006, max_cross=0.3,
                         points=[surface(0.0, 0.45, 0.1, 0.8), surface(0.55, 1.0, 0.1, 0.8)])
    assert ga.center[0] + ga.size[0] / 2 == pytest.approx(0.50) and gb.center[0] - gb.size[0] / 2 == pytest.approx(0.50)
    deep = front(0.60, 1.02, 0.109, 0.50)  # 96 mm into a 292 mm door: past 0.3 of it
    assert share_edges([upper, deep], max_gap=0.025, plane_tol=0.006, max_cross=0.3) == [upper, deep]
    behind = front(0.60, 1.02, 0.109, 0.461, y=Y - 0.010)  # a sliding panel on the track behind
    assert share_edges([upper, behind], max_gap=0.025, plane_tol=0.006, max_cross=0.3) == [upper, behind]
    inside = front(0.62, 1.0, 0.43, 0.69)  # a drawer found inside a door's rectangle
    assert share_edges([upper, inside], max_gap=0.025, plane_tol=0.006, max_cross=0.45) == [upper, inside]
    with pytest.raises(ConfigError, match="shared_edge_cross"):
        FrontsConfig(shared_edge_cross=0.5)


def test_a_front_found_again_inside_a_larger_one_is_dropped_and_reported():
    """A 0.11 m drawer's rectangle inside a 0.25 m drawer's (the same front found twice, from
    masks over part of it): the smaller goes, whichever order the fits come in, and the report
    names the front it repeats with the share inside (and, for a piece of a cut segment, which
    piece). A neighbour that runs 0.3 into it, a panel a track behind and a smaller front beside
    it keep every front; the config takes 0 (off) or a share above one half."""
    from drawer_lib.articulation.fronts import share_inside
    from drawer_lib.articulation.infer import drop_fronts_inside
    from drawer_lib.io.parts import Front

    def front(x0, x1, z0, z1, y=Y):
        return Front(((x0 + x1) / 2, y, (z0 + z1) / 2), (0, -1, 0), (1, 0, 0), (x1 - x0, z1 - z0))

    def seg(i):
        return Segment(i, np.zeros(0, np.int64), 1.0, 5, {}, True, np.zeros(3), 0.0, np.zeros(3))

    whole, again = front(0.0, 0.40, 0.50, 0.75), front(0.005, 0.405, 0.60, 0.71)
    assert share_inside(whole, again, 0.006) == pytest.approx(0.395 / 0.40)
    assert share_inside(again, whole, 0.006) == pytest.approx(0.395 * 0.11 / (0.40 * 0.25))
    for fits in ([(seg(0), whole, {}), (seg(1), again, {})], [(seg(1), again, {}), (seg(0), whole, {})]):
        report = []
        kept = drop_fronts_inside(fits, 0.8, 0.006, 10.0, report)
        assert [s.id for s, _, _ in kept] == [0]
        assert report == [{"segment": 1, "family": "none", "reason": "lies 99% inside the front of segment 0: that "
                           "front found again", "inside": pytest.approx(0.9875), "repeats": 0}]
    below = front(0.0, 0.40, 0.30, 0.575)  # runs 7.5 cm into it: 0.27 of its area, a neighbour
    behind = front(0.005, 0.405, 0.60, 0.71, y=Y - 0.010)  # a sliding panel on the track behind
    beside = front(0.41, 0.61, 0.60, 0.71)
    for other in (below, behind, beside):
        fits = [(seg(0), whole, {}), (seg(1), other, {})]
        assert drop_fronts_inside(fits, 0.8, 0.006, 10.0, []) == fits
    report = []  # a piece of a cut segment says which
    drop_fronts_inside([(seg(0), whole, {}), (seg(1), again, {"piece": 1, "of": 2})], 0.8, 0.006, 10.0, report)
    assert (report[0]["piece"], report[0]["of"], report[0]["repeats"]) == (1, 2, 0)
    with pytest.raises(ConfigError, match="repeat_inside"):
        FrontsConfig(repeat_inside=0.5)
    assert FrontsConfig(repeat_inside=0).repeat_inside == 0


def test_learned_estimator_slots_say_why_they_cannot_run():
    assert get_estimator("geometric") is infer_parts
    with pytest.raises(ConfigError, match="weights"):
        get_estimator("3doi")
    with pytest.raises(ConfigError, match="unknown"):
        get_estimator("nope")
    with pytest.raises(ConfigError):
        TypesConfig(edge_frac=0.7)


def test_carcass_depth_ignores_fronts_above_that_face_the_same_way():
    """A wall cabinet's front above and 0.25 m behind a base front faces like it, but it is not
    the carcass behind it: the depth stays the wall's 0.6 m (it was 0.25 before)."""
    from drawer_lib.articulation.config import JointsConfig
    from drawer_lib.articulation.probes import carcass_depth
    from drawer_lib.io.parts import Front

    wall_cab = box([X0, Y + 0.25, 1.45], [X1, Y + 0.27, 2.15]).subdivide().subdivide()
    mesh = trimesh.util.concatenate([box([-0.5, 0.0, 0.0], [1.0, 0.02, 2.4]), wall_cab])
    pts, idx = trimesh.sample.sample_surface_even(mesh, 20000, seed=0)
    nrm = np.asarray(mesh.face_normals)[idx]
    front = Front((0.25, Y, 0.45), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.5, 0.7))
    assert carcass_depth(front, np.asarray(pts), nrm, JointsConfig()) == pytest.approx(0.6, abs=0.01)
    high = Front((0.25, Y, 1.8), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.5, 0.7))  # level with the wall cabinet
    assert carcass_depth(high, np.asarray(pts), nrm, JointsConfig()) == pytest.approx(0.25, abs=0.01)


def tilted_run(handle: str, deg: float, cfg=ArticulateConfig(types=DRAWER_TYPES)):
    """The scene pitched by ``deg`` about the x axis through the front's centre (its normal
    tilts up or down by ``deg``, as a plane fitted to a noisy mesh does)."""
    mesh, outer = scene(handle)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.deg2rad(deg), [1, 0, 0], [0.25, Y, 0.45]))
    return infer_parts(mesh, [segment(mesh, outer)], CAMS, cfg)


@pytest.mark.parametrize("deg", [-4.0, 2.0, 9.0])
def test_gravity_prior_levels_a_drawer_and_plumbs_a_door_hinge(deg):
    (p,), rep = tilted_run("center", deg)
    assert p.extra["family"] == "drawer"
    assert np.allclose(p.axis.direction, [0, -1, 0], atol=1e-9)  # level: gravity cannot roll it open
    assert rep[0]["tilt_deg"] == pytest.approx(abs(deg), abs=0.05) and rep[0]["plumbed"]
    (d,), _ = tilted_run("right", deg)
    assert d.extra["hinge"] == "left" and np.allclose(d.axis.direction, [0, 0, -1], atol=1e-9)
    # off: the axis keeps the fitted tilt
    off = ArticulateConfig(fronts=FrontsConfig(plumb_deg=0.0), types=DRAWER_TYPES)
    (q,), rep = tilted_run("center", deg, off)
    assert np.degrees(np.arcsin(abs(q.axis.direction[2]))) == pytest.approx(abs(deg), abs=0.05)
    assert not rep[0]["plumbed"]


def test_a_front_tilted_past_the_prior_keeps_its_plane():
    cfg = ArticulateConfig(fronts=FrontsConfig(plumb_deg=5.0), types=DRAWER_TYPES)
    (p,), rep = tilted_run("center", 8.0, cfg)
    assert rep[0]["tilt_deg"] == pytest.approx(8.0, abs=0.05) and not rep[0]["plumbed"]
    assert np.degrees(np.arcsin(abs(p.axis.direction[2]))) == pytest.approx(8.0, abs=0.05)
    with pytest.raises(ConfigError, match="plumb_deg"):
        FrontsConfig(plumb_deg=30.0)
