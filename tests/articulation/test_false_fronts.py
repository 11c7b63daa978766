"""World-fixed false fronts (articulation/infer.py: world_fixed) on analytic evidence: the gap
lines round a rectified front (gaps.border_lines), the surface beyond its sides
(probes.flush_sides), and the rule that drops a patch of wall but keeps a front."""

import numpy as np
import pytest

from drawer_lib.articulation.config import FalseFrontsConfig, SplitConfig
from drawer_lib.articulation.gaps import border_lines
from drawer_lib.articulation.infer import flanked, gave_reasons, world_fixed
from drawer_lib.articulation.probes import flush_sides
from drawer_lib.articulation.rectify import RectifiedFront, front_grid
from drawer_lib.articulation.vocab import Handle
from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Front

RES = 0.004
MARGIN = 0.03
FRONT = Front((0.0, 0.0, 1.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.4, 0.3))  # v = +z


def _rf(sides=(), seen_all=True) -> RectifiedFront:
    """FRONT rectified with a margin: a dark gap line on each of ``sides`` over a grey panel
    with a faint grain."""
    u0, v0, gu, gv = front_grid(FRONT, RES, MARGIN)
    uu, vv = np.meshgrid(u0 + (np.arange(gu) + 0.5) * RES, v0 + (np.arange(gv) + 0.5) * RES)
    gray = 0.6 + 0.003 * np.sin(50 * uu)
    w, h = FRONT.size
    for side in sides:
        at = {"left": (uu, -w / 2), "right": (uu, w / 2), "bottom": (vv, -h / 2), "top": (vv, h / 2)}[side]
        gray[np.abs(at[0] - at[1]) < RES / 2 + 1e-9] -= 0.2
    rgb = np.repeat(gray[..., None], 3, axis=2)
    seen = np.full((gv, gu), 10 if seen_all else 0, np.int32)
    if not seen_all:
        rgb[:] = np.nan
    return RectifiedFront(u0, v0, RES, seen, np.zeros_like(seen), seen.copy(), rgb)


def test_border_lines_find_the_gap_on_each_side_it_runs():
    lines = border_lines(FRONT, _rf(("left", "top")), SplitConfig(), slack=0.012)
    assert lines["left"] == pytest.approx(1.0) and lines["top"] == pytest.approx(1.0)
    assert lines["right"] == 0.0 and lines["bottom"] == 0.0
    assert border_lines(FRONT, _rf(), SplitConfig(), slack=0.012) == dict.fromkeys(("left", "right", "bottom", "top"), 0.0)
    assert set(border_lines(FRONT, _rf(seen_all=False), SplitConfig(), 0.012).values()) == {None}


def _plane_points(z_of, spacing=0.01):
    """Points on the front's plane region +- 0.5 m, displaced along the normal by z_of(u, v)."""
    a, b = np.meshgrid(np.arange(-0.5, 0.5, spacing), np.arange(-0.5, 0.5, spacing))
    a, b = a.ravel(), b.ravel()
    z = z_of(a, b)
    c, u, v, n = (np.asarray(FRONT.center), np.asarray(FRONT.u), FRONT.v, np.asarray(FRONT.normal))
    return c + a[:, None] * u + b[:, None] * v + z[:, None] * n


def test_flush_sides_see_a_wall_run_on_and_a_counter_step_out():
    wall = _plane_points(lambda a, b: np.zeros_like(a))
    assert flush_sides(FRONT, wall, (0.03, 0.1), 0.01, 20) == dict.fromkeys(("left", "right", "bottom", "top"), 1.0)
    # a counter above: 4 cm proud beyond the top side; open space (no points) to the left
    stepped = _plane_points(lambda a, b: np.where(b > FRONT.size[1] / 2, 0.04, 0.0))
    stepped = stepped[(stepped @ np.asarray(FRONT.u)) > -FRONT.size[0] / 2 - 0.01]
    f = flush_sides(FRONT, stepped, (0.03, 0.1), 0.01, 20)
    assert f["top"] == 0.0 and f["left"] is None and f["right"] == 1.0 and f["bottom"] == 1.0


