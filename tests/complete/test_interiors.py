"""Fitted interior templates (drawer_lib/complete/interiors/) on analytic cabinets.

Fixture: a carcass against a wall (plane y = 0) whose fronts face -y with their outer faces at
y = -(D + tf): a door on x in [0, 0.6] beside two stacked drawers on x in [0.6, 1.2]; the mesh
evidence is what a capture of the closed cabinet sees (the wall above it, the counter top, the
floor, the fronts), sampled on a 1 cm grid.
"""

import mujoco
import numpy as np
import pytest
import trimesh

from drawer_lib.complete.interiors.config import FitConfig, InteriorsConfig, TemplateConfig, TextureConfig
from drawer_lib.complete.interiors.drawer_rule import drawer_rule_depth, drawer_rule_interiors
from drawer_lib.complete.interiors.evidence import DepthEvidence
from drawer_lib.complete.interiors.fit import build_interiors, fit_depths
from drawer_lib.complete.interiors.templates import build_template, check_part, template_kind
from drawer_lib.complete.interiors.texture import interior_colours
from drawer_lib.geometry.boxes import overlap_volume
from drawer_lib.errors import ConfigError, NonFiniteError
from drawer_lib.io.parts import Axis, Front, Part, PartsFile

D = 0.56  # carcass depth behind the fronts' inner faces (m)
TF = 0.02  # front thickness (the config's default)
Y = -(D + TF)  # plane of the fronts' outer faces
OUT, UX = (0.0, -1.0, 0.0), (1.0, 0.0, 0.0)
CFG = InteriorsConfig()


def _front(x0, x1, z0, z1, y=Y, normal=OUT, u=UX) -> Front:
    c = np.array([(x0 + x1) / 2, y, (z0 + z1) / 2])
    return Front(tuple(c.tolist()), normal, u, (x1 - x0, z1 - z0))


def door(pid="door", x0=0.0015, x1=0.5985, z0=0.1015, z1=0.7985, y=Y) -> Part:
    f = _front(x0, x1, z0, z1, y)
    return Part(pid, "revolute", Axis((x0, y, f.center[2]), (0.0, 0.0, -1.0)), (0.0, 1.57), f)


def drawer(pid, x0, x1, z0, z1, travel=0.4, y=Y) -> Part:
    f = _front(x0, x1, z0, z1, y)
    return Part(pid, "prismatic", Axis(f.center, OUT), (0.0, travel), f)


