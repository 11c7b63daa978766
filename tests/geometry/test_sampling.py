"""Points on triangles: the per-face low-discrepancy points against a random uniform draw."""

import numpy as np
import pytest
import trimesh

from drawer_lib.articulation.fronts import MAX_SAMPLES, sample_points
from drawer_lib.geometry.sampling import local_triangle_points, sample_triangles

TRI = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [[2.0, 0, 0], [2.5, 0, 0], [2, 0, 0.5]]])


def grid(n: int, step: float) -> np.ndarray:
    """2 n^2 congruent right triangles tiling an n x n grid of squares ``step`` (m) wide, z = 0.3."""
    i, j = (a.ravel() * step for a in np.meshgrid(np.arange(n), np.arange(n)))
    c = np.stack([i, j, np.full_like(i, 0.3)], -1)
    dx, dy = np.array([step, 0, 0]), np.array([0, step, 0])
    lower = np.stack([c, c + dx, c + dy], 1)
    upper = np.stack([c + dx, c + dx + dy, c + dy], 1)
    return np.concatenate([lower, upper])


def test_each_triangle_gets_its_area_times_density_points_inside_it():
    p, f = local_triangle_points(TRI, 1000.0)
    assert np.bincount(f).tolist() == [500, 125]  # areas 0.5 and 0.125 m^2
    a = p[f == 0]
    assert np.all(a[:, 0] >= 0) and np.all(a[:, 1] >= 0) and np.all(a.sum(1) <= 1 + 1e-12) and np.all(a[:, 2] == 0)


def test_the_points_spread_as_a_uniform_draw_does():
    # shares of the triangle's area (slow reference: 400k uniform random points)
    p, _ = local_triangle_points(TRI[:1], 4000.0)
    q, _ = sample_triangles(TRI[:1], 400_000, np.random.default_rng(0))
    for region in (lambda x: x[:, 0] < 0.5, lambda x: x[:, 1] < 0.2, lambda x: x.sum(1) > 0.8,
                   lambda x: (x[:, 0] < 0.3) & (x[:, 1] < 0.3)):
        assert region(p).mean() == pytest.approx(region(q).mean(), abs=0.01)
    assert p.mean(0) == pytest.approx([1 / 3, 1 / 3, 0], abs=0.005)


def test_faces_finer_than_a_point_keep_their_share():
    # 5000 faces of 0.3 points each: rounding would give none, a uniform draw 1500 on average
    tri = grid(50, 0.01)
    density = 0.3 / 5e-5
    _, f = local_triangle_points(tri, density)
    assert len(f) == pytest.approx(1500, rel=0.05)
    assert set(np.bincount(f, minlength=len(tri)).tolist()) == {0, 1}


def test_congruent_faces_do_not_share_their_points_places():
    # one point per face of a regular grid: its barycentric place spreads over the triangle as a
    # uniform draw's does, instead of sitting at one spot (rows of points a row filter would take
    # for a counter edge)
    tri = grid(30, 0.02)
    p, f = local_triangle_points(tri, 1.0 / 2e-4)
    assert np.array_equal(f, np.arange(len(tri)))
    u = (p - tri[:, 0]) @ np.array([1.0, 0, 0]) / 0.02
    lower = np.arange(len(tri)) < len(tri) // 2
    q, _ = sample_triangles(tri[:1], 100_000, np.random.default_rng(0))
    assert np.quantile(u[lower], [0.25, 0.5, 0.75]) == pytest.approx(np.quantile(q[:, 0] / 0.02, [0.25, 0.5, 0.75]),
                                                                      abs=0.05)


def test_round_off_keeps_the_counts_and_barely_moves_the_points():
    tri = grid(20, 0.013)
    moved = tri + np.random.default_rng(0).normal(0.0, 1e-9, tri.shape)
    (p, f), (q, g) = local_triangle_points(tri, 30000.0), local_triangle_points(moved, 30000.0)
    assert np.array_equal(f, g)
    assert np.abs(p - q).max() < 1e-6


def test_changing_one_triangle_moves_its_points_only():
    moved = TRI.copy()
    moved[1, 2] += [0.0, 0.0, 0.1]
    (p, f), (q, g) = local_triangle_points(TRI, 1000.0), local_triangle_points(moved, 1000.0)
    assert np.array_equal(p[f == 0], q[g == 0])
    assert not np.array_equal(p[f == 1], q[g == 1])
    # the random draw moves every point when one triangle changes
    r, s = (sample_triangles(t, 500, np.random.default_rng(0))[0] for t in (TRI, moved))
    assert not np.array_equal(r[:10], s[:10])


def test_zero_area_and_non_finite_triangles_get_no_points():
    bad = np.array([[[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0.0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]])
    p, f = local_triangle_points(bad, 1e4)
    assert len(p) == 0 and len(f) == 0
    with pytest.raises(ValueError, match="density"):
        local_triangle_points(TRI, -1.0)


def test_sample_points_local_keeps_the_centroids_and_the_cap():
    mesh = trimesh.Trimesh(TRI.reshape(-1, 3), np.arange(6).reshape(2, 3), process=False)
    p, f = sample_points(mesh, np.array([0, 1]), 1000.0, seed=0, local=True)
    assert np.allclose(p[:2], TRI.mean(1)) and np.bincount(f).tolist() == [501, 126]
    p, _ = sample_points(mesh, np.array([0, 1]), 1e9, seed=0, local=True)  # capped near MAX_SAMPLES
    assert abs(len(p) - 2 - MAX_SAMPLES) <= 2
