"""Splitting a front at its gap lines (drawer_lib/articulation/gaps.py) on hand-made rectified
fronts: mask boundaries cut (an XY-cut: a vertical gap, then a drawer stack on one side), an
image line cuts only between two handles, tiles and grain do not cut, no cut through a handle or
within min_piece of an edge."""

import numpy as np
import pytest

from drawer_lib.articulation.config import SplitConfig
from drawer_lib.articulation.gaps import even_cuts, split_front
from drawer_lib.articulation.rectify import RectifiedFront
from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Front

RES = 0.004
FRONT = Front((1.0, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.8, 0.6))  # v = n x u = +z


def _rf(boundaries_u=(), boundaries_v=(), lines_u=(), lines_v=(), handles=(), tiles: float | None = None,
        views: int = 20, rate: float = 0.25, front: Front = FRONT, line: float = 0.1) -> RectifiedFront:
    """A rectified ``front`` without margin: boundaries (in ``rate`` of the views) and image lines
    ``line`` darker at u (m from the left edge, full height) or v (m from the bottom; (v, u_from,
    u_to)), handle boxes (u0, u1, v0, v1), an optional tile grid of that pitch."""
    w, h = front.size
    gu, gv = int(round(w / RES)), int(round(h / RES))
    uu = (np.arange(gu) + 0.5) * RES
    vv = (np.arange(gv) + 0.5) * RES
    gray = np.full((gv, gu), 0.5) + 0.004 * np.sin(40 * uu)[None, :]  # a faint grain
    eu, ev = np.zeros((gv, gu), np.int32), np.zeros((gv, gu), np.int32)
    n_edge = int(round(rate * views))
    for u in boundaries_u:
        eu[:, int(u / RES)] = n_edge
    for v, a, b in boundaries_v:
        ev[int(v / RES), int(a / RES):int(b / RES)] = n_edge
    for u in lines_u:
        gray[:, int(u / RES)] -= line
    for v, a, b in lines_v:
        gray[int(v / RES), int(a / RES):int(b / RES)] -= line
    if tiles:
        gray[:, (uu % tiles) < RES] -= 0.1
        gray[(vv % tiles) < RES, :] -= 0.1
    handle = np.zeros((gv, gu), np.int32)
    for u0, u1, v0, v1 in handles:
        handle[int(v0 / RES):int(v1 / RES), int(u0 / RES):int(u1 / RES)] = views
    full = np.full((gv, gu), views, np.int32)
    rgb = np.repeat(gray[..., None], 3, axis=2)
    return RectifiedFront(-w / 2, -h / 2, RES, full, handle, full.copy(), rgb, eu, ev, full.copy(), full.copy())


def _sizes(pieces):
    """Piece sizes to the centimetre (a cut drops its one-cell gap)."""
    return sorted((round(p.size[0] + RES / 2, 2), round(p.size[1] + RES / 2, 2)) for p in pieces)


def test_mask_boundaries_cut_a_door_and_a_drawer_stack():
    rf = _rf(boundaries_u=[0.4], boundaries_v=[(0.3, 0.4, 0.8)])
    pieces = split_front(FRONT, rf, SplitConfig(), 0.3, 3)
    assert _sizes(pieces) == [(0.4, 0.3), (0.4, 0.3), (0.4, 0.6)]
    # pieces tile the front: same plane, areas add up, centres inside
    assert sum(p.size[0] * p.size[1] for p in pieces) == pytest.approx(0.8 * 0.6, rel=0.03)
    for p in pieces:
        assert p.normal == FRONT.normal and p.u == FRONT.u
        d = np.asarray(p.center) - np.asarray(FRONT.center)
        assert abs(d[1]) < 1e-12 and abs(d[0]) < 0.4 and abs(d[2]) < 0.3
    left = min(pieces, key=lambda p: p.center[0])
    assert left.center[0] == pytest.approx(1.0 - 0.2, abs=RES) and left.size[1] == pytest.approx(0.6, abs=RES)


def test_rare_boundaries_do_not_cut():
    rf = _rf(boundaries_u=[0.4], rate=0.05)  # in 1 of 20 views: mask noise
    assert split_front(FRONT, rf, SplitConfig(), 0.3, 3) == [FRONT]