def _grid(lo, hi, step=0.01):
    axes = [np.arange(a + step / 2, b, step) if b > a else np.array([a]) for a, b in zip(lo, hi)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def cabinet_points(x0=0.0, x1=1.2, top=0.8, with_wall=True):
    """(points, normals) of what a capture of the closed cabinet sees."""
    pts, nrm = [], []

    def add(p, n):
        pts.append(p)
        nrm.append(np.broadcast_to(np.asarray(n, float), p.shape))

    if with_wall:
        add(_grid([x0 - 0.5, 0.0, top + 0.04], [x1 + 0.5, 0.0, 2.2]), (0, -1, 0))  # wall above the counter
        add(_grid([x0, Y - 0.02, top + 0.04], [x1, 0.0, top + 0.04]), (0, 0, 1))  # counter top
    add(_grid([x0 - 0.5, -2.0, 0.0], [x1 + 0.5, Y, 0.0]), (0, 0, 1))  # floor
    add(_grid([x0, Y, 0.1], [x1, Y, top]), (0, -1, 0))  # the fronts themselves
    return np.concatenate(pts), np.concatenate(nrm)


def kitchen():
    parts = [door(), drawer("drawer_lo", 0.6015, 1.1985, 0.1015, 0.4485),
             drawer("drawer_hi", 0.6015, 1.1985, 0.4515, 0.7985)]
    return parts, *cabinet_points()


@pytest.fixture(scope="module")
def fitted():
    parts, P, N = kitchen()
    return parts, build_interiors(parts, P, N, CFG)


# ---------------------------------------------------------------------------------------------


def test_fitted_depths_match_carcass(fitted):
    parts, res = fitted
    by = {x.part_id: x for x in res.interiors}
    assert by["door"].template == "cabinet" and by["door"].body == "static"
    assert abs(by["door"].depth - D) < 0.01  # the cavity fills the carcass
    for pid in ("drawer_lo", "drawer_hi"):
        it = by[pid]
        assert it.template == "drawer" and it.body == pid
        assert abs(it.depth + CFG.template.drawer_back_clearance - D) < 0.01  # the box stops short of the back
        assert it.record["evidence"] == "wall" and it.record["active"] == []
    assert by["door"].shelves == 1  # 0.7 m of height, one shelf per 35 cm
    # the template lies behind its front, inside the carcass
    for it in res.interiors:
        ys = np.concatenate([w.box.center[None] for w in it.walls])[:, 1]
        assert np.all(ys > Y) and np.all(ys < 0.0)


def test_adjacent_interiors_do_not_interpenetrate(fitted):
    _, res = fitted
    its = res.interiors
    for i in range(len(its)):
        for j in range(i + 1, len(its)):
            assert overlap_volume(its[i].outer, its[j].outer) < 1e-9, (its[i].part_id, its[j].part_id)
            assert overlap_volume(its[i].occupied, its[j].occupied) < 1e-9
            for a in its[i].walls:
                for b in its[j].walls:
                    ba, bb = a.box, b.box
                    assert overlap_volume(ba, bb) < 1e-9


def test_drawer_box_at_least_its_travel():
    """A drawer travelling 0.54 m: deeper than the carcass (0.56) minus the runner clearance
    (0.04) suggests, still inside the carcass: the travel wins and the record says so."""
    parts, P, N = kitchen()
    parts[1] = drawer("drawer_lo", 0.6015, 1.1985, 0.1015, 0.4485, travel=0.54)
    res = build_interiors(parts, P, N, CFG)
    it = res.interiors[1]
    assert it.depth >= 0.54 - 1e-4
    assert "drawer_travel" in it.record["active"]
    assert it.depth + it.start <= D + TF + 1e-3  # and still inside the carcass


def test_missing_evidence_gives_the_default():
    parts, _, _ = kitchen()
    res = build_interiors(parts, np.zeros((0, 3)), np.zeros((0, 3)), CFG)
    by = {x.part_id: x for x in res.interiors}
    assert res.fit.default_source == "config"
    assert by["door"].depth == pytest.approx(CFG.fit.default_depth, abs=1e-4)
    clear = CFG.template.drawer_back_clearance
    assert by["drawer_hi"].depth == pytest.approx(CFG.fit.default_depth - clear, abs=1e-4)
    assert by["door"].record["default_source"] == "config" and by["door"].record["measured_depth"] is None


def test_missing_evidence_takes_the_median_of_its_run(fitted):
    """A door in the same plane but far from the wall seen: the carcass depth of its run."""
    parts, P, N = kitchen()
    lone = door("lone", 4.0015, 4.5985)
    res = build_interiors(parts + [lone], P, N, CFG)
    it = {x.part_id: x for x in res.interiors}["lone"]
    assert it.record["evidence"] == "none" and it.record["default_source"] == "coplanar_median"
    assert abs(it.depth - D) < 0.01


def test_drawer_rule():
    d, lo = door(), drawer("dr", 0.6, 1.2, 0.1, 0.45)
    assert drawer_rule_depth(d) == pytest.approx(1.5 * d.front.size[0])
    assert drawer_rule_depth(lo) == pytest.approx(1.25 * 0.6)
    f = _front(0.0, 0.6, 1.5, 1.85)  # a flap hinged at its top: 1.5 x its extent across the hinge
    flap = Part("flap", "revolute", Axis((0.3, Y, 1.85), (-1.0, 0.0, 0.0)), (0.0, 1.7), f)
    assert drawer_rule_depth(flap) == pytest.approx(1.5 * 0.35)
    rule = drawer_rule_interiors([d, lo], CFG)
    assert rule[0].free_depth == pytest.approx(1.5 * d.front.size[0] - 0.02)
    assert rule[1].free_depth == pytest.approx(1.25 * 0.6 - 0.02)
    assert rule[0].wall == pytest.approx(0.02) and rule[0].shelves == 0


@pytest.mark.parametrize("part", [door("huge", 0.0, 2.0, 0.0, 2.0), drawer("tiny", 0.0, 0.1, 0.5, 0.6, travel=0.08),
                                  drawer("sliver", 0.0, 0.1, 0.5, 0.51, travel=0.05)], ids=lambda p: p.id)
def test_extreme_fronts_give_valid_boxes(part):
    res = build_interiors([part], *cabinet_points(part.front.center[0] - 1, part.front.center[0] + 1, top=2.0), CFG)
    (it,) = res.interiors
    assert np.isfinite(it.depth) and CFG.fit.min_depth <= it.depth <= CFG.fit.max_depth
    for w in [s.box for s in it.walls] + [it.free, it.outer]:
        assert np.all(np.isfinite(w.center)) and np.all(w.half > 0)
        assert abs(np.linalg.det(w.rotation) - 1) < 1e-9
    assert it.free_depth > 0


def test_nan_front_names_the_part():
    bad = Part("door_7", "revolute", Axis((0.0, Y, 0.5), (0.0, 0.0, -1.0)), (0.0, 1.57),
               Front((np.nan, Y, 0.5), OUT, UX, (0.6, 0.7)))
    with pytest.raises(NonFiniteError, match="door_7"):
        check_part(bad)
    with pytest.raises(NonFiniteError, match="door_7"):
        build_interiors([door(), bad], *cabinet_points(), CFG)
    with pytest.raises(NonFiniteError, match="door_7"):
        drawer_rule_depth(bad)


# ---------------------------------------------------------------------------------------------


def test_corner_cavity_is_shortened_until_it_clears():
    """Two runs at 90 degrees: ``a`` faces -y (its cavity fills y in [-0.6, 0], x in [0, 0.6]);
    ``b`` faces +x at x = 1.3 over y in [-0.6, 0] (its cavity runs toward -x). The mesh shows a wall 0.9 m behind ``b``
    (seen through a gap): at that depth ``b``'s cavity would run into ``a``'s, so the fit
    shortens the weaker-supported ``b`` to where they meet (x = 0.6) and keeps ``a``."""
    fa = Front((0.3, -0.62, 0.45), OUT, UX, (0.6, 0.7))
    fb = Front((1.3, -0.3, 0.45), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.6, 0.7))
    pa = Part("a", "revolute", Axis((0.0, -0.62, 0.45), (0.0, 0.0, -1.0)), (0.0, 1.57), fa)
    pb = Part("b", "revolute", Axis((1.3, -0.6, 0.45), (0.0, 0.0, -1.0)), (0.0, 1.57), fb)

    def ev(pid, wall, n):
        return DepthEvidence(part_id=pid, template="cabinet", reason="", wall=wall, wall_points=n, caps={},
                             carcass_depth=None, tracks=[], blocking=None, blocking_id=None, start=TF, extent=wall,
                             support=n, source="wall", floor_z=0.0)

    cfg = InteriorsConfig(fit=FitConfig(overlap_tol=0.0))
    fit = fit_depths([pa, pb], [ev("a", 0.6, 5000), ev("b", 0.9, 200)], cfg)
    da, db = fit.depths
    assert "overlap:a" in fit.records[1]["active"]
    assert da == pytest.approx(0.58, abs=0.01)  # well supported: kept
    assert 0.6 < db < 0.69  # shortened to where the cavities meet (0.68), not flattened
    ta = build_template(pa, "cabinet", TF, float(da), cfg.template)
    tb = build_template(pb, "cabinet", TF, float(db), cfg.template)
    assert overlap_volume(ta.outer, tb.outer) / 0.42 < 1e-3  # < 1 mm of intrusion over the front's area


