import numpy as np
import pytest
import trimesh

from drawer_lib.errors import ConfigError
from drawer_lib.perturb import displace_along_normals, smooth_field


def grid_plane(n=120, size=4.0):
    """A flat z = 0 grid [n x n vertices] of side ``size`` m, normals +z."""
    xs = np.linspace(0, size, n)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(n * n)], 1)
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    f = np.concatenate([np.stack([a, a + n, a + 1], 1), np.stack([a + 1, a + n, a + n + 1], 1)])
    return trimesh.Trimesh(v, f, process=False)


def test_zero_rms_is_the_identity():
    m = grid_plane(20)
    out, d = displace_along_normals(m, 0.0, 0.1)
    assert np.array_equal(out.vertices, m.vertices) and np.array_equal(out.faces, m.faces)
    assert not d.any()


def test_plane_moves_along_its_normal_with_the_requested_rms_and_zero_mean():
    m = grid_plane()
    out, d = displace_along_normals(m, 0.01, 0.1, seed=3)
    dv = np.asarray(out.vertices) - np.asarray(m.vertices)
    assert np.abs(dv[:, :2]).max() == 0.0  # only along the normal (+z)
    np.testing.assert_allclose(dv[:, 2], d)
    # a 4 m plane holds ~40 wavelengths a side: the spatial mean and rms approach the ensemble's
    assert abs(d.mean()) < 0.1 * 0.01
    assert np.sqrt((d ** 2).mean()) == pytest.approx(0.01, rel=0.15)


def test_the_field_is_smooth_at_the_wavelength():
    """E[(d(x) - d(y))^2] = 2 rms^2 (1 - exp(-r^2 / 2 l^2)) for points r apart (Gaussian kernel)."""
    rng = np.random.default_rng(0)
    rms, ell = 1.0, 0.1
    x = rng.uniform(0, 5, (5000, 3))
    for r in (0.02, 0.1, 0.3):
        u = rng.normal(size=x.shape)
        y = x + r * u / np.linalg.norm(u, axis=1, keepdims=True)
        msd = np.mean((smooth_field(x, rms, ell, seed=1, n_features=1024) - smooth_field(y, rms, ell, seed=1, n_features=1024)) ** 2)
        expect = 2 * rms ** 2 * (1 - np.exp(-r ** 2 / (2 * ell ** 2)))
        assert msd == pytest.approx(expect, rel=0.2), (r, msd, expect)


@pytest.mark.parametrize("scale", [1e-6, 1e4])
def test_tiny_and_huge_scenes_give_the_same_field_in_units_of_the_wavelength(scale):
    x = np.random.default_rng(2).uniform(0, 1, (500, 3))
    ref = smooth_field(x, 1.0, 0.2, seed=5)
    got = smooth_field(x * scale, scale, 0.2 * scale, seed=5) / scale
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, ref, atol=1e-9)


def test_deterministic_per_seed():
    x = np.random.default_rng(2).uniform(0, 1, (50, 3))
    np.testing.assert_array_equal(smooth_field(x, 0.01, 0.1, seed=7), smooth_field(x, 0.01, 0.1, seed=7))
    assert not np.allclose(smooth_field(x, 0.01, 0.1, seed=7), smooth_field(x, 0.01, 0.1, seed=8))


def test_zero_area_faces_and_unreferenced_vertices_stay_put_without_nan():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 2, 2], [3, 3, 3], [4, 4, 4], [9, 9, 9.0]])
    f = np.array([[0, 1, 2], [3, 4, 5]])  # a real face, a degenerate (collinear) one; vertex 6 unused
    out, d = displace_along_normals(trimesh.Trimesh(v, f, process=False), 0.05, 0.5)
    assert np.isfinite(out.vertices).all()
    np.testing.assert_array_equal(np.asarray(out.vertices)[3:], v[3:])
    assert (d[3:] == 0).all() and (d[:3] != 0).any()


@pytest.mark.parametrize("rms, ell, match", [(-0.01, 0.1, "rms_m = -0.01"), (float("nan"), 0.1, "rms_m = nan"),
                                             (0.01, 0.0, "wavelength_m = 0.0"), (0.01, float("inf"), "wavelength_m = inf")])
def test_bad_values_are_named(rms, ell, match):
    with pytest.raises(ConfigError, match=match):
        smooth_field(np.zeros((1, 3)), rms, ell)
