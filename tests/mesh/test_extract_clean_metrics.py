"""Marching cubes on analytic SDFs, masks, clean-up and both decimators, grid fields, and the geometry
metrics (docs/formats.md#geometry) on analytic meshes."""

import math

import numpy as np
import pytest
import torch
import trimesh

from drawer_lib.errors import ConfigError, NonFiniteError
from drawer_lib.geometry.camera import Intrinsics
from drawer_lib.mesh.clean import CleanConfig, clean_mesh, fast_quadric, snap_vertices, unit_edge_scale
from drawer_lib.geometry.isosurface import crossing_cubes, cube_mask, frustum_mask, grid_field_mesh, seen_crossing_mask, grid_shape, marching_cubes_mesh, refine_levels, sdf_grid
from drawer_lib.metrics.geometry import MeshEvaluator
from drawer_lib.sdf.io import GridSDF

R = 0.5


def sphere_sdf(x: torch.Tensor) -> torch.Tensor:
    return x.norm(dim=-1) - R


def sphere_mesh(cell=0.01, coarse=4):
    lo, hi = np.full(3, -0.8), np.full(3, 0.8)
    v = sdf_grid(sphere_sdf, lo, hi, cell, coarse)
    return marching_cubes_mesh(v, lo, cell)


@pytest.mark.parametrize("coarse", [1, 4])
def test_sphere_area_within_one_percent_and_normals_point_out(coarse):
    m = sphere_mesh(coarse=coarse)
    assert abs(m.area - 4 * math.pi * R**2) / (4 * math.pi * R**2) < 0.01
    c = m.triangles_center
    assert (np.einsum("ij,ij->i", m.face_normals, c) > 0).mean() > 0.999
    assert abs(np.linalg.norm(m.vertices, axis=1).mean() - R) < 1e-3


def test_coarse_to_fine_grid_equals_dense_near_the_surface():
    lo, hi, cell = np.full(3, -0.8), np.full(3, 0.8), 0.02
    dense = sdf_grid(sphere_sdf, lo, hi, cell, 1)
    c2f = sdf_grid(sphere_sdf, lo, hi, cell, 4)
    near = np.abs(dense) < 2 * cell
    np.testing.assert_allclose(c2f[near], dense[near], atol=1e-6)
    assert np.all(np.sign(c2f[~near]) == np.sign(dense[~near]))


@pytest.mark.parametrize("coarse", [2, 6, 8])
def test_every_coarse_to_fine_ladder_is_exact_near_the_surface_and_keeps_the_sign(coarse):
    lo, hi, cell = np.full(3, -0.8), np.full(3, 0.8), 0.02
    dense = sdf_grid(sphere_sdf, lo, hi, cell, 1)
    c2f = sdf_grid(sphere_sdf, lo, hi, cell, coarse)
    near = np.abs(dense) < 2 * cell
    np.testing.assert_allclose(c2f[near], dense[near], atol=1e-6)
    assert np.all(np.sign(c2f[~near]) == np.sign(dense[~near]))


def test_refine_levels_halve_while_even():
    assert refine_levels(1) == [1]
    assert refine_levels(4) == [4, 2, 1]
    assert refine_levels(8) == [8, 4, 2, 1]
    assert refine_levels(6) == [6, 3, 1]
    assert refine_levels(5) == [5, 1]


def test_coarse_to_fine_evaluates_a_fraction_of_the_dense_grid():
    lo, hi, cell, n = np.full(3, -0.8), np.full(3, 0.8), 0.01, [0]

    def counted(x):
        n[0] += len(x)
        return sphere_sdf(x)

    sdf_grid(counted, lo, hi, cell, 4)
    assert n[0] < 0.15 * np.prod(grid_shape(lo, hi, cell))


def test_level_key_offsets_the_surface():
    lo, hi, cell = np.full(3, -0.8), np.full(3, 0.8), 0.01
    v = sdf_grid(sphere_sdf, lo, hi, cell, 4)
    m = marching_cubes_mesh(v, lo, cell, level=0.1)
    assert abs(np.linalg.norm(m.vertices, axis=1).mean() - (R + 0.1)) < 2e-3


