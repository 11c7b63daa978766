"""Static collision boxes: greedy merging, the rotated grid, carving, the mesh fallback and the
fidelity metric, on synthetic occupancies and analytic SDFs."""

import math
from dataclasses import dataclass

import numpy as np
import pytest
import torch
import trimesh
from complete_fixtures import cabinet_parts, cabinet_scene

from drawer_lib.complete.config import CutConfig, StaticCollisionConfig
from drawer_lib.complete.cut import cut_parts
from drawer_lib.geometry.boxes import OrientedBox
from drawer_lib.complete.static_collision import (VoxelGrid, carve, collision_fidelity, dominant_yaw, merge_boxes,
                                                  static_collision, yaw_rotation)
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.bodies import box_shape

EXACT = StaticCollisionConfig(cell=0.04, shell_depth=0.0, fill_tol=0.0, min_island_voxels=0, skins=False)


def _cover(boxes, shape):
    """(union [X, Y, Z] bool, summed box volume in cells) of cell boxes [B, 2, 3]."""
    cov = np.zeros(shape, bool)
    for (x, y, z), (x1, y1, z1) in boxes:  # a test-side loop over boxes
        cov[x:x1, y:y1, z:z1] = True
    return cov, int(np.prod(boxes[:, 1] - boxes[:, 0], axis=1).sum())


@pytest.mark.parametrize("overlap", [True, False])
def test_two_overlapping_boxes_and_an_l_shape(overlap):
    occ = np.zeros((8, 8, 8), bool)
    occ[0:4, 0:4, 0:4] = True
    occ[2:6, 2:6, 2:6] = True
    b = merge_boxes(occ, overlap=overlap, fill_tol=0.0)
    cov, vol = _cover(b, occ.shape)
    assert len(b) == 4  # A; then B's rest as three slabs (x-run, y-run, the top layer)
    np.testing.assert_array_equal(cov, occ)
    if not overlap:
        assert vol == occ.sum()  # disjoint
    assert b[0].tolist() == [[0, 0, 0], [4, 4, 4]]

    L = np.zeros((7, 7, 3), bool)
    L[0:6, 0:2, 0:2] = True
    L[0:2, 2:6, 0:2] = True
    b = merge_boxes(L, overlap=overlap)
    assert sorted(map(lambda x: x.tolist(), b)) == [[[0, 0, 0], [6, 2, 2]], [[0, 2, 0], [2, 6, 2]]]


def test_random_occupancy_is_covered_exactly_and_tolerance_only_adds():
    rng = np.random.default_rng(0)
    occ = rng.random((20, 18, 16)) < 0.6
    occ[3:15, 2:12, 4:10] = True
    for overlap in (True, False):
        b = merge_boxes(occ, overlap=overlap)
        cov, vol = _cover(b, occ.shape)
        np.testing.assert_array_equal(cov, occ)
        assert overlap or vol == occ.sum()
    b = merge_boxes(occ, fill_tol=0.3)
    cov, _ = _cover(b, occ.shape)
    assert np.all(cov[occ]) and len(b) < len(merge_boxes(occ))
    assert len(merge_boxes(np.zeros((3, 3, 3), bool))) == 0
    assert merge_boxes(np.ones((5, 4, 3), bool)).tolist() == [[[0, 0, 0], [5, 4, 3]]]


# ------------------------------------------------------------------------- rotated analytic scene


@dataclass
class BoxesField:
    """An exact SDF of a union of boxes (``boxes``: (center [3], rotation [3, 3], half [3]))
    with a box [lo, hi] like a LoadedField."""

    boxes: list
    lo: np.ndarray
    hi: np.ndarray

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        out = None
        for c, R, h in self.boxes:
            q = (x.double() - torch.from_numpy(c)) @ torch.from_numpy(R)
            d = q.abs() - torch.from_numpy(h)
            s = d.clamp(min=0).norm(dim=-1) + d.max(-1).values.clamp(max=0)
            out = s if out is None else torch.minimum(out, s)
        return out.float()