def test_an_image_line_cuts_only_between_two_handles():
    two_pulls = [(0.30, 0.33, 0.2, 0.4), (0.47, 0.50, 0.2, 0.4)]  # a double door's pulls by the gap
    rf = _rf(lines_u=[0.4], handles=two_pulls)
    assert _sizes(split_front(FRONT, rf, SplitConfig(), 0.3, 3)) == [(0.4, 0.6), (0.4, 0.6)]
    rf = _rf(lines_u=[0.4], handles=two_pulls[:1])
    assert split_front(FRONT, rf, SplitConfig(), 0.3, 3) == [FRONT]


def test_tiles_and_grain_do_not_cut():
    assert split_front(FRONT, _rf(tiles=0.15), SplitConfig(), 0.3, 3) == [FRONT]
    assert split_front(FRONT, _rf(), SplitConfig(), 0.3, 3) == [FRONT]


def test_no_cut_through_a_handle_or_near_an_edge():
    rf = _rf(boundaries_u=[0.4], handles=[(0.38, 0.42, 0.25, 0.35)])  # a knob on the line
    assert split_front(FRONT, rf, SplitConfig(), 0.3, 3) == [FRONT]
    rf = _rf(boundaries_u=[0.06])  # 6 cm from the edge: a frame, not a front
    assert split_front(FRONT, rf, SplitConfig(), 0.3, 3) == [FRONT]


def _partial_boundary(rows_per_third: int) -> RectifiedFront:
    """FRONT with a strong mask boundary at u = 0.4 m in the first ``rows_per_third`` rows of
    each third of its 150 rows (50 per third; coverage 0.6 needs 30 of them)."""
    rf = _rf(boundaries_u=[0.4])
    col = int(0.4 / RES)
    keep = np.zeros(rf.edge_u.shape[0], bool)
    for t in range(3):
        keep[50 * t:50 * t + rows_per_third] = True
    rf.edge_u[~keep, col] = 0
    return rf


def test_a_gap_line_one_cell_from_its_coverage_bound_is_reported_near():
    """A cut whose coverage clears its bound by less than one cell of a third, or misses it by
    one cell at most, goes to ``near`` (made or not, where, by how much); one well clear or
    well short does not, and the pieces are those of the same front without ``near``."""
    band = 1 / 50
    for rows, made in ((30, True), (29, False)):  # the bound exactly; one cell short of it in each third
        near = []
        pieces = split_front(FRONT, _partial_boundary(rows), SplitConfig(), 0.3, 3, near=near)
        assert len(pieces) == (2 if made else 1)
        assert pieces == split_front(FRONT, _partial_boundary(rows), SplitConfig(), 0.3, 3)
        (n,) = near
        assert n["cut"] == "gap_line" and n["axis"] == "u" and n["made"] is made
        assert n["margin"] == pytest.approx(rows / 50 - 0.6, abs=1e-4) and n["band"] == pytest.approx(band)
        assert n["at_u"] == pytest.approx(0.0, abs=RES)  # the line, from the front's centre (0.4 m from its left)
    for rows in (45, 20):  # 0.3 clear, 0.2 short: no cell decides it
        near = []
        split_front(FRONT, _partial_boundary(rows), SplitConfig(), 0.3, 3, near=near)
        assert near == []


def test_a_front_one_cell_from_max_width_is_reported_near():
    """Whether a front counts as too wide to be one is a width test: one a cell either side of
    ``max_width`` is listed (``too_wide``, its width and whether it was), one clear of it is not."""
    rf = _wide_rf(lines_u=[0.5, 1.0, 1.5])
    near = []
    split_front(WIDE, rf, SplitConfig(max_width=2.0, wide_even=0.0), 0.3, 3, near=near)
    assert {"cut": "too_wide", "made": False, "width": pytest.approx(2.0, abs=RES)} in near
    near = []
    split_front(WIDE, rf, SplitConfig(max_width=1.996, wide_even=0.0), 0.3, 3, near=near)
    assert {"cut": "too_wide", "made": True, "width": pytest.approx(2.0, abs=RES)} in near
    near = []
    split_front(WIDE, rf, SplitConfig(max_width=1.3), 0.3, 3, near=near)
    assert not [n for n in near if n["cut"] == "too_wide"]


def test_nothing_seen_is_no_split():
    rf = _rf(boundaries_u=[0.4])
    rf.rgb[:] = np.nan
    assert split_front(FRONT, rf, SplitConfig(), 0.3, 3) == [FRONT]


