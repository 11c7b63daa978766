"""The one oriented-box type (drawer_lib/geometry/boxes.py): its corners, triangles, bounds and
membership against slow references, the overlap volume against closed forms and Monte Carlo,
the translated hull, the box faces, and the front frame."""

import math

import numpy as np
import pytest

from drawer_lib.geometry.boxes import OrientedBox, boxes_contain, front_frame, overlap_volume, separated


def rot(a: float, b: float, c: float) -> np.ndarray:
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    Rz = np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1.0]])
    Rx = np.array([[1, 0, 0], [0, cb, -sb], [0, sb, cb]])
    Ry = np.array([[cc, 0, sc], [0, 1, 0], [-sc, 0, cc]])
    return Rz @ Rx @ Ry


BOX = OrientedBox(np.array([0.3, -0.2, 1.1]), rot(0.4, 0.3, -0.7), np.array([0.25, 0.1, 0.05]))


def test_the_box_is_frozen_and_checks_its_shapes():
    with pytest.raises(ValueError, match="non-writable|read-only"):
        BOX.center[0] = 1.0
    with pytest.raises((ValueError, TypeError), match="half"):  # the shape check, or the tests' type-check hook first
        OrientedBox(np.zeros(3), np.eye(3), np.ones(2))
    assert BOX.volume == pytest.approx(8 * 0.25 * 0.1 * 0.05)


def test_corners_triangles_and_bounds_against_a_loop():
    R, c, h = BOX.rotation, BOX.center, BOX.half
    ref = np.array([c + R @ (np.array([sx, sy, sz]) * h) for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)])
    np.testing.assert_allclose(BOX.corners(), ref, atol=1e-15)
    V, F = BOX.triangles()
    np.testing.assert_allclose(V, BOX.corners(), atol=1e-15)
    tri = V[F]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("fi,fi->f", n, tri.mean(1) - c) > 0)  # outward
    assert np.einsum("fi,fi->f", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6 == pytest.approx(BOX.volume)
    lo, hi = BOX.bounds(0.01)
    grown = OrientedBox(c, R, h + 0.01).corners()
    np.testing.assert_allclose(lo, grown.min(0), atol=1e-15)
    np.testing.assert_allclose(hi, grown.max(0), atol=1e-15)


def test_contains_and_boxes_contain_match_a_loop():
    rng = np.random.default_rng(1)
    K = 7
    A = np.linalg.qr(rng.normal(size=(K, 3, 3)))[0]
    c, h = rng.normal(size=(K, 3)) * 0.3, rng.uniform(0.05, 0.3, size=(K, 3))
    P = rng.normal(size=(5000, 3)) * 0.5
    ref = np.zeros(len(P), bool)
    for k in range(K):
        ref |= np.all(np.abs((P - c[k]) @ A[k]) <= h[k], axis=1)
    np.testing.assert_array_equal(boxes_contain(P, c, A, h), ref)
    one = OrientedBox(c[0], A[0], h[0])
    np.testing.assert_array_equal(one.contains(P), np.all(np.abs((P - c[0]) @ A[0]) <= h[0], axis=1))
    inner, outer = c[0] + 0.999 * (one.corners() - c[0]), c[0] + 1.001 * (one.corners() - c[0])
    assert one.contains(inner).all() and not one.contains(outer).any()
    assert one.contains(outer, inflate=0.01).all()
    assert boxes_contain(np.zeros((0, 3)), c, A, h).shape == (0,) and not boxes_contain(P, c[:0], A[:0], h[:0]).any()


def test_overlap_volume_closed_forms_and_monte_carlo():
    I = np.eye(3)
    a = OrientedBox(np.zeros(3), I, np.array([1.0, 1.0, 1.0]))
    assert overlap_volume(a, a) == pytest.approx(8.0)
    assert overlap_volume(a, OrientedBox(np.array([0.5, 0.5, 0.0]), I, np.ones(3))) == pytest.approx(1.5 * 1.5 * 2)
    touching = OrientedBox(np.array([2.0, 0.0, 0.0]), I, np.ones(3))
    assert overlap_volume(a, touching) == 0.0 and separated(a, touching)
    assert overlap_volume(a, OrientedBox(np.array([3.0, 0.0, 0.0]), I, np.ones(3))) == 0.0
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    small = OrientedBox(np.zeros(3), Rz, np.array([0.3, 0.2, 0.1]))
    assert overlap_volume(a, small) == pytest.approx(small.volume) and not separated(a, small)
    # slow twin: Monte Carlo on a generic pair
    rng = np.random.default_rng(0)
    b = OrientedBox(np.array([0.7, -0.4, 0.3]), rot(np.pi / 4, 0.4, 0.0), np.array([0.8, 0.5, 0.6]))
    X = rng.uniform(-1, 1, (400_000, 3))
    mc = 8.0 * np.mean(b.contains(X))
    assert overlap_volume(a, b) == pytest.approx(mc, rel=0.02)
    flat = OrientedBox(np.zeros(3), I, np.array([1.0, 1.0, 0.0]))  # zero thickness: no volume
    assert overlap_volume(a, flat) == 0.0


def test_translated_hull_holds_the_travel_and_no_more():
    """A tilted box slid along a slanted axis: every corner at every q lies in the hull, and for
    a box slid along one of its own axes the hull is exactly the swept box."""
    box = OrientedBox(np.array([0.1, 0.2, 0.3]), rot(0.3, 0.0, 0.0), np.array([0.2, 0.01, 0.1]))
    d = np.array([0.0, -1.0, 0.2])
    hull = box.translated_hull(d, 0.05, 0.4)
    corners = box.corners()
    u = d / np.linalg.norm(d)
    for q in np.linspace(0.05, 0.4, 15):
        assert hull.contains(corners + q * u, inflate=1e-9).all()
    along = OrientedBox(np.zeros(3), np.eye(3), np.array([0.2, 0.1, 0.1])).translated_hull([0.0, 2.0, 0.0], 0.0, 0.4)
    np.testing.assert_allclose(along.center, [0.0, 0.2, 0.0])
    np.testing.assert_allclose(along.half, [0.2, 0.3, 0.1])


def test_faces_cover_the_surface_outward():
    faces = BOX.faces()
    assert len(faces) == 6
    area = sum(4 * h[0] * h[1] for _, _, _, h in faces)
    hx, hy, hz = BOX.half
    assert area == pytest.approx(8 * (hx * hy + hy * hz + hx * hz))
    for c, n, ab, h in faces:
        assert np.dot(c - BOX.center, n) > 0 and abs(np.linalg.norm(n) - 1) < 1e-12
        assert np.allclose(ab @ n, 0.0) and BOX.contains((c + h[0] * ab[0] + h[1] * ab[1])[None], inflate=1e-12).all()


@pytest.mark.parametrize("normal", [(0.0, -1.0, 0.0), (math.sin(0.7), -math.cos(0.7), 0.0), (0.6, 0.0, 0.8)])
def test_front_frame_is_a_proper_rotation_of_u_v_n(normal):
    n = np.asarray(normal) / np.linalg.norm(normal)
    u = np.cross([0.0, 0.0, 1.0], n)
    u = u / np.linalg.norm(u)
    R = front_frame(n, u)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[:, 0], u)
    np.testing.assert_allclose(R[:, 2], n)
    np.testing.assert_allclose(R[:, 1], np.cross(n, u))
