"""Cutting parts out of the scene mesh: bodies, cavities, swept volumes (analytic cabinet)."""

import math
import time
from dataclasses import replace

import numpy as np
import pytest
import trimesh
from complete_fixtures import (PANEL_T, Scene, box_mesh, cabinet_parts, cabinet_scene, door_part, drawer_part,
                               in_prismatic_sweep, in_revolute_sweep, rect_y)

from drawer_lib.complete.config import CutConfig
from drawer_lib.complete.cut import cut_parts, part_depth, part_solid, sweep_part
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.parts import Axis, Front, Part, PartsFile

CFG = CutConfig()
DEPTH = 0.5  # drawer box depth given to the cut (outer face to the box's back)


@pytest.fixture(scope="module")
def cabinet():
    scene = cabinet_scene()
    t = time.perf_counter()
    res = cut_parts(scene.mesh, cabinet_parts(), CFG, depths={"drawer_0": DEPTH})
    return scene, res, time.perf_counter() - t


def _points_of(mesh: trimesh.Trimesh, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(centroids [K, 3], vertices [K, 3, 3]) of ``faces``."""
    tri = np.asarray(mesh.vertices)[np.asarray(mesh.faces)[faces]]
    return tri.mean(1), tri


def _drawer_boxes(depth):
    panel = (np.array([0.05, -PANEL_T, 0.5]), np.array([0.55, 0.0, 0.7]))
    inset = CFG.drawer_inset
    box = (np.array([0.05 + inset, 0.0, 0.5 + inset]), np.array([0.55 - inset, depth - PANEL_T, 0.7 - inset]))
    return [panel, box]


def _in_drawer_sweep(P, depth, travel=0.4):
    return np.any([in_prismatic_sweep(P, lo, hi, [0, -1, 0], travel) for lo, hi in _drawer_boxes(depth)], axis=0)


def _in_door_sweep(P):
    door = door_part()
    lo, hi = np.array([0.05, -PANEL_T, 0.05]), np.array([0.55, 0.0, 0.45])
    return in_revolute_sweep(P, lo, hi, np.asarray(door.axis.origin), np.asarray(door.axis.direction), door.limits[1])


def test_bodies_hold_their_panels_and_handles(cabinet):
    scene, res, _ = cabinet
    g = scene.groups
    for pid, names in (("drawer_0", ("drawer_panel", "drawer_handle")), ("door_0", ("door_panel", "door_handle"))):
        body = set(res.parts[pid].body_faces.tolist())
        for name in names:
            assert set(g[name].tolist()) <= body, f"{pid} misses faces of {name}"
        # anything else in the body lies in the margin band around the rectangle (a frame's rim)
        own = np.concatenate([g[n] for n in names])
        extra = np.array(sorted(body - set(own.tolist())), dtype=np.int64)
        cen, _ = _points_of(scene.mesh, extra)
        part = res.parts[pid]
        f = (drawer_part() if pid == "drawer_0" else door_part()).front
        d = np.maximum(np.abs(cen[:, 0] - f.center[0]) - f.size[0] / 2, np.abs(cen[:, 2] - f.center[2]) - f.size[1] / 2)
        assert len(extra) == 0 or (d.min() >= -1e-9 and d.max() <= CFG.margin + 1e-9)
        assert len(part.body.faces) == len(body)
    assert res.parts["drawer_0"].depth == DEPTH and res.parts["drawer_0"].depth_source == "given"


def test_no_static_point_inside_any_swept_volume(cabinet):
    scene, res, _ = cabinet
    cen, tri = _points_of(scene.mesh, res.static_faces)
    P = np.concatenate([cen, tri.reshape(-1, 3)])
    assert not _in_drawer_sweep(P, DEPTH).any()
    assert not _in_door_sweep(P).any()
    # and the static mesh the result carries is exactly those faces
    np.testing.assert_allclose(np.sort(res.static.triangles_center, 0), np.sort(cen, 0))


def test_cavity_removes_exactly_what_the_parts_pass_through(cabinet):
    scene, res, _ = cabinet
    g = scene.groups
    cav_d = set(res.parts["drawer_0"].cavity_faces.tolist())
    cav_o = set(res.parts["door_0"].cavity_faces.tolist())
    # the floater in the door's swing goes, all of it; the shelf inside the drawer's box goes where
    # the box is and stays elsewhere; the floor, wall, top and sides stay whole
    assert set(g["floater"].tolist()) <= cav_o
    shelf = g["shelf"]
    in_box = np.isin(shelf, list(cav_d))
    assert 0 < in_box.sum() < len(shelf)
    cen, _ = _points_of(scene.mesh, shelf[in_box])
    x0, x1 = 0.05 + CFG.drawer_inset, 0.55 - CFG.drawer_inset
    assert np.all((cen[:, 0] > x0 - 0.03) & (cen[:, 0] < x1 + 0.03))
    for name in ("floor", "wall", "top", "side_l", "side_r", "frame_l", "frame_r", "frame_b", "frame_t"):
        assert not (set(g[name].tolist()) & (cav_d | cav_o)), f"{name} lost faces to a cavity"
    # the cut is conservative by at most the growth: every removed face comes within it of the solid
    cen, tri = _points_of(scene.mesh, np.array(sorted(cav_d)))
    near = np.zeros(len(cen), bool)
    for lo, hi in _drawer_boxes(DEPTH):
        lo2, hi2 = lo - 2 * CFG.sweep_tol, hi + 2 * CFG.sweep_tol
        Pk = np.concatenate([cen[:, None], tri], 1)  # [K, 4, 3]
        near |= in_prismatic_sweep(Pk.reshape(-1, 3), lo2, hi2, [0, -1, 0], 0.4).reshape(-1, 4).any(1)
    assert near.all()


def test_faces_partition_into_static_bodies_and_cavities(cabinet):
    scene, res, wall_s = cabinet
    ids = [res.static_faces] + [p.body_faces for p in res.parts.values()] + [p.cavity_faces for p in res.parts.values()]
    allf = np.concatenate(ids)
    assert len(allf) == len(np.unique(allf)) == len(scene.mesh.faces)
    st = res.stats()
    assert st["parts"]["door_0"]["n_q"] >= 100 and st["parts"]["drawer_0"]["n_q"] >= 60
    print(f"\ncabinet: {len(scene.mesh.faces)} faces, cut in {wall_s:.3f} s: {st['parts']}")


def test_measured_carcass_depth_is_the_default_and_keeps_the_wall():
    scene = cabinet_scene()
    res = cut_parts(scene.mesh, cabinet_parts(), CFG)
    d = res.parts["drawer_0"]
    # the wall behind (facing the room) is 0.62 behind the outer face; minus the clearance
    assert d.depth_source == "measured"
    assert d.depth == pytest.approx(0.62 - CFG.drawer_back_clearance, abs=2e-3)
    assert not set(scene.groups["wall"].tolist()) & set(d.cavity_faces.tolist())
    # carcass depth recorded by articulate wins over measuring
    res2 = cut_parts(scene.mesh, cabinet_parts(carcass=0.3), CFG)
    assert res2.parts["drawer_0"].depth == pytest.approx(0.3 - CFG.drawer_back_clearance)
    assert res2.parts["drawer_0"].depth_source == "carcass"


def test_sampled_sweep_contains_the_exact_one():
    """The grown samples cover the motion between them: dense random points inside the exact
    swept volume of the door (fine oracle) are all inside the sampled one."""
    door = door_part()
    sw = sweep_part(door, CFG.panel_thickness, CFG)
    rng = np.random.default_rng(0)
    P = rng.uniform([-0.05, -0.6, 0.0], [0.6, 0.05, 0.5], size=(20000, 3))
    exact = _in_door_sweep(P)
    assert exact.sum() > 500
    assert sw.contains(P)[exact].all()
    # and it is tight: points farther than ~2 x the growth from the exact volume are outside
    lo, hi = np.array([0.05, -PANEL_T, 0.05]), np.array([0.55, 0.0, 0.45])
    g = 2.5 * sw.grow
    far = ~in_revolute_sweep(P, lo - g, hi + g, np.asarray(door.axis.origin), np.asarray(door.axis.direction),
                             door.limits[1], n_q=1500)
    assert not sw.contains(P)[far].any()


# ------------------------------------------------------------------------------------ extremes


def _wall_with_front(w: float, h: float, edge: float, wall_y: float = 0.0) -> Scene:
    return Scene({"wall": rect_y(-0.5 - w, 0.5 + w, 0.0, h + 0.4, wall_y, -1, max(edge, 0.05)),
                  "panel": box_mesh([-w / 2, -PANEL_T, 0.2], [w / 2, 0.0, 0.2 + h], edge)})


def test_tiny_two_centimetre_drawer():
    s = _wall_with_front(0.02, 0.02, 0.004)
    f = Front((0.0, -PANEL_T, 0.21), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.02, 0.02))
    p = Part("drawer_t", "prismatic", Axis(f.center, f.normal), (0.0, 0.05), f, extra={"carcass_depth": 0.1})
    res = cut_parts(s.mesh, PartsFile((p,)), CFG)
    pc = res.parts["drawer_t"]
    assert set(s.groups["panel"].tolist()) <= set(pc.body_faces.tolist())
    boxes = part_solid(p, pc.depth, CFG)
    assert all(np.all(b.half > 0) for b in boxes)  # the inset never turns the box inside out
    cen, tri = _points_of(s.mesh, res.static_faces)
    assert not pc.sweep.contains(np.concatenate([cen, tri.reshape(-1, 3)]), inflate=-CFG.sweep_tol).any()


def test_huge_two_and_a_half_metre_door():
    w, h = 2.5, 2.4
    s = _wall_with_front(w, h, 0.05, wall_y=0.01)  # 1 cm behind the panel
    s = Scene({"wall": s.mesh.submesh([s.groups["wall"]], append=True),
               "panel": s.mesh.submesh([s.groups["panel"]], append=True),
               "floater": box_mesh([0.5, -1.5, 1.0], [0.6, -1.4, 1.1], 0.02)})
    f = Front((0.0, -PANEL_T, 0.2 + h / 2), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (w, h))
    from drawer_lib.articulation.joints import hinge_axis

    p = Part("door_big", "revolute", hinge_axis(f, "left"), (0.0, math.pi / 2), f)
    t = time.perf_counter()
    res = cut_parts(s.mesh, PartsFile((p,)), CFG)
    dt = time.perf_counter() - t
    pc = res.parts["door_big"]
    assert pc.sweep.n_q > 600 and pc.sweep.grow == pytest.approx(CFG.sweep_tol)
    assert set(s.groups["floater"].tolist()) <= set(pc.cavity_faces.tolist())
    assert not set(s.groups["wall"].tolist()) & set(pc.cavity_faces.tolist())
    assert set(s.groups["panel"].tolist()) <= set(pc.body_faces.tolist())
    assert dt < 10
    # capped samples: the growth rises so that the sweep still covers the motion
    capped = sweep_part(p, CFG.panel_thickness, CutConfig(max_q_samples=50))
    assert capped.n_q == 50 and capped.grow > CFG.sweep_tol
    assert capped.grow == pytest.approx(math.pi / 2 * math.hypot(w, PANEL_T) / 49 / 2, rel=1e-6)


def test_zero_area_faces_and_zero_range_limits():
    scene = cabinet_scene()
    m = scene.mesh
    V = np.asarray(m.vertices)
    nv = len(V)
    # degenerate faces: a point inside the drawer box (all three corners equal) and a collinear one outside
    extra_v = np.array([[0.3, 0.3, 0.6], [2.0, 0.0, 0.0], [2.1, 0.0, 0.0], [2.2, 0.0, 0.0]])
    extra_f = np.array([[nv, nv, nv], [nv + 1, nv + 2, nv + 3]])
    mesh = trimesh.Trimesh(np.concatenate([V, extra_v]), np.concatenate([m.faces, extra_f]), process=False)
    F = len(m.faces)
    res = cut_parts(mesh, cabinet_parts(), CFG, depths={"drawer_0": DEPTH})
    assert F in set(res.parts["drawer_0"].cavity_faces.tolist())
    assert F + 1 in set(res.static_faces.tolist())
    # a zero-width range sweeps the closed solid only
    f = door_part().front
    p = Part("door_z", "revolute", door_part().axis, (0.0, 0.0), f)
    sw = sweep_part(p, 0.02, CFG)
    assert sw.n_q == 1 and len(sw.q) == 1


def test_bad_inputs_raise_naming_the_input():
    scene = cabinet_scene()
    with pytest.raises(InputError, match="unknown articulated parts"):
        cut_parts(scene.mesh, cabinet_parts(), CFG, depths={"nope": 0.3})
    with pytest.raises(InputError, match="drawer_0"):
        cut_parts(scene.mesh, cabinet_parts(), CFG, depths={"drawer_0": float("nan")})
    V = np.asarray(scene.mesh.vertices).copy()
    V[3] = np.nan
    with pytest.raises(InputError, match="non-finite"):
        cut_parts(trimesh.Trimesh(V, scene.mesh.faces, process=False), cabinet_parts(), CFG)
    with pytest.raises(InputError, match="object_0"):
        sweep_part(Part("object_0", "rigid", center=(0, 0, 0), bounds=((0, 0, 0), (1, 1, 1))), 0.1, CFG)
    with pytest.raises(ConfigError):
        CutConfig(sweep_tol=0.0)
    assert part_depth(door_part(), CFG) == (CFG.panel_thickness, "panel")
    assert part_depth(drawer_part(), CFG) == (CFG.drawer_default_depth, "default")


# ------------------------------------------------------------------ a whole procedural kitchen


def _exact_in_sweep(P, part, depth):
    """Exact: points [N, 3] that the part's solid (part_solid) passes through over its range,
    each box shrunk by the cut's tolerance (``sweep_tol``); in each box's own frame."""
    hit = np.zeros(len(P), bool)
    o, k = np.asarray(part.axis.origin, np.float64), np.asarray(part.axis.direction, np.float64)
    for b in part_solid(part, depth, CFG):
        R, c = np.asarray(b.rotation), np.asarray(b.center)
        half = np.maximum(np.asarray(b.half) - CFG.sweep_tol, 0.0)
        local = (P - c) @ R  # world -> box frame (columns of R are the box axes)
        if part.kind == "prismatic":
            hit |= in_prismatic_sweep(local, -half, half, R.T @ k, part.limits[1])
        else:  # n_q 600: at most 1.6 mm between samples at 0.6 m radius, below the 3 mm shrink
            hit |= in_revolute_sweep(local, -half, half, R.T @ (o - c), R.T @ k, part.limits[1], n_q=600)
    return hit


@pytest.fixture(scope="module")
def kitchen():
    """kitchen_small's GT surface where its parts move, remeshed to <= 3 cm edges (about a
    reconstruction's triangles: the GT's boxes have faces as large as the counter), and its GT
    parts."""
    from omegaconf import OmegaConf

    from drawer_lib.config.typed import to_typed
    from drawer_lib.synth.config import SynthConfig
    from drawer_lib.synth.gt import layout_mesh, layout_parts
    from drawer_lib.synth.layout import sample_layout
    from helpers import ROOT

    synth = OmegaConf.load(ROOT / "conf" / "scene" / "kitchen_small.yaml").synth
    layout = sample_layout(to_typed(SynthConfig, synth, "synth", strict=False))
    mesh, _ = layout_mesh(layout)
    parts = layout_parts(layout)
    # only what the parts can reach: the fronts' bounds grown by their largest size (the room's
    # far walls, floor and ceiling would be millions of 3 cm triangles)
    fr = [p.front for p in parts.parts if p.articulated]
    reach = max(max(f.size) for f in fr) + 0.1
    lo = np.min([f.center for f in fr], 0) - reach
    hi = np.max([f.center for f in fr], 0) + reach
    for axis in range(3):
        for sign, at in ((1.0, lo), (-1.0, hi)):
            n = np.zeros(3)
            n[axis] = sign
            mesh = mesh.slice_plane(at * np.abs(n), n, cap=False)
    v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=0.03, max_iter=20)
    c = v[f].mean(1)
    near = np.zeros(len(f), bool)
    for fr_ in fr:  # each front's own reach
        r = max(fr_.size) + 0.1
        near |= np.all(np.abs(c - np.asarray(fr_.center)) <= r, axis=1)
    return trimesh.Trimesh(v, f[near], process=False), parts


def _with_blobs(mesh: trimesh.Trimesh, parts) -> trimesh.Trimesh:
    """``mesh`` plus a 1.5 cm ball of stray geometry (as reconstructions leave) in the middle of
    each part's panel when opened half way: in the part's path, so the cut must remove it."""
    from drawer_lib.io.parts import joint_motion

    blobs = [mesh]
    for p in parts.parts:
        if p.articulated:
            R, t = joint_motion(p, 0.5 * (p.limits[0] + p.limits[1]))
            c = np.asarray(p.front.center) - 0.01 * np.asarray(p.front.normal)
            blobs.append(trimesh.creation.icosphere(2, 0.015).apply_translation(R @ c + t))
    return trimesh.util.concatenate(blobs)


def test_whole_kitchen_no_static_face_inside_any_swept_volume(kitchen):
    """Every drawer, door, flap and sliding panel of a procedural kitchen, each part shifted
    6 mm sideways and 6 mm out of its GT place (as detections are), with stray geometry in each
    one's path: no static face has its centroid or a vertex in the exact swept volume of any
    part."""
    mesh, parts = kitchen
    s = 0.006
    moved = []
    for p in parts.parts:
        if not p.articulated:
            moved.append(p)
            continue
        d = s * (np.asarray(p.front.u) + np.asarray(p.front.normal))
        f = Front(tuple(np.asarray(p.front.center) + d), p.front.normal, p.front.u, p.front.size)
        moved.append(replace(p, axis=Axis(tuple(np.asarray(p.axis.origin) + d), p.axis.direction), front=f))
    pf = PartsFile(tuple(moved))
    mesh = _with_blobs(mesh, pf)
    res = cut_parts(mesh, pf, CFG)
    cen, _ = _points_of(mesh, res.static_faces)
    P = np.concatenate([cen, np.asarray(mesh.vertices)[np.unique(np.asarray(mesh.faces)[res.static_faces])]])
    arts = [p for p in pf.parts if p.articulated]
    assert {p.kind for p in arts} >= {"prismatic", "revolute"} and len(arts) >= 8
    for p in arts:
        # the cut's sampled sweep contains the exact one (test_sampled_sweep_contains_the_exact_one):
        # only points within its bounds need the exact test
        lo, hi = res.parts[p.id].sweep.bounds(0.01)
        near = np.flatnonzero(np.all((P >= lo) & (P <= hi), axis=1))
        inside = _exact_in_sweep(P[near], p, res.parts[p.id].depth)
        assert not inside.any(), f"{p.id}: {inside.sum()} static points in its swept volume"
        assert len(res.parts[p.id].body_faces) > 0, p.id
    # every stray ball left the static mesh: into a cavity, or a part's body when it lies in
    # another part's front slab (the sliding panels overlap)
    n_blob = len(mesh.faces) - len(kitchen[0].faces)
    assert not np.isin(np.arange(len(mesh.faces) - n_blob, len(mesh.faces)), res.static_faces).any()
    assert sum(len(pc.cavity_faces) for pc in res.parts.values()) >= n_blob * (len(arts) - 2) / len(arts)
