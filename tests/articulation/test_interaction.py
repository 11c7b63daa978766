"""The interaction test (drawer_lib/articulation/interaction.py) on analytic scenes: a free
front opens every way; a wall in front blocks a door's swing and a drawer's travel where the
geometry says; an obstacle by one edge blocks only the door hinged on the other side; a surface
behind leaves no room for a drawer; the front's own panel and handle are not obstacles; and
the score rule drops what the test blocks."""

import numpy as np
import pytest

from drawer_lib.articulation.config import InteractionConfig, JointsConfig, TypesConfig
from drawer_lib.articulation.decide import decide_by_score
from drawer_lib.articulation.interaction import (
    Obstacles,
    blocked_hypotheses,
    interaction_evidence,
    panel_samples,
    room_behind,
    sweep_clear,
    sweep_reach,
)
from drawer_lib.articulation.scoring import Evidence
from drawer_lib.articulation.vocab import Handle
from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Front

# a 0.6 x 0.7 m front facing -y, centre 0.5 m up; u = +x, v = n x u = +z
FRONT = Front((0.0, 0.0, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.6, 0.7))
CFG = InteractionConfig()
JOINTS = JointsConfig()


def _plane(center, a, b, half_a, half_b, spacing=0.01):
    """Points on the rectangle centre +- half_a along a, +- half_b along b."""
    s, t = np.meshgrid(np.arange(-half_a, half_a + 1e-9, spacing), np.arange(-half_b, half_b + 1e-9, spacing))
    return np.asarray(center) + s.ravel()[:, None] * np.asarray(a) + t.ravel()[:, None] * np.asarray(b)


def _own():
    """The front's own panel and a bar handle 3 cm proud of it."""
    panel = _plane((0.0, 0.0, 0.5), (1, 0, 0), (0, 0, 1), 0.3, 0.35)
    bar = _plane((0.0, -0.03, 0.78), (1, 0, 0), (0, 0, 1), 0.15, 0.01, 0.005)
    return np.concatenate([panel, bar])


def _far():
    """A wall 3 m away: something to build a tree on."""
    return _plane((0.0, -3.0, 0.5), (1, 0, 0), (0, 0, 1), 0.5, 0.5, 0.05)


def test_a_free_front_opens_every_way_and_its_own_surface_is_no_obstacle():
    obs = Obstacles.of(np.concatenate([_own(), _far()]))
    ev = interaction_evidence(FRONT, obs, JOINTS, CFG)
    assert ev["clear"] == {h: 1.0 for h in ("drawer", "door_left", "door_right", "flap_top", "flap_bottom")}
    assert ev["room"] == pytest.approx(CFG.room_probe)
    assert blocked_hypotheses(ev, CFG) == {}


def test_a_wall_in_front_blocks_the_swing_and_the_travel_where_geometry_says():
    gap = 0.2  # a wall 20 cm in front of the front, facing it
    wall = _plane((0.0, -gap, 0.5), (1, 0, 0), (0, 0, 1), 1.0, 1.0)
    obs = Obstacles.of(np.concatenate([_own(), wall]))
    # a door: the free edge (inset) at radius r reaches the wall at asin((gap - clearance) / r)
    r = FRONT.size[0] - CFG.inset
    expect = np.degrees(np.arcsin((gap - CFG.clearance) / r)) / JOINTS.revolute_limit_deg
    got = sweep_clear(FRONT, "door_left", obs, JOINTS, CFG)
    step = CFG.step / FRONT.size[1] * 2  # one motion sample (the farthest point moves <= step)
    assert expect - step <= got <= expect + 1e-9
    # a drawer travelling 0.4 m (no carcass: 0.8 x 0.5): the face reaches the wall at gap - clearance
    travel = JOINTS.drawer_travel * JOINTS.default_depth
    got = sweep_clear(FRONT, "drawer", obs, JOINTS, CFG)
    assert (gap - CFG.clearance) / travel - CFG.step / travel <= got <= (gap - CFG.clearance) / travel + 1e-9
    ev = interaction_evidence(FRONT, obs, JOINTS, CFG)
    assert set(blocked_hypotheses(ev, CFG)) == {"drawer", "door_left", "door_right", "flap_top", "flap_bottom"}