def test_template_kinds_and_tracks():
    tc = TemplateConfig()
    oven = Part("oven", "revolute", Axis((0.3, Y, 0.2), (-1.0, 0.0, 0.0)), (0.0, 1.57), _front(0.0, 0.6, 0.2, 0.75))
    assert template_kind(oven, 0.0, tc)[0] == "appliance"
    assert template_kind(oven, None, tc)[0] == "cabinet"  # no floor seen: not classified as an oven
    high = Part("flap", "revolute", Axis((0.3, Y, 1.5), (-1.0, 0.0, 0.0)), (0.0, 1.57), _front(0.0, 0.6, 1.5, 2.1))
    assert template_kind(high, 0.0, tc)[0] == "cabinet"
    # a sliding pair: the outer panel's interior starts behind the inner panel's track
    inner = Part("in", "prismatic", Axis((0.75, Y, 0.45), (-1.0, 0.0, 0.0)), (0.0, 0.4), _front(0.49, 1.0, 0.1, 0.8))
    outer = Part("out", "prismatic", Axis((0.25, Y - 0.025, 0.45), (1.0, 0.0, 0.0)), (0.0, 0.4),
                 _front(0.0, 0.51, 0.1, 0.8, y=Y - 0.025))
    res = build_interiors([inner, outer], *cabinet_points(), CFG)
    ev = {e.part_id: e for e in res.evidence}
    assert ev["out"].tracks == ["in"] and ev["out"].start == pytest.approx(0.025 + TF)
    a, b = res.interiors
    assert a.template == b.template == "cabinet"
    assert overlap_volume(a.outer, b.outer) < 1e-9  # the 2 cm where the panels overlap is split
    assert abs(a.start + a.depth - (D + TF)) < 0.01 and abs(b.start + b.depth - (D + TF + 0.025)) < 0.01