WIDE = Front((1.0, -0.6, 1.8), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (2.0, 0.7))  # a run of wall doors as one


def _wide_rf(lines_u=(), handles=()) -> RectifiedFront:
    """A rectified WIDE front: faint image lines (half the contrast of _rf's) at u, handle boxes,
    no mask boundary anywhere."""
    return _rf(lines_u=lines_u, handles=handles, front=WIDE, line=0.05)


def test_a_front_too_wide_to_be_one_is_cut_at_its_lines_without_handles():
    """Four 0.5 m doors joined in every view, no handle found: off (max_width 0), one front; at
    1.3 m (the default), cut at the image lines until no piece is wider (the 1.0 m pair left at the end stays
    one, as a front of 1.0 m may be); with max_width 0.9, all four. A wide front without any line, or with
    lines only near its ends, stays whole with wide_even off."""
    rf = _wide_rf(lines_u=[0.5, 1.0, 1.5])
    assert split_front(WIDE, rf, SplitConfig(max_width=0.0), 0.3, 3) == [WIDE]
    assert split_front(WIDE, rf, SplitConfig(), 0.3, 3) == split_front(WIDE, rf, SplitConfig(max_width=1.3), 0.3, 3)
    sizes = _sizes(split_front(WIDE, rf, SplitConfig(max_width=1.3), 0.3, 3))
    assert sum(w for w, _ in sizes) == pytest.approx(2.0, abs=0.02) and max(w for w, _ in sizes) <= 1.3
    assert sizes == [(0.5, 0.7), (0.5, 0.7), (1.0, 0.7)]  # 0.5 | 1.5, and the 1.5 m piece once more
    assert _sizes(split_front(WIDE, rf, SplitConfig(max_width=0.9), 0.3, 3)) == [(0.5, 0.7)] * 4
    off = SplitConfig(max_width=1.3, wide_even=0.0)  # the fallback alone: no equal pieces
    assert split_front(WIDE, _wide_rf(), off, 0.3, 3) == [WIDE]
    assert split_front(WIDE, _wide_rf(lines_u=[0.06, 1.94]), off, 0.3, 3) == [WIDE]
    # a line too faint for a cut (in one row of four: under coverage_handles) is still the best one there
    rf = _wide_rf(lines_u=[0.8])
    col = int(0.8 / RES)
    faint = np.arange(rf.rgb.shape[0]) % 4 != 0
    rf.rgb[faint, col] = rf.rgb[faint, col + 3]
    assert split_front(WIDE, rf, SplitConfig(max_width=0.0), 0.3, 3) == [WIDE]  # off: it cuts nothing
    assert _sizes(split_front(WIDE, rf, SplitConfig(max_width=1.3), 0.3, 3)) == [(0.8, 0.7), (1.2, 0.7)]
    # a handle on the line is never cut through
    knob = [(0.48, 0.52, 0.3, 0.4)]
    assert split_front(WIDE, _wide_rf(lines_u=[0.5], handles=knob), off, 0.3, 3) == [WIDE]
    # a front up to max_width keeps the old rule: an image line cuts only between two handles
    narrow = Front(WIDE.center, WIDE.normal, WIDE.u, (1.2, 0.7))  # the middle 1.2 m of the rectified front
    assert split_front(narrow, _wide_rf(lines_u=[1.0]), SplitConfig(max_width=1.3), 0.3, 3) == [narrow]
    assert len(split_front(narrow, _wide_rf(lines_u=[1.0]), SplitConfig(max_width=1.1), 0.3, 3)) == 2


def test_even_cuts_are_equal_and_drop_the_cut_column():
    assert even_cuts(0, 300, 3) == [(0, 100), (101, 200), (201, 300)]
    assert even_cuts(10, 17, 2) == [(10, 14), (15, 17)]  # 3.5 rounds to even: 4
    assert even_cuts(5, 9, 1) == [(5, 9)]
    for n in (2, 3, 7):  # disjoint, in order, covering all but the n - 1 cut columns, equal within a cell
        got = even_cuts(3, 503, n)
        assert got[0][0] == 3 and got[-1][1] == 503 and sum(b - a for a, b in got) == 500 - (n - 1)
        assert all(b0 < a1 for (_, b0), (a1, _) in zip(got, got[1:]))
        assert max(b - a for a, b in got) - min(b - a for a, b in got) <= 2
    # no cut on a handle: it moves to the nearest free column less than half a piece away, or is not made
    knob = np.zeros(300, bool)
    knob[95:110] = True
    assert even_cuts(0, 300, 3, knob) == [(0, 94), (95, 200), (201, 300)]
    bar = np.zeros(300, bool)
    bar[40:160] = True
    assert even_cuts(0, 300, 3, bar) == [(0, 200), (201, 300)]
    assert even_cuts(0, 300, 2, np.ones(300, bool)) == [(0, 300)]


