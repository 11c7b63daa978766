"""Training at a lower image resolution (``appearance.train_scale``): the box filter against a
per-pixel loop, the downscaled camera against projecting at full size and dividing, bad
factors named."""

import numpy as np
import pytest
import torch

from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Camera, Intrinsics
from drawer_lib.splat.config import AnchorDisplacement, AppearanceConfig
from drawer_lib.splat.train import downscale_camera, downscale_images


def _box_loop(img: np.ndarray, f: int) -> np.ndarray:
    H, W = img.shape[1] // f, img.shape[2] // f
    out = np.zeros((img.shape[0], H, W, 3))
    for c in range(img.shape[0]):
        for i in range(H):
            for j in range(W):
                out[c, i, j] = img[c, i * f:(i + 1) * f, j * f:(j + 1) * f].reshape(-1, 3).mean(0)
    return out


@pytest.mark.parametrize("f,shape", [(1, (2, 6, 8)), (2, (2, 6, 8)), (3, (1, 7, 11)), (4, (1, 9, 8))])
def test_box_filter_matches_loop(f, shape):
    img = torch.rand(*shape, 3, generator=torch.Generator().manual_seed(f))
    got = downscale_images(img, f)
    assert got.shape == (shape[0], shape[1] // f, shape[2] // f, 3)
    np.testing.assert_allclose(got.numpy(), _box_loop(img.numpy(), f), atol=1e-6)


@pytest.mark.parametrize("f", [1, 2, 4])
def test_downscaled_camera_projects_to_the_block(f):
    """A point seen at full-size pixel coordinates u lands at u / f in the box-filtered image
    (pixel centres at +0.5: the centre of block k is f k + f / 2)."""
    cam = Camera(Intrinsics(180.0, 176.0, 101.3, 74.2, 200, 150), np.eye(4))
    small = downscale_camera(cam, f)
    assert (small.width, small.height) == (200 // f, 150 // f)
    pts = np.random.default_rng(0).uniform([-1, -1, 1], [1, 1, 4], (50, 3))
    uv, z = cam.project(pts)
    uv_s, z_s = small.project(pts)
    np.testing.assert_allclose(uv_s, uv / f, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(z_s, z)


def test_bad_factors_are_named():
    with pytest.raises(ConfigError, match="train_scale"):
        AppearanceConfig(train_scale=0)
    with pytest.raises(ConfigError, match="larger than the images"):
        downscale_images(torch.zeros(1, 3, 4, 3), 4)
    with pytest.raises(ConfigError, match="rms_m"):
        AnchorDisplacement(rms_m=float("nan"))
    with pytest.raises(ConfigError, match="wavelength_m"):
        AnchorDisplacement(rms_m=0.01, wavelength_m=0.0)


def test_max_side_sets_the_train_factor():
    from pathlib import Path

    from drawer_lib.io.capture import Capture
    from drawer_lib.splat.train import train_factor

    cap = Capture(Path("phone"), Intrinsics(900.0, 900.0, 640.0, 480.0, 1280, 960), [], [], [])
    assert train_factor(cap, AppearanceConfig()) == 2  # max_side 640 by default
    assert train_factor(cap, AppearanceConfig(max_side=None)) == 1
    assert train_factor(cap, AppearanceConfig(train_scale=4)) == 4  # the larger factor wins
    with pytest.raises(ConfigError, match="appearance.max_side = 2"):
        AppearanceConfig(max_side=2)


def test_chunked_scores_equal_one_batch():
    """Many large test views are scored in chunks; the per-image scores are those of one batch."""
    from drawer_lib.metrics.image import image_scores

    g = torch.Generator().manual_seed(0)
    gt = torch.rand(5, 40, 48, 3, generator=g)
    pred = gt + 0.1 * torch.randn(5, 40, 48, 3, generator=g)  # out of [0, 1]: clamped
    whole = image_scores(pred, gt, chunk_px=10**9)
    parts = image_scores(pred, gt, chunk_px=2 * 40 * 48)  # chunks of 2, 2 and 1 views
    for k in ("psnr", "ssim", "lpips"):
        assert parts[k].shape == (5,) and torch.isfinite(parts[k]).all()
        np.testing.assert_allclose(parts[k].numpy(), whole[k].numpy(), rtol=1e-5)
    assert "lpips" not in image_scores(pred, gt, with_lpips=False)