def test_no_crossing_or_empty_mask_gives_an_empty_mesh():
    v = np.ones((5, 5, 5), np.float32)
    assert len(marching_cubes_mesh(v, np.zeros(3), 0.1).faces) == 0
    v[2, 2, 2] = -1
    assert len(marching_cubes_mesh(v, np.zeros(3), 0.1, mask=np.zeros(v.shape, bool)).faces) == 0
    with pytest.raises(NonFiniteError):
        marching_cubes_mesh(np.full((3, 3, 3), np.nan), np.zeros(3), 0.1)


def test_marching_cubes_mask_is_read_at_the_cube_s_highest_corner():
    """The convention cube_mask and crossing_cubes rely on: one negative vertex makes 8 crossing
    cubes, and scikit-image computes exactly those whose highest corner is masked."""
    v = np.ones((6, 6, 6), np.float32)
    v[2, 2, 2] = -1.0
    hits = []
    for idx in np.ndindex(*v.shape):
        m = np.zeros(v.shape, bool)
        m[idx] = True
        if len(marching_cubes_mesh(v, np.zeros(3), 1.0, mask=m).faces):
            hits.append(idx)
    assert hits == [tuple(int(i) for i in np.argwhere(crossing_cubes(v))[n]) for n in range(8)]
    assert {h for h in hits} == {(2 + a, 2 + b, 2 + c) for a in (0, 1) for b in (0, 1) for c in (0, 1)}


def test_cube_mask_keeps_cubes_with_all_corners_known():
    ok = np.ones((4, 4, 4), bool)
    ok[3, 3, 3] = False
    m = cube_mask(ok)
    assert m.shape == ok.shape and not m[3, 3, 3] and m[2, 2, 2] and m[1:, 1:, 1:].sum() == 26
    assert not m[0].any() and not m[:, 0].any() and not m[:, :, 0].any()  # a cube's highest corner is never at 0


def test_grid_field_never_meshes_unobserved_cells():
    """A TSDF-like grid: the sphere observed only for z < 0.1; no vertex may come from the
    unknown region or from the border between known and unknown."""
    lo, cell = np.full(3, -0.8), 0.02
    v = sdf_grid(sphere_sdf, lo, np.full(3, 0.8), cell, 1).astype(np.float32)
    z = lo[2] + cell * np.arange(v.shape[2])
    v[:, :, z >= 0.1] = np.nan
    g = GridSDF(lo, cell, v)
    obs = g.observed()
    m = marching_cubes_mesh(np.where(obs, v, g.unknown), lo, cell, 0.0, cube_mask(obs))
    assert len(m.faces) > 0 and m.vertices[:, 2].max() < 0.1
    assert abs(np.linalg.norm(m.vertices, axis=1) - R).max() < 0.005
    # interpolation returns `unknown` wherever a corner is unobserved
    s = g.sdf(torch.tensor([[0.0, 0.0, -R], [0.0, 0.0, 0.3]], dtype=torch.float32))
    assert abs(float(s[0])) < 1e-3 and float(s[1]) == g.unknown


def test_frustum_mask_marks_what_a_camera_sees():
    intr = Intrinsics(fx=50.0, fy=50.0, cx=50.0, cy=40.0, width=100, height=80)
    w2c = np.eye(4)[None]  # camera at the origin looking along +z
    lo, cell = np.array([-1.0, -1.0, -1.0]), 0.1
    shape = grid_shape(lo, np.array([1.0, 1.0, 2.0]), cell)
    m = frustum_mask(lo, shape, cell, intr, w2c)
    k = lambda p: tuple(np.rint((np.array(p) - lo) / cell).astype(int))  # noqa: E731
    assert m[k([0, 0, 1])] and not m[k([0, 0, -0.5])] and not m[k([1, 0, 0.5])]
    # testing only some vertices gives the full mask there and False elsewhere (chunked too)
    where = np.random.default_rng(0).random(shape) < 0.3
    for chunk in (1 << 20, 97):
        np.testing.assert_array_equal(frustum_mask(lo, shape, cell, intr, w2c, where=where, chunk=chunk), m & where)