def _rotated_scene(yaw_deg: float):
    R = yaw_rotation(math.radians(yaw_deg))
    solids = [((0.0, 0.0, 0.0), (0.4, 0.2, 0.8)), ((0.6, 0.0, 0.0), (1.0, 0.4, 0.4)), ((0.2, 0.6, 0.0), (0.6, 0.8, 0.2))]
    boxes, meshes = [], []
    shift = np.array([1.3, -0.7, 0.1])  # world offset: arbitrary, not on the grid
    for lo, hi in solids:
        lo, hi = np.array(lo), np.array(hi)
        c = R @ ((lo + hi) / 2) + shift
        boxes.append((c, R, (hi - lo) / 2))
        m = trimesh.creation.box(extents=hi - lo)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, c
        m.apply_transform(T)
        meshes.append(m)
    mesh = trimesh.util.concatenate(meshes)
    mesh = trimesh.Trimesh(*trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, 0.05), process=False)
    field = BoxesField(boxes, mesh.bounds[0] - 0.5, mesh.bounds[1] + 0.5)
    return mesh, field, boxes, shift


@pytest.mark.parametrize("yaw_deg", [20.0, 0.0, -37.0])
def test_rotated_scene_gives_one_box_per_solid(yaw_deg):
    mesh, field, solids, _ = _rotated_scene(yaw_deg)
    assert math.degrees(dominant_yaw(mesh, EXACT)) == pytest.approx(yaw_deg, abs=1e-6)
    # the grid starts at the mesh's lowest corner in the rotated frame, so the solids' faces
    # (multiples of the cell from it) lie on grid planes: each solid is exactly one box
    sc = static_collision(mesh, EXACT, field=field)
    assert len(sc.shapes) == 3
    got = sorted(sc.shapes, key=lambda s: tuple(np.round(s.box.center, 3)))
    want = sorted(solids, key=lambda s: tuple(np.round(s[0], 3)))
    for s, (c, R, h) in zip(got, want):
        np.testing.assert_allclose(s.box.center, c, atol=1e-6)
        np.testing.assert_allclose(s.box.half, h, atol=1e-6)
        np.testing.assert_allclose(s.box.rotation, R, atol=1e-9)
    fid = collision_fidelity(sc.shapes, mesh, n_points=3000)
    assert fid["chamfer_l1"] < 1e-5 and fid["n_shapes"] == 3
    # without the rotation the same scene needs a staircase of boxes
    if yaw_deg != 0.0:
        unaligned = static_collision(mesh, StaticCollisionConfig(cell=0.04, shell_depth=0.0, fill_tol=0.0,
                                                                 min_island_voxels=0, align=False), field=field)
        assert len(unaligned.shapes) > 10


def test_yaw_is_found_mod_90_degrees_despite_noise():
    mesh, _, _, _ = _rotated_scene(50.0)
    rng = np.random.default_rng(0)
    noisy = trimesh.Trimesh(mesh.vertices + rng.normal(scale=0.002, size=mesh.vertices.shape), mesh.faces, process=False)
    assert math.degrees(dominant_yaw(noisy, EXACT)) == pytest.approx(-40.0, abs=0.5)
    flat = trimesh.creation.box(extents=(1, 1, 1e-3))
    flat = trimesh.Trimesh(flat.vertices, flat.faces[np.abs(flat.face_normals[:, 2]) > 0.9], process=False)
    assert dominant_yaw(flat, EXACT) == 0.0  # no vertical faces


def test_carving_removes_the_swept_volume():
    occ = np.ones((30, 20, 10), bool)
    grid = VoxelGrid(occ, np.zeros(3), 0.04, np.eye(3))
    cav = OrientedBox(np.array([0.6, 0.4, 0.2]), yaw_rotation(0.3), np.array([0.2, 0.1, 0.1]))
    carved, n = carve(grid, [cav], inflate=0.02)
    idx = np.argwhere(grid.occ)
    inside = cav.contains(grid.centers(idx), 0.02)
    assert n == inside.sum() > 0
    np.testing.assert_array_equal(carved.occ[tuple(idx.T)], ~inside)
    # an interior's cavity given as a box Shape carves the same cells
    shape = box_shape(cav.center, cav.half, cav.rotation)
    carved2, n2 = carve(grid, [shape], inflate=0.02)
    assert n2 == n and np.array_equal(carved2.occ, carved.occ)
    with pytest.raises(InputError, match="neither"):
        carve(grid, [object()], 0.0)