def test_abutting_sliding_pair_still_shares_tracks():
    """Panels that meet edge to edge at q = 0 (no overlap) pass each other when opened: the
    outer one's interior still starts behind the inner one's track (its swept rectangle)."""
    inner = Part("in", "prismatic", Axis((0.75, Y, 0.45), (-1.0, 0.0, 0.0)), (0.0, 0.45), _front(0.5, 1.0, 0.1, 0.8))
    outer = Part("out", "prismatic", Axis((0.25, Y - 0.025, 0.45), (1.0, 0.0, 0.0)), (0.0, 0.45),
                 _front(0.0, 0.5, 0.1, 0.8, y=Y - 0.025))
    res = build_interiors([inner, outer], *cabinet_points(), CFG)
    ev = {e.part_id: e for e in res.evidence}
    assert ev["out"].tracks == ["in"] and ev["out"].start == pytest.approx(0.025 + TF)
    assert ev["in"].tracks == [] and ev["in"].start == pytest.approx(TF)
    # a drawer beside a panel is not a track: only in-plane slides sweep across their neighbours
    d = drawer("d", 0.5, 1.0, 0.1, 0.8, y=Y + 0.025)
    ev = {e.part_id: e for e in build_interiors([d, outer], *cabinet_points(), CFG).evidence}
    assert ev["out"].tracks == []


def test_evidence_from_caps_when_the_wall_is_hidden():
    """A tall unit: no wall visible above it, but its end panel shows its depth."""
    part = door("tall", 0.0015, 0.5985, 0.1, 2.1)
    P, N = cabinet_points(0.0, 0.6, top=2.1, with_wall=False)
    side = _grid([0.6, Y + TF, 0.1], [0.6, 0.0, 2.1])
    res = build_interiors([part], np.concatenate([P, side]), np.concatenate([N, np.tile([1.0, 0, 0], (len(side), 1))]),
                          CFG)
    (it,) = res.interiors
    assert it.record["evidence"] == "cap:right"
    assert abs(it.start + it.depth - (D + TF)) < 0.02


# ---------------------------------------------------------------------------------------------


def test_interior_colours(fitted):
    _, res = fitted
    it = {x.part_id: x for x in res.interiors}["door"]
    rng = np.random.default_rng(0)
    front = np.clip(rng.normal([0.6, 0.4, 0.2], 0.02, (100, 3)), 0, 1)
    tx = interior_colours(it, front, TextureConfig())
    assert tx.source == "front" and set(tx.base) == set(it.wall_names)
    assert np.all(tx.base["back"] < tx.base["left"])  # deeper is darker
    assert np.all(tx.base["top"] < tx.base["bottom"])  # the ceiling is shaded
    assert np.all(tx.base["left"] <= np.array([0.6, 0.4, 0.2]) + 0.02)
    assert tx.patch.shape == (32, 32, 3) and abs(tx.patch.mean() - 1) < 0.02
    assert interior_colours(it, front[:3], TextureConfig()).source == "default"  # too few samples
    grey = interior_colours(it, front[:0], TextureConfig())
    assert grey.source == "default" and np.allclose(grey.base["bottom"], grey.base["bottom"][0])
    with pytest.raises(ConfigError, match="matfuse"):
        interior_colours(it, front, TextureConfig(texturer="learned"))


def test_config_validation():
    with pytest.raises(ConfigError, match="wall"):
        TemplateConfig(wall=0.0)
    with pytest.raises(ConfigError, match="texturer"):
        TextureConfig(texturer="diffusion")
    with pytest.raises(ConfigError, match="min_depth"):
        FitConfig(min_depth=1.0, max_depth=0.5)