def test_crossing_cubes_against_a_loop_over_cubes():
    v = np.random.default_rng(1).normal(size=(5, 6, 4)).astype(np.float32)
    v[0, 0, 0] = 0.25  # a corner exactly at the level counts as crossing
    ref = np.zeros(v.shape, bool)
    for i, j, k in np.ndindex(4, 5, 3):
        c = v[i : i + 2, j : j + 2, k : k + 2]
        ref[i + 1, j + 1, k + 1] = c.min() <= 0.25 and c.max() >= 0.25
    np.testing.assert_array_equal(crossing_cubes(v, 0.25), ref)
    assert crossing_cubes(v, 0.25)[1, 1, 1]
    assert crossing_cubes(np.ones((1, 4, 4)), 0.0).shape == (1, 4, 4)


def test_frustum_mask_only_on_crossing_cubes_gives_the_same_mesh():
    """The mesh stage tests the frustum only where a cube straddles the level: the same mesh,
    vertex for vertex, as with the full mask (a camera sees part of the sphere)."""
    lo, cell = np.full(3, -0.8), 0.02
    v = sdf_grid(sphere_sdf, lo, np.full(3, 0.8), cell, 4)
    intr = Intrinsics(fx=150.0, fy=150.0, cx=50.0, cy=40.0, width=100, height=80)
    w2c = np.eye(4)[None]
    w2c[0, 2, 3] = 1.2  # sphere centre 1.2 m ahead, a narrow view of its front
    full = frustum_mask(lo, v.shape, cell, intr, w2c)
    near = seen_crossing_mask(v, lo, cell, intr, w2c)
    np.testing.assert_array_equal(near, frustum_mask(lo, v.shape, cell, intr, w2c, where=crossing_cubes(v)))
    assert near.sum() < 0.2 * full.sum()
    a, b = marching_cubes_mesh(v, lo, cell, mask=full), marching_cubes_mesh(v, lo, cell, mask=near)
    assert 0 < len(a.faces) < 0.5 * len(sphere_mesh(cell=cell).faces)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)


def test_grid_field_mesh_equals_the_full_masks():
    """grid_field_mesh tests the frustum only at observed crossing cubes: the mesh of the plain
    observed-and-seen mask, vertex for vertex."""
    lo, cell = np.full(3, -0.8), 0.02
    v = sdf_grid(sphere_sdf, lo, np.full(3, 0.8), cell, 1).astype(np.float32)
    v[:, :, lo[2] + cell * np.arange(v.shape[2]) >= 0.1] = np.nan
    g = GridSDF(lo, cell, v)
    intr = Intrinsics(fx=150.0, fy=150.0, cx=50.0, cy=40.0, width=100, height=80)
    w2c = np.eye(4)[None]
    w2c[0, 2, 3] = 1.2
    obs = g.observed()
    full = cube_mask(obs) & frustum_mask(lo, obs.shape, cell, intr, w2c)
    a = marching_cubes_mesh(np.where(obs, v, g.unknown), lo, cell, 0.0, full)
    b = grid_field_mesh(g, intr, w2c)
    assert len(a.faces) > 0
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)


def test_clean_drops_small_components_and_simplifies():
    big = trimesh.creation.icosphere(subdivisions=4, radius=0.5)
    small = trimesh.creation.icosphere(subdivisions=1, radius=0.01)
    small.apply_translation([2.0, 0, 0])
    m = trimesh.util.concatenate([big, small])
    out, counts = clean_mesh(m, CleanConfig(min_component_diag=0.05, target_faces=1000))
    assert counts["faces_in"] == len(m.faces) and counts["faces_components"] == len(big.faces)
    assert counts["faces_out"] <= 1000 and counts["faces_out"] >= 900
    assert np.abs(out.vertices).max() < 0.6  # the small component is gone
    assert abs(out.area - big.area) / big.area < 0.02
    out2, _ = clean_mesh(big, CleanConfig(min_component_diag=0.0, target_faces=0, remesh_iters=2, remesh_edge=0.05))
    e = out2.edges_unique_length
    assert 0.02 < np.median(e) < 0.08 and abs(out2.area - big.area) / big.area < 0.03