def test_a_front_too_wide_with_no_line_is_cut_into_equal_pieces():
    """The 2.0 m run of wall doors with no line anywhere: whole with wide_even off; at 0.6 m
    (the default), three pieces of 2.0 / 3 m (round(3.33)), recorded in the log; at
    0.5 m, four; a line where there is one is cut first, and only a piece still too wide without
    one is cut evenly (1.5 m at 0.6 m: round(2.5) = 2 pieces of 0.75 m); a front up to max_width
    is never cut evenly, nor with max_width off."""
    rf = _wide_rf()
    assert split_front(WIDE, rf, SplitConfig(wide_even=0.0), 0.3, 3) == [WIDE]
    assert split_front(WIDE, rf, SplitConfig(), 0.3, 3) == split_front(WIDE, rf, SplitConfig(wide_even=0.6), 0.3, 3)
    log = []
    sizes = _sizes(split_front(WIDE, rf, SplitConfig(wide_even=0.6), 0.3, 3, log=log))
    assert len(sizes) == 3 and all(w == pytest.approx(2.0 / 3, abs=0.01) and h == 0.7 for w, h in sizes)
    assert log == [{"even_pieces": 3, "width": pytest.approx(2.0, abs=0.01)}]
    assert len(split_front(WIDE, rf, SplitConfig(wide_even=0.5), 0.3, 3)) == 4
    # a line at 0.5 m cuts first; the 1.5 m piece beyond it has none: two pieces of 0.75 m
    log = []
    sizes = _sizes(split_front(WIDE, _wide_rf(lines_u=[0.5]), SplitConfig(wide_even=0.6), 0.3, 3, log=log))
    assert sizes == [(0.5, 0.7), (0.75, 0.7), (0.75, 0.7)] and [e["even_pieces"] for e in log] == [2]
    # a knob where an even cut would fall: the cut moves off it
    sizes = _sizes(split_front(WIDE, _wide_rf(handles=[(0.62, 0.7, 0.3, 0.4)]), SplitConfig(), 0.3, 3))
    assert sizes == [(0.63, 0.7), (0.67, 0.7), (0.7, 0.7)]  # 0 | 0.70 (not 0.67) | 1.33 | 2.0
    narrow = Front(WIDE.center, WIDE.normal, WIDE.u, (1.2, 0.7))
    assert split_front(narrow, _wide_rf(), SplitConfig(wide_even=0.6), 0.3, 3) == [narrow]
    assert split_front(WIDE, rf, SplitConfig(max_width=0.0), 0.3, 3) == [WIDE]


@pytest.mark.parametrize("bad", [{"coverage": 0.0}, {"boundary_rate": 1.5}, {"min_piece": 0.0}, {"step": 0},
                                 {"max_width": -1.0}, {"wide_min_piece": 0.0}, {"max_width": 0.3, "wide_min_piece": 0.2},
                                 {"wide_even": 0.1}, {"wide_even": 1.5}, {"wide_even": -0.6}, {"wide_even": float("nan")}])
def test_config_checked(bad):
    with pytest.raises(ConfigError, match="articulate.split"):
        SplitConfig(**bad)


