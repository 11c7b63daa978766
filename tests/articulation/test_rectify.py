"""Fronts rectified from every view: the handle map against an analytic scene (a front in the
plane y = 0 facing -y, a handle 2 cm proud of it, cameras on an arc), occlusion, the views a
front was detected in, and the margin / confidence of a decision."""

import numpy as np
import pytest

from drawer_lib.articulation.config import RectifyConfig
from drawer_lib.articulation.decide import margin_confidence
from drawer_lib.articulation.handles import handle_candidates, describe_handle
from drawer_lib.articulation.config import HandlesConfig
from drawer_lib.articulation.rectify import View, front_grid, rectify_front, rectify_fronts
from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Camera, Intrinsics, invert_rigid, look_at_opencv, pixel_of
from drawer_lib.io.parts import Front

FRONT = Front((0.0, 0.0, 1.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.6, 0.4))  # v = n x u = +z
HANDLE_C = np.array([0.2, -0.02, 1.12])  # a_u = (0.2 + 0.3) / 0.6, a_v = (0.12 + 0.2) / 0.4
HANDLE_HALF = np.array([0.01, 0.0, 0.06])  # a vertical bar 2 x 12 cm


def _views(n: int = 8, handle_in: set[int] | None = None, occluder_depth: float | None = None) -> list[View]:
    it = Intrinsics(500.0, 500.0, 160.0, 120.0, 320, 240)
    views = []
    for t, ang in enumerate(np.linspace(-0.6, 0.6, n)):
        eye = np.array([1.2 * np.sin(ang), -1.2 * np.cos(ang), 1.1])
        cam = Camera(it, invert_rigid(look_at_opencv(eye, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0]))))
        o, d = cam.rays()
        # the plane y = 0 hit along every ray: the reconstructed surface is the front's plane
        tz = -o[..., 1] / np.where(np.abs(d[..., 1]) > 1e-9, d[..., 1], 1e-9)
        depth = np.where(tz > 0, tz, 0.0).astype(np.float32)
        if occluder_depth is not None:
            depth = np.minimum(depth, occluder_depth).astype(np.float32)
        # the handle's mask: its box (2 cm proud) sampled densely and projected
        g = np.stack(np.meshgrid(*(np.linspace(-1, 1, 61),) * 3, indexing="ij"), -1).reshape(-1, 3)
        pts = HANDLE_C + g * (HANDLE_HALF + np.array([0.0, 0.01, 0.0]))
        r, c, _, ok = pixel_of(pts, cam.w2c, it)
        mask = np.zeros((it.height, it.width), bool)
        if handle_in is None or t in handle_in:
            mask[r[ok], c[ok]] = True
        views.append(View(cam, depth, mask, None, f"f{t}"))
    return views


def test_handle_found_where_it_is():
    cfg = RectifyConfig()
    rf = rectify_front(FRONT, _views(), cfg)
    u0, v0, gu, gv = front_grid(FRONT, cfg.res, cfg.margin)
    assert rf.shape == (gv, gu) and (rf.seen.max() == 8)
    _, pts, rates = rectify_fronts([FRONT], _views(), cfg)
    cands = handle_candidates([FRONT], pts, HandlesConfig(), 1.5 * cfg.res, cfg.min_cells, weights=rates)
    assert len(cands[0]) == 1
    h = describe_handle(FRONT, cands[0][0][0], "images", HandlesConfig())
    assert h.a_u == pytest.approx(0.5 / 0.6, abs=0.02) and h.a_v == pytest.approx(0.32 / 0.4, abs=0.03)
    assert h.orientation == "vertical"


