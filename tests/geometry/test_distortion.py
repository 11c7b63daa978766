"""The OPENCV distortion model against kornia's implementation, its inverse on extreme inputs,
and the pinhole camera an undistorted image gets."""

import numpy as np
import pytest
import torch

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import Intrinsics
from drawer_lib.geometry.distortion import distort, remap, undistort, undistorted_intrinsics, undistortion_map

DISTS = [(-0.12, 0.03, 0.001, -0.0008), (0.08, -0.02, -0.002, 0.001), (-0.3, 0.09, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)]


@pytest.mark.parametrize("dist", DISTS)
def test_distort_matches_kornia(dist):
    from kornia.geometry.calibration import distort_points

    rng = np.random.default_rng(0)
    xy = rng.uniform(-0.6, 0.6, (500, 2))
    K = torch.eye(3, dtype=torch.float64)[None]
    ref = distort_points(torch.tensor(xy)[None], K, torch.tensor(dist, dtype=torch.float64)[None])[0].numpy()
    np.testing.assert_allclose(distort(xy, dist), ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("dist", DISTS)
def test_undistort_inverts_distort(dist):
    rng = np.random.default_rng(1)
    xy = rng.uniform(-0.6, 0.6, (2000, 2))
    np.testing.assert_allclose(undistort(distort(xy, dist), dist), xy, rtol=0, atol=1e-10)
    assert undistort(np.zeros((0, 2)), dist).shape == (0, 2)


def test_undistort_extremes_and_fold_over():
    d = (-0.12, 0.03, 0.001, -0.0008)
    for s in (1e-9, 1e-4, 1.0):  # tiny and ordinary radii
        xy = np.array([[s, -s], [0.0, s]])
        np.testing.assert_allclose(undistort(distort(xy, d), d), xy, rtol=1e-9, atol=1e-18)
    # k1 strongly negative: the model folds back beyond r = 1 / sqrt(3 |k1|); no inverse there
    with pytest.raises(InputError, match="folds"):
        undistort(np.array([[2.0, 0.0]]), (-0.5, 0.0, 0.0, 0.0))


@pytest.mark.parametrize("dist", DISTS[:3])
def test_undistorted_camera_sees_only_what_the_image_holds(dist):
    src = Intrinsics(80.0, 82.0, 48.3, 35.7, 96, 72, dist)
    dst = undistorted_intrinsics(src)
    assert (dst.width, dst.height) == (96, 72) and not dst.has_distortion
    rows, cols = undistortion_map(src, dst)
    # every output pixel centre maps into the source image (pixel-centre coordinates -0.5 .. W - 0.5)
    assert cols.min() >= -0.5 - 1e-6 and cols.max() <= 96 - 0.5 + 1e-6
    assert rows.min() >= -0.5 - 1e-6 and rows.max() <= 72 - 0.5 + 1e-6
    # and the rectangle is tight: some border pixel of the output reaches a source border
    assert min(cols.min() + 0.5, 95.5 - cols.max(), rows.min() + 0.5, 71.5 - rows.max()) < 1.0


def test_no_distortion_is_the_identity_map():
    src = Intrinsics(80.0, 80.0, 48.0, 36.0, 96, 72)
    rows, cols = undistortion_map(src, src)
    ii, jj = np.mgrid[0:72, 0:96]
    np.testing.assert_allclose(rows, ii, atol=1e-9)
    np.testing.assert_allclose(cols, jj, atol=1e-9)
    img = np.random.default_rng(0).integers(0, 255, (72, 96, 3), dtype=np.uint8)
    assert np.array_equal(remap(img, rows, cols), img)
    lab = np.random.default_rng(0).integers(0, 9, (72, 96)).astype(np.uint16)
    assert np.array_equal(remap(lab, rows + 0.3, cols - 0.3, nearest=True), lab)  # labels are never mixed