def test_a_piece_that_repeats_another_segments_front_is_dropped():
    from drawer_lib.articulation.fronts import coplanar_iou
    from drawer_lib.articulation.infer import drop_duplicate_pieces
    from drawer_lib.perception.decompose import Segment

    def seg(i, support):
        return Segment(i, np.zeros(0, np.int64), 1.0, support, {}, True, np.zeros(3), 0.0, np.zeros(3))

    own = Front((0.8, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.4, 0.6))  # a door detected on its own
    piece_a = Front((0.805, -0.605, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.39, 0.6))  # the same door, cut out
    piece_b = Front((1.2, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.4, 0.6))  # its neighbour: only here
    assert coplanar_iou(own, piece_a) > 0.9 and coplanar_iou(own, piece_b) == pytest.approx(0.0, abs=1e-9)
    turned = Front((0.8, -0.6, 0.5), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.4, 0.6))
    assert coplanar_iou(own, turned) == 0.0
    fits = [(seg(1, 30), own, {}), (seg(2, 20), piece_a, {"piece": 0, "of": 2}), (seg(2, 20), piece_b, {"piece": 1, "of": 2}),
            (seg(3, 10), Front(piece_b.center, piece_b.normal, piece_b.u, (0.41, 0.6)), {"piece": 0, "of": 3})]
    report = []
    kept = drop_duplicate_pieces(fits, 0.5, report)
    assert [(s.id, info.get("piece")) for s, _, info in kept] == [(1, None), (2, 1)]  # the better supported piece stays
    assert [(r["segment"], r["piece"]) for r in report] == [(2, 0), (3, 0)]


# --- depth steps: two sliding panels merged into one front -------------------------------------

def _panel_points(rng, spans, h=0.7, noise=0.002, yaw=0.0, n_per=4000):
    """Points [P, 3] of panels on the front plane x-z (u = x, v = z, normal = -y toward the
    camera): ``spans`` [(u0, u1, offset toward the camera (m))]; ``yaw``: the fitted plane's tilt
    (offset grows by yaw x u)."""
    out = []
    for u0, u1, off in spans:
        u = rng.uniform(u0, u1, n_per)
        v = rng.uniform(-h / 2, h / 2, n_per)
        n = off + yaw * u + rng.normal(0, noise, n_per)
        out.append(np.stack([u, -n, v], axis=1))
    return np.concatenate(out)