def test_static_boxes_leave_the_parts_free_to_move():
    """On the cabinet: boxes from the mesh fallback, carved by the parts' sweeps: no box reaches
    into a swept volume by more than the carving's slack, and the closed carcass is solid."""
    scene = cabinet_scene()
    cut = cut_parts(scene.mesh, cabinet_parts(), CutConfig(), depths={"drawer_0": 0.5})
    cfg = StaticCollisionConfig(source="mesh", cell=0.04, shell_depth=0.0, fill_tol=0.0)
    sc = static_collision(cut.static, cfg, carvers=[p.sweep for p in cut.parts.values()])
    assert 10 < len(sc.shapes) < 400
    rng = np.random.default_rng(0)
    pts = []
    for s in sc.shapes:  # points inside every box (a test-side loop over boxes)
        u = rng.uniform(-1, 1, size=(50, 3)) * s.box.half
        pts.append(s.box.center + u @ s.box.rotation.T)
    P = np.concatenate(pts)
    slack = cfg.cell * (math.sqrt(3) / 2 - cfg.carve_inflate) + 1e-9  # a cell corner beyond the carved centre
    for p in cut.parts.values():
        assert not p.sweep.contains(P, inflate=-slack - p.sweep.grow).any(), p.id
    # the carcass below the top and beside the cavities is solid (filled below the up-facing top)
    probe = np.array([[0.3, 0.3, 0.25 + 0.0], [0.02, 0.3, 0.4]])
    from drawer_lib.geometry.boxes import boxes_contain

    inside = boxes_contain(probe, np.stack([s.box.center for s in sc.shapes]), np.stack([s.box.rotation for s in sc.shapes]),
                           np.stack([s.box.half for s in sc.shapes]))
    assert inside[1]  # the left carcass side, no part sweeps there


def test_fidelity_ignores_shared_faces():
    big = box_shape([0.0, 0.0, 0.5], [0.5, 0.25, 0.5])
    halves = [box_shape([-0.25, 0.0, 0.5], [0.25, 0.25, 0.5]), box_shape([0.25, 0.0, 0.5], [0.25, 0.25, 0.5])]
    mesh = trimesh.Trimesh(*big.triangles(), process=False)
    f1 = collision_fidelity([big], mesh, n_points=4000)
    f2 = collision_fidelity(halves, mesh, n_points=4000)
    assert f1["chamfer_l1"] < 1e-6 and f2["chamfer_l1"] < 1e-6  # the shared face at x = 0 is not sampled
    shifted = [box_shape([0.0, 0.0, 0.52], [0.5, 0.25, 0.5])]
    f3 = collision_fidelity(shifted, mesh, n_points=4000, free=lambda p: np.linalg.norm(p, axis=1) < 10)
    assert 0.003 < f3["chamfer_l1"] < 0.01 and f3["exposed_fraction"] == 1.0


def test_bad_inputs():
    mesh, field, _, _ = _rotated_scene(0.0)
    with pytest.raises(InputError, match="source: mesh"):
        static_collision(mesh, StaticCollisionConfig(), field=None)
    with pytest.raises(ConfigError):
        StaticCollisionConfig(cell=0.0)
    with pytest.raises(ConfigError):
        StaticCollisionConfig(source="voxels")
    far = BoxesField(field.boxes, field.lo + 100, field.hi + 100)
    with pytest.raises(InputError, match="outside the field"):
        static_collision(mesh, EXACT, field=far)
    with pytest.raises(ValueError, match="fill_tol"):
        merge_boxes(np.ones((2, 2, 2), bool), fill_tol=1.0)