def test_an_obstacle_by_one_edge_blocks_only_the_door_hinged_on_the_other_side():
    # a post 5 cm in from the right edge, 15-30 cm in front: the right-hinged door passes it at
    # ~72 deg, the left-hinged one hits it at ~15 deg
    post = _plane((0.25, -0.225, 0.5), (0, 1, 0), (0, 0, 1), 0.075, 0.3)
    obs = Obstacles.of(np.concatenate([_own(), post]))
    left = sweep_clear(FRONT, "door_left", obs, JOINTS, CFG)
    right = sweep_clear(FRONT, "door_right", obs, JOINTS, CFG)
    assert left < 0.25 and 0.7 < right < 1.0
    blocked = blocked_hypotheses(interaction_evidence(FRONT, obs, JOINTS, CFG), CFG)
    assert "door_left" in blocked and "door_right" not in blocked


def test_a_surface_behind_leaves_no_room_for_a_drawer():
    back = _plane((0.0, 0.1, 0.5), (1, 0, 0), (0, 0, 1), 0.4, 0.45)  # a back panel 10 cm behind
    obs = Obstacles.of(np.concatenate([_own(), back]))
    assert room_behind(FRONT, obs, CFG) == pytest.approx(0.1, abs=1e-6)
    why = blocked_hypotheses(interaction_evidence(FRONT, obs, JOINTS, CFG), CFG)
    assert "drawer" in why and "10 cm" in why["drawer"]
    # a wall 40 cm behind (beyond the probe) leaves room
    deep = Obstacles.of(np.concatenate([_own(), back + [0.0, 0.3, 0.0]]))
    assert room_behind(FRONT, deep, CFG) == pytest.approx(CFG.room_probe)


def test_a_stray_point_is_no_wall():
    stray = np.array([[0.0, -0.2, 0.5]])
    obs = Obstacles.of(np.concatenate([_own(), _far(), stray]))
    assert sweep_clear(FRONT, "drawer", obs, JOINTS, CFG) == 1.0
    one = InteractionConfig(min_hits=1)
    assert sweep_clear(FRONT, "drawer", obs, JOINTS, one) < 1.0


def test_panel_samples_cover_the_front_and_the_drawer_box():
    pts = panel_samples(FRONT, 0.05, inset=0.0)
    assert pts[:, 0].min() == pytest.approx(-0.3) and pts[:, 2].max() == pytest.approx(0.85)
    assert np.allclose(pts[:, 1], 0.0)
    box = panel_samples(FRONT, 0.05, inset=0.0, depth=0.3)
    assert box[:, 1].max() == pytest.approx(0.3)  # reaches 30 cm behind (+y)


def test_the_score_rule_drops_what_the_interaction_test_blocks():
    h = Handle(0.9, 0.5, "vertical", 20, "masks")  # a pull by the right edge: a left-hinged door
    ev = Evidence(handle=h, size=(0.6, 0.7), z_mid=0.5, stacked=0, beside_left=False, beside_right=False,
                  partner=False, rail=0.0, carcass=None, labels={}, support=30)
    types = TypesConfig()
    dec, _ = decide_by_score(ev, types, types.prior)
    assert (dec.family, dec.hinge) == ("door", "left")
    dec, terms = decide_by_score(ev, types, types.prior, {"door_left": "its motion hits the scene after 10% of its range",
                                                           "fixed": "never excluded"})
    assert (dec.family, dec.hinge) != ("door", "left") and "door_left" in terms["excluded"]
    assert "fixed" not in terms["excluded"]


@pytest.mark.parametrize("size", [(0.6, 0.7), (1.0, 0.1), (0.1, 1.0)])
def test_no_swept_sample_leaves_the_reach_the_scene_is_cropped_to(size):
    """A wide, low door swung to 90 deg reaches farther from the centre than its diagonal."""
    from drawer_lib.articulation.joints import make_part
    from drawer_lib.articulation.vocab import Decision
    from drawer_lib.geometry.joints import apply_transform, joint_transform

    f = Front((0.0, 0.0, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), size)
    reach = sweep_reach(f, JOINTS)
    for hyp in ("drawer", "door_left", "door_right", "flap_top", "flap_bottom"):
        fam, _, hinge = hyp.partition("_")
        part = make_part("t", Decision(fam, hinge or None), f, JOINTS, {})
        pts = panel_samples(f, 0.02, 0.0, part.limits[1] if part.kind == "prismatic" else 0.0)
        for q in np.linspace(*part.limits, 7):
            moved = apply_transform(joint_transform(part.kind, np.asarray(part.axis.origin),
                                                    np.asarray(part.axis.direction), q), pts)
            assert np.linalg.norm(moved - np.asarray(f.center), axis=1).max() <= reach + 1e-9


def test_obstacles_must_be_finite_and_config_is_checked():
    with pytest.raises(ValueError, match="finite"):
        Obstacles.of(np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(ConfigError, match="min_clear"):
        InteractionConfig(min_clear=1.5)
    with pytest.raises(ConfigError):
        InteractionConfig(clearance=0.0)