def test_a_patch_of_wall_is_dropped_and_a_front_kept():
    cfg = FalseFrontsConfig()
    flush = dict.fromkeys(("left", "right", "bottom", "top"), 1.0)
    none = dict.fromkeys(("left", "right", "bottom", "top"), 0.0)
    why = world_fixed({"lines": none, "flush": flush}, None, cfg)
    assert why is not None and "4 sides" in why
    # a colour-only handle does not save it; a detected one does
    assert world_fixed({"lines": none, "flush": flush}, Handle(0.5, 0.8, "horizontal", 30, "colour"), cfg)
    assert world_fixed({"lines": none, "flush": flush}, Handle(0.5, 0.8, "horizontal", 30, "masks"), cfg) is None
    # a gap line on one side, a step on one side, or an unseen side: kept
    assert world_fixed({"lines": none | {"top": 0.8}, "flush": flush}, None, cfg) is None
    assert world_fixed({"lines": none, "flush": flush | {"top": 0.1}}, None, cfg) is None
    assert world_fixed({"lines": none, "flush": flush | {"top": None}}, None, cfg) is None
    assert world_fixed({"lines": dict.fromkeys(none), "flush": flush}, None, cfg) is None  # nothing seen: no call
    # a front in a run of fronts (a drawer stack whose gaps the images do not resolve): kept
    assert world_fixed({"lines": none, "flush": flush}, None, cfg, (1, False, False)) is None
    assert world_fixed({"lines": none, "flush": flush}, None, cfg, (0, False, True)) is None


def test_a_front_flush_at_both_sides_without_gaps_is_flanked():
    """Flanked: flush beyond left and right, a gap line along fewer than two sides. A gap on
    two sides, a step or an unseen side at either side, or the rule turned off: not flanked."""
    cfg = FalseFrontsConfig()
    sides = ("left", "right", "bottom", "top")
    wall = {"left": 0.9, "right": 0.5, "bottom": None, "top": 1.0}
    one_line = dict.fromkeys(sides, 0.0) | {"bottom": 0.8}
    assert flanked({"lines": one_line, "flush": wall}, cfg)
    assert flanked({"lines": dict.fromkeys(sides), "flush": wall}, cfg)  # no side seen: no gap shown
    assert not flanked({"lines": one_line | {"top": 0.35}, "flush": wall}, cfg)
    assert flanked({"lines": one_line | {"top": 0.25}, "flush": wall}, cfg)  # under flanked_line
    assert not flanked({"lines": one_line, "flush": wall | {"right": 0.3}}, cfg)  # a step at one side
    assert not flanked({"lines": one_line, "flush": wall | {"left": None}}, cfg)  # nothing seen beyond it
    assert not flanked({"lines": one_line, "flush": wall}, FalseFrontsConfig(flanked_min_lines=0))
    assert not flanked({"lines": one_line, "flush": wall}, FalseFrontsConfig(flanked_min_lines=1))


def test_false_fronts_config_is_checked():
    with pytest.raises(ConfigError, match="ring"):
        FalseFrontsConfig(ring=[0.1, 0.05])
    with pytest.raises(ConfigError):
        FalseFrontsConfig(min_flush_sides=5)
    with pytest.raises(ConfigError, match="flanked_line = 1.5"):
        FalseFrontsConfig(flanked_line=1.5)
    with pytest.raises(ConfigError, match="flanked_min_lines = 5"):
        FalseFrontsConfig(flanked_min_lines=5)


def test_gave_reasons_says_each_pull_once():
    """A pull handed over in two moves (both of a front's shares, one after the other) gives the
    same sentence twice: the reason says it once; other fronts' moves are not its own."""
    why = "the pull it shared with segment {} reaches 1.8 cm deeper into that front, which took it"
    gave = [(0, 1, why), (0, 1, why), (0, 2, "the pull it shared with segment {} went there"), (1, 0, why)]
    assert gave_reasons(gave, 0, [7, 16, 20]) == ("; the pull it shared with segment 16 reaches 1.8 cm deeper into "
                                                   "that front, which took it; the pull it shared with segment 20 went there")
    assert gave_reasons(gave, 1, [7, 16, 20]).count("segment 7") == 1
    assert gave_reasons(gave, 2, [7, 16, 20]) == ""