def test_skins_keep_the_counter_above_a_carved_cavity():
    """A base cabinet (0.6 x 0.6 x 0.82 m) under a 4 cm counter, its door's cavity carved out
    (grown by a cell, as the stage does): the boxes lose the counter above it, the skins give
    it back — one thin box at the counter's height over the cabinet — and none lies inside the
    cavity or the door's sweep."""
    from drawer_lib.complete.static_collision import surface_skins

    carcass = trimesh.creation.box((0.6, 0.6, 0.82)).apply_translation((0.3, 0.3, 0.41))
    counter = trimesh.creation.box((1.2, 0.65, 0.04)).apply_translation((0.3, 0.32, 0.84))
    floor = trimesh.creation.box((3.0, 3.0, 0.02)).apply_translation((0.3, 0.0, -0.01))
    mesh = trimesh.util.concatenate([carcass, counter, floor])
    cavity = OrientedBox(np.array([0.3, 0.32, 0.45]), np.eye(3), np.array([0.28, 0.28, 0.37]))  # top at 0.82
    cfg = StaticCollisionConfig(source="mesh", cell=0.04, skins=False)
    sc = static_collision(mesh, cfg, carvers=[cavity])
    above = np.array([0.3, 0.3, 0.845])  # in the counter, above the cavity: carved away with it

    def inside(s, p):
        return bool(np.all(np.abs(np.asarray(s.box.rotation).T @ (p - np.asarray(s.box.center))) <= np.asarray(s.box.half)))

    assert not any(inside(s, above) for s in sc.shapes)
    skins = surface_skins(mesh, sc.grid.rotation, [cavity])
    tops = np.array([s.box.center[2] + s.box.half[2] for s in skins])
    on_counter = [s for s, t in zip(skins, tops) if abs(t - 0.86) < 0.006]
    assert on_counter, tops
    # the counter's skins cover the cabinet's footprint, thin, at the counter's top
    xy = np.array([[x, y] for x in np.linspace(0.05, 0.55, 6) for y in np.linspace(0.05, 0.55, 6)])
    covered = np.zeros(len(xy), bool)
    for s in on_counter:
        covered |= np.all(np.abs(xy - np.asarray(s.box.center)[:2]) <= np.asarray(s.box.half)[:2] + 1e-9, axis=1)
        assert s.box.half[2] == pytest.approx(0.005)
        assert not cavity.contains(np.asarray(s.box.center)[None]).any()
    assert covered.all()
    assert any(abs(t - 0.0) < 0.006 for t in tops)  # the floor too
    # with skins on, the stage's boxes include them
    sc2 = static_collision(mesh, StaticCollisionConfig(source="mesh", cell=0.04), carvers=[cavity])
    assert sc2.stats["n_skins"] == len(skins) and len(sc2.shapes) == len(sc.shapes) + len(skins)


def test_union_keeps_a_solid_without_volume_as_its_surface():
    """A hull that qhull's clean-up left open (a 1 cm sliver seen by a real capture) cannot go
    through the boolean union: it joins the union's surface as it is."""
    from drawer_lib.bodies import Shape
    from drawer_lib.complete.static_collision import union_mesh

    a, b = box_shape([0.0, 0.0, 0.5], [0.5, 0.25, 0.5]), box_shape([0.4, 0.0, 0.5], [0.5, 0.25, 0.5])
    c = box_shape([3.0, 0.0, 0.5], [0.1, 0.1, 0.1])
    v, f = c.triangles()

    class Open(Shape):  # a solid with one triangle missing
        def solid(self):
            return v, f[:-1]

    u = union_mesh([a, b, Open("box", box=c.box)])
    assert not u.is_volume and len(u.faces) == len(union_mesh([a, b]).faces) + len(f) - 1
    assert union_mesh([a, b]).is_volume and union_mesh([a, b]).volume == pytest.approx(1.4 * 0.5 * 1.0)