def _front(w=1.0, h=0.7):
    return Front((0.0, 0.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (w, h))


def _cut(pts, front=None, **kw):
    from drawer_lib.articulation.gaps import depth_step_cuts

    return depth_step_cuts(front or _front(), pts, (0.008, 0.06), 0.1, **kw)


@pytest.mark.parametrize("yaw", [0.0, 0.02])
def test_a_track_offset_cuts_a_merged_sliding_pair(yaw):
    rng = np.random.default_rng(0)
    pts = _panel_points(rng, [(-0.5, 0.01, 0.022), (0.01, 0.5, 0.0)], yaw=yaw)
    pieces = _cut(pts)
    assert len(pieces) == 2
    left, right = sorted(pieces, key=lambda f: f.center[0])
    assert abs(left.size[0] - 0.51) < 0.03 and abs(right.size[0] - 0.49) < 0.03
    assert abs(left.size[0] + right.size[0] - 1.0) < 1e-9
    # each piece takes its own plane: the outer panel 22 mm nearer the camera (-y), the yaw's mean aside
    assert abs((-left.center[1]) - (-right.center[1]) - (0.022 - yaw * 0.5)) < 0.004


def test_three_panels_on_two_tracks_give_three_pieces():
    rng = np.random.default_rng(1)
    pts = _panel_points(rng, [(-0.75, -0.25, 0.0), (-0.25, 0.25, 0.02), (0.25, 0.75, 0.0)])
    assert len(_cut(pts, _front(w=1.5))) == 3


@pytest.mark.parametrize("case", ["flat", "shaker", "top_third_only", "too_deep", "near_edge"])
def test_what_is_not_a_track_offset_does_not_cut(case):
    rng = np.random.default_rng(2)
    if case == "flat":
        pts = _panel_points(rng, [(-0.5, 0.5, 0.0)], noise=0.004)
    elif case == "shaker":  # a frame-and-panel door: 6 cm stiles and rails 10 mm proud of the panel
        pts = np.concatenate([_panel_points(rng, [(-0.5, -0.44, 0.01), (0.44, 0.5, 0.01)]),
                              _panel_points(rng, [(-0.44, 0.44, 0.0)], h=0.58)])
    elif case == "top_third_only":  # e.g. a shelf seen through an open top half, not a panel edge
        top = _panel_points(rng, [(-0.5, 0.0, 0.03)], h=0.2)
        top[:, 2] += 0.25
        pts = np.concatenate([_panel_points(rng, [(-0.5, 0.5, 0.0)]), top])
        pts = pts[~((pts[:, 0] < 0) & (pts[:, 2] > 0.15) & (np.abs(pts[:, 1]) < 0.005))]
    elif case == "too_deep":  # a door beside a niche 8 cm deep
        pts = _panel_points(rng, [(-0.5, 0.0, 0.0), (0.0, 0.5, -0.08)])
    else:  # a step 5 cm from the end: less than min_piece
        pts = _panel_points(rng, [(-0.5, -0.45, 0.02), (-0.45, 0.5, 0.0)])
    assert len(_cut(pts)) == 1


def test_a_depth_step_cut_records_its_margin_and_one_near_its_bounds_is_reported():
    """Each cut's ``margin`` is the least clearance of its tests (m); a step whose margin lies
    within STEP_BAND of 0, cut or not, goes to ``near``: a mesh moved by its last bits could
    decide it the other way. A clear track offset is not near; a flat front has no step near."""
    from drawer_lib.articulation.gaps import STEP_BAND

    rng = np.random.default_rng(5)
    log, near = [], []
    assert len(_cut(_panel_points(rng, [(-0.5, 0.01, 0.022), (0.01, 0.5, 0.0)]), log=log, near=near)) == 2
    (c,) = log
    assert c["margin"] == pytest.approx(min(abs(c["step"]) - 0.008, c["least_third"] - 0.004,
                                            abs(c["step"]) / 4 - c["rms"]), abs=2e-4)
    assert c["margin"] > STEP_BAND and near == []
    for off, made in ((0.0085, True), (0.0075, False)):  # half a millimetre either side of the 8 mm bound
        log, near = [], []
        pieces = _cut(_panel_points(np.random.default_rng(6), [(-0.5, 0.01, off), (0.01, 0.5, 0.0)], noise=0.0003),
                      log=log, near=near)
        assert len(pieces) == (2 if made else 1) and len(log) == int(made)
        (n,) = near
        assert n["made"] is made and abs(n["margin"]) < STEP_BAND and n["at_u"] == pytest.approx(0.0, abs=0.03)
    near = []
    _cut(_panel_points(rng, [(-0.5, 0.5, 0.0)], noise=0.0003), near=near)
    assert near == []


def test_depth_steps_degenerate_input():
    f = _front()
    assert _cut(np.zeros((0, 3)), f) == [f]
    rng = np.random.default_rng(3)
    pts = _panel_points(rng, [(-0.5, 0.01, 0.022), (0.01, 0.5, 0.0)])
    pts[::7] = np.nan  # NaN points are not data
    assert len(_cut(pts)) == 2
    tiny = Front((0.0, 0.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.15, 0.15))
    assert _cut(pts, tiny) == [tiny]


def test_the_pieces_of_a_merged_sliding_pair_are_partners():
    """The two pieces of one segment measure their step on their own points: with the
    segment's points shared, the step between them would read 0 and the pair would be doors."""
    from drawer_lib.articulation.config import JointsConfig
    from drawer_lib.articulation.infer import piece_points
    from drawer_lib.articulation.joints import sliding_partners

    rng = np.random.default_rng(4)
    pts = _panel_points(rng, [(-0.5, 0.01, 0.022), (0.01, 0.5, 0.0)], n_per=1500)
    pieces = _cut(pts)
    assert len(pieces) == 2
    cfg = JointsConfig()
    own = [piece_points(pts, f, True) for f in pieces]
    assert sliding_partners(pieces, [None, None], cfg, own) == {0: (1, pytest.approx(0.0, abs=1e-9)),
                                                                1: (0, pytest.approx(0.0, abs=1e-9))}
    assert sliding_partners(pieces, [None, None], cfg, [pts, pts]) == {}


def test_leaves_pulled_where_they_meet_are_not_a_sliding_pair():
    """Two fronts a step apart are a sliding pair when pulled at their outer edges (or not at
    all); pulled where they meet, they are a double door's leaves (a recessed one, a door of
    another depth) and stay unpaired. Either leaf's pull alone decides; centred pulls say
    nothing."""
    from drawer_lib.articulation.config import JointsConfig
    from drawer_lib.articulation.infer import piece_points
    from drawer_lib.articulation.joints import sliding_partners
    from drawer_lib.articulation.vocab import Handle

    rng = np.random.default_rng(4)
    pts = _panel_points(rng, [(-0.5, 0.01, 0.022), (0.01, 0.5, 0.0)], n_per=1500)
    pieces = _cut(pts)
    own = [piece_points(pts, f, True) for f in pieces]
    left_of = [float(np.asarray(f.center) @ np.asarray(f.u)) for f in pieces]
    assert left_of[0] < left_of[1]  # piece 0 on the left along u, piece 1 on the right

    def pull(a_u):
        return Handle(a_u, 0.5, "vertical", 50, "images")

    cfg = JointsConfig()
    outer = [pull(0.1), pull(0.9)]           # each at its outer edge: sliding panels
    meeting = [pull(0.9), pull(0.1)]         # each at the edge it shares: a double door
    assert set(sliding_partners(pieces, outer, cfg, own)) == {0, 1}
    assert set(sliding_partners(pieces, [pull(0.5), pull(0.5)], cfg, own)) == {0, 1}
    assert sliding_partners(pieces, meeting, cfg, own) == {}
    assert sliding_partners(pieces, [pull(0.9), None], cfg, own) == {}   # the left leaf's pull alone
    assert sliding_partners(pieces, [None, pull(0.1)], cfg, own) == {}   # the right leaf's alone
    off = JointsConfig(sliding_pull_meets=None)
    assert set(sliding_partners(pieces, meeting, off, own)) == {0, 1}


# --- outline steps: an L-shaped segment is two fronts --------------------------------------------

def _rect_points(rng, u0, u1, v0, v1, off=0.0, n_per_m2=40000):
    n = max(int((u1 - u0) * (v1 - v0) * n_per_m2), 1)
    u, v = rng.uniform(u0, u1, n), rng.uniform(v0, v1, n)
    return np.stack([u, -np.full(n, off) - rng.normal(0, 0.001, n), v], axis=1)  # x = u, -y = toward the camera, z = v


def _l_shape(rng):
    """A door 0.45 x 0.66 (left) merged with a door 0.40 x 0.82 (right), bottoms level; the
    front's rectangle is their bounding box 0.85 x 0.82 centred at the origin."""
    seg = np.concatenate([_rect_points(rng, -0.425, 0.0, -0.41, 0.25), _rect_points(rng, 0.0, 0.425, -0.41, 0.41)])
    return seg, Front((0.0, 0.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.85, 0.82))


@pytest.mark.parametrize("notch", ["wall_behind", "another_segment", "same_plane_no_segment", "object_in_front", "none"])
def test_an_l_shaped_segment_is_cut_where_its_outline_steps(notch):
    from drawer_lib.articulation.gaps import extent_step_cuts

    rng = np.random.default_rng(5)
    seg, front = _l_shape(rng)
    scene = [seg]
    owner = [np.full(len(seg), 1)]  # the segment's own id: 1
    if notch != "none":
        off = {"wall_behind": -0.3, "another_segment": 0.0, "same_plane_no_segment": 0.0, "object_in_front": 0.12}[notch]
        pts = _rect_points(rng, -0.425, 0.0, 0.25, 0.41, off)
        scene.append(pts)
        owner.append(np.full(len(pts), 5 if notch == "another_segment" else -1))
    pieces = extent_step_cuts(front, seg, np.concatenate(scene), np.concatenate(owner), 1, 0.05, 0.1)
    if notch in ("wall_behind", "another_segment"):
        assert len(pieces) == 2
        left, right = sorted(pieces, key=lambda f: f.center[0])
        assert left.size[0] == pytest.approx(0.425, abs=0.021) and left.size[1] == pytest.approx(0.66, abs=0.02)
        assert right.size[0] == pytest.approx(0.425, abs=0.021) and right.size[1] == pytest.approx(0.82, abs=0.02)
        assert left.center[2] == pytest.approx(-0.08, abs=0.01)  # the short door keeps its own height
    else:  # the front's own surface that decompose left out, an object hiding a corner, nothing seen
        assert pieces == [front]


def test_a_rectangle_or_a_small_step_is_not_cut():
    from drawer_lib.articulation.gaps import extent_step_cuts

    rng = np.random.default_rng(6)
    f = Front((0.0, 0.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.85, 0.82))
    rect = _rect_points(rng, -0.425, 0.425, -0.41, 0.41)
    wall = _rect_points(rng, -0.425, 0.425, 0.41, 0.6, -0.3)
    scene, owner = np.concatenate([rect, wall]), np.r_[np.ones(len(rect)), -np.ones(len(wall))].astype(int)
    assert extent_step_cuts(f, rect, scene, owner, 1, 0.05, 0.1) == [f]
    ragged = np.concatenate([_rect_points(rng, -0.425, 0.0, -0.41, 0.38), _rect_points(rng, 0.0, 0.425, -0.41, 0.41)])
    assert extent_step_cuts(f, ragged, scene, owner, 1, 0.05, 0.1) == [f]  # a 3 cm step: under min_step
    assert extent_step_cuts(f, np.zeros((0, 3)), scene, owner, 1, 0.05, 0.1) == [f]


def test_an_outline_step_records_its_margins_and_one_near_its_bounds_is_reported():
    """An outline cut logs ``margin`` (the least clearance of its length tests, m) and
    ``notch_margin`` (the notch's share of other surfaces less 2/3); with ``min_step`` half a
    millimetre either side of the measured step the cut is made or not, and either way listed
    in ``near``; at the default bound it is clear and not listed."""
    from drawer_lib.articulation.gaps import STEP_BAND, extent_step_cuts

    rng = np.random.default_rng(5)
    seg, front = _l_shape(rng)
    wall = _rect_points(rng, -0.425, 0.0, 0.25, 0.41, -0.3)
    scene = np.concatenate([seg, wall])
    owner = np.r_[np.ones(len(seg)), -np.ones(len(wall))].astype(int)
    log, near = [], []
    assert len(extent_step_cuts(front, seg, scene, owner, 1, 0.05, 0.1, log=log, near=near)) == 2
    (c,) = log
    assert c["margin"] == pytest.approx(min(abs(c["step"]) - 0.05, abs(c["step"]) / 4 - c["spread"],
                                            0.425 - abs(c["at_u"]) - 0.1), abs=2e-4)
    assert c["notch_margin"] == pytest.approx(c["notch_other"] - 2 / 3, abs=2e-3) and c["notch_margin"] > 0.02
    assert c["margin"] > STEP_BAND and near == []
    for d, made in ((-0.0005, True), (0.0005, False)):
        log, near = [], []
        pieces = extent_step_cuts(front, seg, scene, owner, 1, abs(c["step"]) + d, 0.1, log=log, near=near)
        assert len(pieces) == (2 if made else 1) and len(log) == int(made)
        (n,) = [x for x in near if x["outline"] == c["outline"]]
        assert n["cut"] == "outline_step" and n["made"] is made and abs(n["margin"]) < STEP_BAND
        assert n["at_u"] == pytest.approx(c["at_u"], abs=1e-9)


def test_window_contrast_reads_a_pane_not_a_pull():
    """An oven door 0.6 x 0.45 m: a dark pane inset 6 cm (sides) / 8 and 12 cm (bottom / top)
    stands 0.4 off the frame; the same door with no pane, or a plain drawer with a dark bar
    across its middle (a pull over less than half the panel), stands ~0 off; a panel no view saw
    gives None, as does a front with no image."""
    from drawer_lib.articulation.rectify import window_contrast

    door = Front((0.0, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.6, 0.45))
    rf = _rf(front=door)
    assert window_contrast(door, rf) == pytest.approx(0.0, abs=0.01)
    gv, gu = rf.shape
    uu, vv = (np.arange(gu) + 0.5) * RES, (np.arange(gv) + 0.5) * RES
    pane = ((vv > 0.08) & (vv < 0.45 - 0.12))[:, None] & ((uu > 0.06) & (uu < 0.54))[None, :]
    rf.rgb[pane] = 0.1
    assert window_contrast(door, rf) == pytest.approx(0.4, abs=0.01)
    bar = _rf(front=door)
    bar.rgb[(np.abs(vv - 0.22) < 0.015)[:, None] & (np.abs(uu - 0.3) < 0.1)[None, :]] = 0.05
    assert window_contrast(door, bar) == pytest.approx(0.0, abs=0.01)
    blind = _rf(front=door)
    blind.rgb[pane] = np.nan
    assert window_contrast(door, blind) is None
    blind.rgb = None
    assert window_contrast(door, blind) is None