@pytest.mark.parametrize("w", [0.001, 0.3999, 0.424, 0.48399, 1.7])
def test_a_centre_anchored_grid_covers_the_front_with_cells_at_whole_steps_from_its_centre(w):
    """``grid_anchor: centre``: an odd count of cells centred at whole multiples of ``res`` from
    the front's centre, covering the rectangle and its margin with less than a cell to spare."""
    res, margin = 0.004, 0.03
    f = Front((0.0, 0.0, 1.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (w, 0.37 * w + 0.01))
    u0, v0, gu, gv = front_grid(f, res, margin, "centre")
    for lo, n, half in ((u0, gu, w / 2 + margin), (v0, gv, f.size[1] / 2 + margin)):
        centres = lo + (np.arange(n) + 0.5) * res
        assert n % 2 == 1 and np.allclose(centres / res, np.round(centres / res), atol=1e-9)
        assert -lo >= half - 1e-12 and -lo - half < res
    with pytest.raises(ValueError, match="anchor"):
        front_grid(f, res, margin, "corner")


def test_a_width_change_across_a_cell_moves_the_handle_cells_only_with_a_size_anchored_grid():
    """A front whose width (+ margins) crosses a multiple of the cell by 0.02 mm, as another
    machine's mesh moves it: with ``grid_anchor: size`` the cell count's parity flips and every
    handle cell moves by half a cell; with ``centre`` the handle's cells stay where they were."""
    w = 4 * 0.004 * 30 - 2 * 0.03  # 0.42 m: w + 2 margin is 120 cells
    pts = {}
    for anchor in ("size", "centre"):
        cfg = RectifyConfig(grid_anchor=anchor)
        for dw in (-2e-5, 2e-5):
            f = Front(FRONT.center, FRONT.normal, FRONT.u, (w + dw, FRONT.size[1]))
            _, p, _ = rectify_fronts([f], _views(), cfg)
            pts[anchor, dw] = p[np.lexsort(p.T)]
    assert len(pts["centre", -2e-5]) > 20 and np.array_equal(pts["centre", -2e-5], pts["centre", 2e-5])
    a, b = pts["size", -2e-5], pts["size", 2e-5]
    assert len(a) != len(b) or not np.allclose(a, b, atol=1e-3)


def test_occluded_views_do_not_count():
    cfg = RectifyConfig()
    rf = rectify_front(FRONT, _views(occluder_depth=0.5), cfg)  # a surface 0.5 m from every camera
    assert rf.seen.max() == 0 and rf.handle_rate(cfg.min_views).max() == 0


def test_a_front_seen_in_few_views_keeps_its_handle():
    cfg = RectifyConfig()
    views = _views(n=12, handle_in={0, 5, 9})  # the detector held the front (and its handle) in 3 of 12 views
    everywhere = rectify_front(FRONT, views, cfg).handle_rate(cfg.min_views).max()
    detected = np.zeros(12, bool)
    detected[[0, 5, 9]] = True
    where_detected = rectify_front(FRONT, views, cfg, detected).handle_rate(cfg.min_views).max()
    assert everywhere < cfg.min_rate <= where_detected
    detected[:] = False
    detected[0] = True  # fewer than min_views detected views: all views count
    assert rectify_front(FRONT, views, cfg, detected).handle_rate(cfg.min_views).max() == pytest.approx(everywhere)


def test_no_handle_masks_no_points():
    cfg = RectifyConfig()
    _, pts, rates = rectify_fronts([FRONT], _views(handle_in=set()), cfg)
    assert pts.shape == (0, 3) and rates.shape == (0,)


@pytest.mark.parametrize("bad", [{"res": 0.0}, {"max_angle_deg": 90.0}, {"min_rate": 0.0}, {"margin": -0.01},
                                 {"handle_link": 0.5}, {"grid_anchor": "corner"}])
def test_config_checked(bad):
    with pytest.raises(ConfigError, match="articulate.rectify"):
        RectifyConfig(**bad)


def test_margin_and_confidence():
    scores = {"drawer": 2.0, "door_left": 1.0, "door_right": 1.0, "flap_top": -1.0, "flap_bottom": -1.0,
              "sliding": -3.0, "fixed": 0.0}
    ru, m, c = margin_confidence(scores, "drawer")
    assert ru == "door_left" and m == pytest.approx(1.0)
    s = np.array(list(scores.values()))
    assert c == pytest.approx(np.exp(2.0) / np.exp(s).sum())
    tie = scores | {"door_left": 3.0, "door_right": 3.0}  # two hinge sides alike: margin 0
    ru, m, c = margin_confidence(tie, "door_left")
    assert ru == "door_right" and m == 0.0 and c < 0.5
    big = {k: v * 1e3 for k, v in scores.items()}  # no overflow with huge scores
    assert margin_confidence(big, "drawer")[2] == pytest.approx(1.0)


def _colour_front(bar: tuple[float, float, float, float] | None, noise: float = 0.01, seed: int = 0):
    """FRONT rectified without margin: a panel of one colour with noise, and a metal bar
    (u0, u1, v0, v1 in m from the bottom-left corner)."""
    from drawer_lib.articulation.rectify import RectifiedFront

    res = 0.004
    gu, gv = int(round(0.6 / res)), int(round(0.4 / res))
    rgb = np.empty((gv, gu, 3))
    rgb[:] = (0.45, 0.3, 0.2)
    rgb += np.random.default_rng(seed).normal(0, noise, rgb.shape)
    for b in [] if bar is None else [bar] if np.isscalar(bar[0]) else bar:  # one bar or a list of them
        u0, u1, v0, v1 = (int(round(x / res)) for x in b)
        rgb[v0:v1, u0:u1] = (0.75, 0.75, 0.78)
    seen = np.full((gv, gu), 10, np.int32)
    return RectifiedFront(-0.3, -0.2, res, seen, np.zeros_like(seen), seen.copy(), rgb)


def test_colour_handle_finds_a_bar_the_masks_missed():
    from drawer_lib.articulation.handles import colour_handle

    cfg = RectifyConfig()
    pts = colour_handle(FRONT, _colour_front((0.48, 0.50, 0.20, 0.32)), cfg)  # a vertical pull by the right edge
    assert pts is not None
    h = describe_handle(FRONT, pts, "colour", HandlesConfig())
    assert h.a_u == pytest.approx(0.49 / 0.6, abs=0.02) and h.a_v == pytest.approx(0.26 / 0.4, abs=0.02)
    assert h.orientation == "vertical"


@pytest.mark.parametrize("bar", [None, (0.05, 0.55, 0.18, 0.2), (0.0, 0.6, 0.0, 0.012)],
                         ids=["plain panel", "a stripe across the front", "a gap along the edge"])
def test_colour_handle_finds_nothing_that_is_not_a_handle(bar):
    from drawer_lib.articulation.handles import colour_handle

    assert colour_handle(FRONT, _colour_front(bar), RectifyConfig()) is None


def test_a_colour_pull_chosen_with_a_margin_is_not_near():
    from drawer_lib.articulation.handles import colour_handle

    near = {}
    assert colour_handle(FRONT, _colour_front((0.48, 0.50, 0.20, 0.32)), RectifyConfig(), near=near) is not None
    assert near == {}


def test_a_colour_pull_a_cell_from_a_bound_is_near():
    from drawer_lib.articulation.handles import colour_handle

    # a 0.12 m bar (30 cells) against a longest pull of 0.122 m: half a cell to spare
    cfg = RectifyConfig(colour_max_len=0.122)
    near = {}
    pts = colour_handle(FRONT, _colour_front((0.48, 0.50, 0.20, 0.32)), cfg, near=near)
    assert pts is not None and near["why"] == "bound"
    assert near["a_u"] == pytest.approx(0.49 / 0.6, abs=0.02) and near["a_v"] == pytest.approx(0.26 / 0.4, abs=0.02)
    # 0.118 m allowed: the bar fails by half a cell, no pull is read, and the one it nearly was is named
    near = {}
    assert colour_handle(FRONT, _colour_front((0.48, 0.50, 0.20, 0.32)), RectifyConfig(colour_max_len=0.118),
                         near=near) is None
    assert near["why"] == "rival" and near["a_u"] == pytest.approx(0.49 / 0.6, abs=0.02)
    # two cells short: neither a pull nor near one
    near = {}
    assert colour_handle(FRONT, _colour_front((0.48, 0.50, 0.20, 0.32)), RectifyConfig(colour_max_len=0.11),
                         near=near) is None
    assert near == {}


def test_two_colour_pulls_alike_far_apart_are_near_and_a_small_one_is_not():
    from drawer_lib.articulation.handles import colour_handle

    left, right = (0.10, 0.12, 0.20, 0.32), (0.48, 0.50, 0.20, 0.32)
    near = {}
    pts = colour_handle(FRONT, _colour_front([left, (0.48, 0.50, 0.20, 0.33)]), RectifyConfig(), near=near)
    assert pts is not None and near["why"] == "rival"
    assert near["a_u"] == pytest.approx(0.11 / 0.6, abs=0.02)  # the left one, 30 cells against 32.5
    near = {}
    colour_handle(FRONT, _colour_front([(0.10, 0.12, 0.20, 0.24), right]), RectifyConfig(), near=near)
    assert near == {}  # a third of the chosen one's cells
    near = {}
    colour_handle(FRONT, _colour_front([(0.44, 0.46, 0.20, 0.32), right]), RectifyConfig(), near=near)
    assert near == {}  # as big, but 0.04 m beside it: the same hinge side


def test_sliding_needs_a_track_or_a_partner():
    from drawer_lib.articulation.config import TypesConfig
    from drawer_lib.articulation.decide import decide_by_score
    from drawer_lib.articulation.scoring import Evidence

    w = {k: {} for k in ("drawer", "door", "flap_top", "flap_bottom", "fixed")} | {"sliding": {"bias": 5.0}}
    ev = dict(handle=None, size=(0.5, 0.7), z_mid=1.8, stacked=0, beside_left=True, beside_right=True,
              partner=False, rail=0.0, carcass=None, labels={}, support=20)
    dec, terms = decide_by_score(Evidence(**ev), TypesConfig(), w)
    assert dec.family != "sliding" and "sliding" in terms["excluded"] and terms["scores"]["sliding"] == 5.0
    dec, terms = decide_by_score(Evidence(**(ev | {"rail": 1.2})), TypesConfig(), w)
    assert dec.family == "sliding" and terms["excluded"] == {}
    dec, _ = decide_by_score(Evidence(**ev), TypesConfig(sliding_needs_track=False), w)
    assert dec.family == "sliding"


def _painted_views(bars: list[tuple[float, float, float, float]]) -> list[View]:
    """``_views`` without handle masks, with images: the plane y = 0 wood-coloured, metal within
    each bar (x0, x1, z0, z1 in m) of FRONT."""
    import dataclasses

    out = []
    for v in _views(handle_in=set()):
        o, d = v.camera.rays()
        p = o + v.depth[..., None] * d  # _views' depth is the ray parameter to the plane: the point on it
        img = np.empty(v.depth.shape + (3,), np.uint8)
        img[:] = (115, 77, 51)
        for x0, x1, z0, z1 in bars:
            img[(p[..., 0] >= x0) & (p[..., 0] <= x1) & (p[..., 2] >= z0) & (p[..., 2] <= z1)] = (191, 191, 199)
        out.append(dataclasses.replace(v, image=img))
    return out


@pytest.mark.parametrize("bars, near", [([(0.17, 0.19, 1.0, 1.12)], False),
                                        ([(0.17, 0.19, 1.0, 1.12), (-0.19, -0.17, 1.0, 1.125)], True)],
                         ids=["one pull", "two pulls alike at either edge"])
def test_a_front_whose_colour_pull_had_no_margin_is_listed_and_marked(bars, near):
    """Through ``infer_parts``: a front whose masks show no pull gets one off its colours; with
    a second bar alike at the other edge the choice had no margin, and the decision lists
    ``near_colour`` and is ``low_margin``."""
    import trimesh

    from drawer_lib.articulation.config import ArticulateConfig
    from drawer_lib.articulation.infer import infer_parts
    from drawer_lib.perception.decompose import Segment, face_geometry

    panel = trimesh.creation.box(extents=(0.6, 0.019, 0.4)).subdivide().subdivide().subdivide()
    panel.apply_translation((0.0, 0.0095, 1.0))
    n = np.asarray(panel.face_normals)
    outer = np.nonzero(n[:, 1] < -0.99)[0]
    nrm, area, cen, frac = face_geometry(panel, outer, 30.0)
    seg = Segment(0, outer, 1.0, 8, {"front": 8}, frac > 0.6, nrm, area, cen)
    views = _painted_views(bars)
    cams = np.array([v.camera.center for v in views])
    parts, rep = infer_parts(panel, [seg], cams, ArticulateConfig(), views=views)
    row = next(r for r in rep if r.get("segment") == 0)
    assert row["handle"] is not None and row["handle"]["source"] == "colour"
    assert ("near_colour" in row) == near
    if near:
        assert row["near_colour"]["why"] == "rival" and row["low_margin"]
