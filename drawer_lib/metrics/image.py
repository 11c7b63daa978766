"""Novel-view-synthesis metrics (DESIGN §6): PSNR (data range 1) and SSIM (11x11 Gaussian window,
sigma 1.5, K1 = 0.01, K2 = 0.03, mean over RGB and pixels, valid region only, as in the SSIM
paper and scikit-image's ``gaussian_weights=True, use_sample_covariance=False``)."""

import torch
import torch.nn.functional as F
from jaxtyping import Float
from torch import Tensor


def psnr(x: Float[Tensor, "B 3 H W"], y: Float[Tensor, "B 3 H W"]) -> Float[Tensor, "B"]:
    """-10 log10(MSE) per image, images in [0, 1]; inf for identical images."""
    mse = ((x - y) ** 2).flatten(1).mean(1)
    return -10.0 * torch.log10(mse)


def _gauss_window(size: int, sigma: float, dtype: torch.dtype) -> Tensor:
    r = torch.arange(size, dtype=dtype) - (size - 1) / 2
    g = torch.exp(-(r**2) / (2 * sigma**2))
    return g / g.sum()


def ssim(x: Float[Tensor, "B C H W"], y: Float[Tensor, "B C H W"], size: int = 11, sigma: float = 1.5) -> Float[Tensor, "B"]:
    """Mean SSIM per image over channels and the valid (unpadded) window positions."""
    if x.shape != y.shape or x.shape[-1] < size or x.shape[-2] < size:
        raise ValueError(f"ssim: images must share a shape of at least {size}x{size}, got {tuple(x.shape)}, {tuple(y.shape)}")
    C = x.shape[1]
    g = _gauss_window(size, sigma, x.dtype)
    wx = g.view(1, 1, 1, size).repeat(C, 1, 1, 1)
    wy = g.view(1, 1, size, 1).repeat(C, 1, 1, 1)
    blur = lambda t: F.conv2d(F.conv2d(t, wx, groups=C), wy, groups=C)  # noqa: E731
    mx, my = blur(x), blur(y)
    sxx = blur(x * x) - mx * mx
    syy = blur(y * y) - my * my
    sxy = blur(x * y) - mx * my
    c1, c2 = 0.01**2, 0.03**2
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return s.flatten(1).mean(1)