def test_gt_interior_depth_on_an_analytic_cabinet():
    """A closed cabinet: front panel (instance 1, 2 cm, with a handle bar) 0.5 m in front of the
    back panel; the GT depth is the gap between them, the front's geometry skipped."""
    from drawer_lib.metrics.interiors import GtInteriorProbe, interior_depth_error

    panel = trimesh.creation.box(extents=(0.6, 0.02, 0.7))
    panel.apply_translation((0.3, Y + 0.01, 0.45))
    handle = trimesh.creation.box(extents=(0.02, 0.03, 0.3))
    handle.apply_translation((0.5, Y - 0.015, 0.45))
    back = trimesh.creation.box(extents=(0.6, 0.02, 0.7))
    back.apply_translation((0.3, Y + TF + 0.5 + 0.01, 0.45))
    mesh = trimesh.util.concatenate([panel, handle, back])
    inst = np.concatenate([np.full(len(panel.faces), 1), np.full(len(handle.faces), 1), np.zeros(len(back.faces), int)])
    f = _front(0.0, 0.6, 0.1, 0.8)
    with_inst = GtInteriorProbe(mesh, inst).depth(f, 1)
    assert with_inst["depth"] == pytest.approx(0.5, abs=1e-3)
    assert with_inst["front_thickness"] == pytest.approx(TF, abs=1e-3)
    assert GtInteriorProbe(mesh).depth(f)["depth"] == pytest.approx(0.5, abs=1e-3)  # first two hits = the panel
    # a solid body right behind the front (a microwave): depth 0, whatever the order of coincident faces
    body = trimesh.creation.box(extents=(0.6, 0.3, 0.7))
    body.apply_translation((0.3, Y + TF + 0.15, 0.45))
    solid = trimesh.util.concatenate([panel, handle, body])
    inst2 = np.concatenate([np.full(len(panel.faces) + len(handle.faces), 1), np.zeros(len(body.faces), int)])
    assert GtInteriorProbe(solid, inst2).depth(f, 1)["depth"] == pytest.approx(0.0, abs=1e-3)
    gt = Part("g", "revolute", Axis((0.0, Y, 0.45), (0.0, 0.0, -1.0)), (0.0, 1.57), f, instance_id=1)
    pred = door("p", 0.0, 0.6, 0.1, 0.8)
    fit = [build_template(pred, "cabinet", TF, 0.45, CFG.template)]
    rule = drawer_rule_interiors([pred], CFG)
    rows = interior_depth_error(PartsFile((pred,)), mesh, PartsFile((gt,)), {x.part_id: (x.template, x.free_depth) for x in fit},
                                {x.part_id: x.free_depth for x in rule}, inst)
    r = rows["p"]
    assert r["gt"] == "g" and r["fitted"] == pytest.approx(0.43)
    assert r["fitted_error"] == pytest.approx(0.07, abs=2e-3)
    assert r["rule_error"] == pytest.approx(0.88 - 0.5, abs=2e-3)


def test_a_sliding_panel_slides_clear_of_its_cabinet_walls():
    """The cavity's sides start ``cavity_clearance`` behind the panel: a sliding panel (a 2 cm
    panel box at q = 0, behind its outer face) driven along its plane in MuJoCo with contacts on
    travels its range; with the sides flush against the panel (clearance 0) it sticks."""
    import math

    from drawer_lib.bodies import PartBody, TwinModel
    from drawer_lib.complete.cut import front_box
    from drawer_lib.bodies import Shape
    from drawer_lib.sim.config import ContactConfig, SimConfig
    from drawer_lib.sim.mjcf import build_spec, compile_spec, part_index, set_drives

    p = Part("sliding_0", "prismatic", Axis((0.3, Y, 0.45), (1.0, 0.0, 0.0)), (0.0, 0.3), _front(0.0, 0.6, 0.1, 0.8))

    def travel(clearance: float) -> float:
        it = build_template(p, "cabinet", TF, 0.5, TemplateConfig(cavity_clearance=clearance))
        n = np.asarray(p.front.normal)
        near = [float((w.box.center - np.asarray(p.front.center)) @ n + np.abs(w.box.rotation.T @ n) @ w.box.half)
                for w, nm in zip(it.walls, it.wall_names) if nm in ("left", "right", "top", "bottom")]
        np.testing.assert_allclose(near, -(TF + clearance), atol=1e-9)  # every side starts that far behind
        panel = Shape("box", box=front_box(p.front, -TF, 0.0, 0.005))
        body = PartBody(p.id, p.kind, np.asarray(p.axis.origin), np.asarray(p.axis.direction), p.limits, [], [panel],
                        600.0)
        cfg = SimConfig(contact=ContactConfig(part_static=True, part_part=True))
        m = set_drives(compile_spec(build_spec(TwinModel([], list(it.walls), [body], []), cfg)), True)
        ix = part_index(m, p.id)
        d = mujoco.MjData(m)
        d.ctrl[ix["actuator"]] = m.actuator_ctrlrange[ix["actuator"], 1]
        mujoco.mj_step(m, d, nstep=math.ceil(1.5 / m.opt.timestep))
        return float(d.qpos[ix["qpos"]])

    assert travel(0.003) == pytest.approx(0.3, abs=0.005)
    assert travel(0.0) < 0.05