@pytest.mark.parametrize("decimator", ["fast_quadric", "pymeshlab"])
def test_both_decimators_keep_a_sphere_within_a_millimetre(decimator):
    m = sphere_mesh(cell=0.01)  # ~94k faces
    out, counts = clean_mesh(m, CleanConfig(min_component_diag=0.0, target_faces=5000, decimator=decimator))
    assert 4750 <= counts["faces_out"] <= 5000
    r = np.linalg.norm(out.vertices, axis=1)
    assert np.abs(r - R).max() < 1e-3 and np.abs(r - R).mean() < 4e-4  # slow reference: the exact sphere
    assert (np.einsum("ij,ij->i", out.face_normals, out.triangles_center) > 0).mean() > 0.999
    assert abs(out.area - m.area) / m.area < 0.01


def test_fast_quadric_is_deterministic_and_the_same_in_any_power_of_two_unit():
    m = sphere_mesh(cell=0.02)
    v, f = fast_quadric(m.vertices, m.faces, 2000)
    v2, f2 = fast_quadric(m.vertices, m.faces, 2000)
    np.testing.assert_array_equal(v, v2)
    np.testing.assert_array_equal(f, f2)
    for k in (-20, 20):  # ~1 um and ~1000 km spheres
        vk, fk = fast_quadric(m.vertices * 2.0**k, m.faces, 2000)
        np.testing.assert_array_equal(fk, f)
        np.testing.assert_array_equal(vk / 2.0**k, v)
    # another unit (centimetres): not bit-identical, as good
    vc, fc = fast_quadric(m.vertices * 100.0, m.faces, 2000)
    assert len(fc) == len(f) and np.abs(np.linalg.norm(vc / 100.0, axis=1) - R).max() < 2e-3


def test_unit_edge_scale_and_degenerate_meshes():
    v = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0]], float)
    assert unit_edge_scale(v, np.array([[0, 1, 2]])) == 128.0  # median edge 1 cm -> x128
    assert unit_edge_scale(np.zeros((3, 3)), np.array([[0, 1, 2]])) == 1.0  # all zero-length
    m = sphere_mesh(cell=0.05)
    faces = np.concatenate([m.faces, m.faces[:50, [0, 0, 1]]])  # zero-area faces among the input
    out, counts = clean_mesh(trimesh.Trimesh(m.vertices, faces, process=False), CleanConfig(min_component_diag=0.0, target_faces=500))
    assert counts["faces_out"] <= 500 and np.isfinite(out.vertices).all()
    assert np.all(out.area_faces > 0)
    bad = m.vertices.copy()
    bad[3] = np.nan
    with pytest.raises(NonFiniteError, match="non-finite"):
        fast_quadric(bad, m.faces, 100)
    with pytest.raises(ConfigError, match="decimator"):
        CleanConfig(decimator="quadric")


def test_clean_of_an_empty_mesh_is_empty():
    out, counts = clean_mesh(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)), CleanConfig())
    assert len(out.faces) == 0 and counts["faces_out"] == 0


def _views_around(n=8, dist=2.0):
    """Cameras on a circle looking at the origin (OpenCV frames)."""
    w2c = []
    for a in np.linspace(0, 2 * np.pi, n, endpoint=False):
        c = np.array([dist * np.cos(a), dist * np.sin(a), 0.3])
        f = -c / np.linalg.norm(c)
        r = np.cross(f, [0, 0, 1.0])
        r /= np.linalg.norm(r)
        d = np.cross(f, r)
        Rw = np.stack([r, d, f], 1)  # columns: camera axes in world
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Rw.T, -Rw.T @ c
        w2c.append(T)
    return Intrinsics(fx=80.0, fy=80.0, cx=60.0, cy=45.0, width=120, height=90), np.stack(w2c)


