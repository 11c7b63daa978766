"""Splitting a front at its gap lines (drawer_lib/articulation/gaps.py) on hand-made rectified
fronts: mask boundaries cut (an XY-cut: a vertical gap, then a drawer stack on one side), an
image line cuts only between two handles, tiles and grain do not cut, no cut through a handle or
within min_piece of an edge."""

import numpy as np
import pytest

from drawer_lib.articulation.config import SplitConfig
from drawer_lib.articulation.gaps import split_front
from drawer_lib.articulation.rectify import RectifiedFront
from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Front

RES = 0.004
FRONT = Front((1.0, -0.6, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.8, 0.6))  # v = n x u = +z


def _rf(boundaries_u=(), boundaries_v=(), lines_u=(), lines_v=(), handles=(), tiles: float | None = None,
        views: int = 20, rate: float = 0.25) -> RectifiedFront:
    """A rectified FRONT without margin: boundaries (in ``rate`` of the views) and image lines at
    u (m from the left edge, full height) or v (m from the bottom; (v, u_from, u_to)), handle
    boxes (u0, u1, v0, v1), an optional tile grid of that pitch."""
    w, h = FRONT.size
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
        gray[:, int(u / RES)] -= 0.1
    for v, a, b in lines_v:
        gray[int(v / RES), int(a / RES):int(b / RES)] -= 0.1
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


def test_nothing_seen_is_no_split():
    rf = _rf(boundaries_u=[0.4])
    rf.rgb[:] = np.nan
    assert split_front(FRONT, rf, SplitConfig(), 0.3, 3) == [FRONT]


@pytest.mark.parametrize("bad", [{"coverage": 0.0}, {"boundary_rate": 1.5}, {"min_piece": 0.0}, {"step": 0}])
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
