"""PSNR and SSIM against scikit-image (the slow reference) and on analytic cases."""

import math

import pytest
import torch
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from drawer_lib.metrics.image import psnr, ssim, ssim_target_stats


def pair(seed=0, H=40, W=52):
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(2, 3, H, W, generator=g, dtype=torch.float64)
    x = torch.nn.functional.avg_pool2d(x, 3, 1, 1)  # some structure
    y = (x + 0.05 * torch.randn(x.shape, generator=g, dtype=torch.float64)).clamp(0, 1)
    return x, y


def test_psnr_matches_skimage_and_analytic():
    x, y = pair()
    for b in range(2):
        ref = peak_signal_noise_ratio(x[b].numpy(), y[b].numpy(), data_range=1.0)
        assert psnr(x, y)[b].item() == pytest.approx(ref, rel=1e-10)
    assert psnr(torch.zeros(1, 3, 4, 4), torch.full((1, 3, 4, 4), 0.1)).item() == pytest.approx(20.0)
    assert math.isinf(psnr(x, x)[0].item())


def test_ssim_matches_skimage():
    x, y = pair(1)
    for b in range(2):
        ref = structural_similarity(x[b].permute(1, 2, 0).numpy(), y[b].permute(1, 2, 0).numpy(), channel_axis=2,
                                    data_range=1.0, gaussian_weights=True, sigma=1.5, use_sample_covariance=False)
        assert ssim(x, y)[b].item() == pytest.approx(ref, abs=1e-6)
    assert ssim(x, x)[0].item() == pytest.approx(1.0, abs=1e-12)


def test_ssim_refuses_small_images():
    with pytest.raises(ValueError, match="11x11"):
        ssim(torch.rand(1, 3, 8, 8), torch.rand(1, 3, 8, 8))


def test_ssim_with_cached_target_stats_equals_plain():
    """The training loop's path (target statistics computed once) gives the same value and the
    same gradient as the plain call (float64)."""
    x, y = pair(3)
    x, y = x.double(), y.double()
    x1 = x.clone().requires_grad_(True)
    x2 = x.clone().requires_grad_(True)
    a, b = ssim(x1, y), ssim(x2, y, y_stats=ssim_target_stats(y))
    assert torch.allclose(a, b, rtol=0, atol=1e-12)
    a.sum().backward()
    b.sum().backward()
    assert torch.allclose(x1.grad, x2.grad, rtol=0, atol=1e-12)
    assert ssim_target_stats(y).shape == (2, 6, y.shape[2] - 10, y.shape[3] - 10)