def test_metrics_of_a_mesh_against_itself_are_zero_and_see_a_shift():
    gt = trimesh.creation.icosphere(subdivisions=5, radius=R)
    intr, w2c = _views_around()
    ev = MeshEvaluator(gt, intr, w2c, n_points=20_000)
    r = ev(gt)
    assert r["chamfer_l1"] < 1e-6 and r["fscore_1cm"] == 1.0 and r["normal_consistency"] > 0.9999
    # the analytic sphere from marching cubes against the exact icosphere: ~0
    r = ev(sphere_mesh())
    assert r["chamfer_l1"] < 1e-3 and r["fscore_1cm"] > 0.999
    shifted = gt.copy()
    shifted.vertices = shifted.vertices * (R + 0.005) / R  # concentric, 5 mm larger
    r = ev(shifted)
    assert r["chamfer_l1"] == pytest.approx(0.005, rel=0.05)
    assert r["fscore_1cm"] == 1.0
    grown = gt.copy()
    grown.vertices = grown.vertices * (R + 0.015) / R
    assert ev(grown)["fscore_1cm"] < 0.01 and ev(grown)["fscore_2cm"] == 1.0


def test_metrics_refuse_empty_or_unseen_predictions():
    gt = trimesh.creation.icosphere(subdivisions=3, radius=R)
    intr, w2c = _views_around()
    ev = MeshEvaluator(gt, intr, w2c, n_points=5000)
    with pytest.raises(ValueError, match="empty"):
        ev(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)))
    inside = trimesh.creation.icosphere(subdivisions=2, radius=0.1)  # hidden behind the GT surface
    with pytest.raises(ValueError, match="no predicted surface"):
        ev(inside)


def test_a_mesh_moved_by_its_last_bits_simplifies_the_same_once_snapped():
    from scipy.spatial import cKDTree

    from drawer_lib.perturb import jitter_mesh

    # an irregular wavy surface of 2 m, 20k faces, simplified to 8k (PyMeshLab's greedy collapse)
    rng = np.random.default_rng(0)
    x, y = np.meshgrid(np.linspace(0, 2, 101), np.linspace(0, 2, 101))
    x, y = x + rng.uniform(-0.004, 0.004, x.shape), y + rng.uniform(-0.004, 0.004, y.shape)
    z = 0.02 * np.sin(7 * x) * np.cos(5 * y) + rng.normal(0, 0.001, x.shape)
    i = np.arange(100)[:, None] * 101 + np.arange(100)[None, :]
    f = np.concatenate([np.stack([i, i + 1, i + 101], -1).reshape(-1, 3),
                        np.stack([i + 1, i + 102, i + 101], -1).reshape(-1, 3)])
    mesh = trimesh.Trimesh(np.stack([x.ravel(), y.ravel(), z.ravel()], 1), f, process=False)
    cfg = CleanConfig(min_component_diag=0.0, target_faces=8000, decimator="pymeshlab")

    def faces_kept(q: float) -> list[float]:  # the share of the simplified faces that noise of 1e-7 m leaves in place
        ref, _ = clean_mesh(snap_vertices(mesh, q), cfg)
        tree = cKDTree(np.asarray(ref.triangles_center))
        return [float((tree.query(np.asarray(clean_mesh(snap_vertices(jitter_mesh(mesh, 1e-7, seed), q), cfg)[0]
                                             .triangles_center))[0] < 1e-6).mean()) for seed in range(3)]

    raw, snapped = faces_kept(0.0), faces_kept(1e-3)
    assert min(snapped) >= 0.95 and np.mean(raw) <= np.mean(snapped) - 0.1, (raw, snapped)
    s = snap_vertices(mesh, 1e-3)
    assert np.abs(s.vertices - mesh.vertices).max() <= 0.5e-3 + 1e-12
    assert snap_vertices(s, 1e-3).vertices.tolist() == s.vertices.tolist()  # idempotent
    assert snap_vertices(mesh, 0.0) is mesh
    with pytest.raises(ValueError, match="grid"):
        snap_vertices(mesh, float("nan"))
