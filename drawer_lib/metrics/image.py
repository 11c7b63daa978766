"""Novel-view-synthesis metrics (docs/formats.md#nvs): PSNR (data range 1) and SSIM (11x11 Gaussian window,
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


def _blur(t: Tensor, size: int, sigma: float) -> Tensor:
    """Separable Gaussian blur of every channel of [B, C, H, W], valid region only."""
    C = t.shape[1]
    g = _gauss_window(size, sigma, t.dtype)
    t = F.conv2d(t, g.view(1, 1, 1, size).expand(C, 1, 1, size), groups=C)
    return F.conv2d(t, g.view(1, 1, size, 1).expand(C, 1, size, 1), groups=C)


def _check(x: Tensor, size: int) -> None:
    if x.dim() != 4 or x.shape[-1] < size or x.shape[-2] < size:
        raise ValueError(f"ssim: images must be [B, C, H, W] of at least {size}x{size}, got {tuple(x.shape)}")


def ssim_target_stats(y: Float[Tensor, "B C H W"], size: int = 11, sigma: float = 1.5) -> Float[Tensor, "B C2 h w"]:
    """The target's local mean and variance (mu_y, sigma_yy stacked on channels: C2 = 2C; h, w
    the valid region) for :func:`ssim` ``y_stats=``: a training loop against fixed images
    computes them once."""
    _check(y, size)
    C = y.shape[1]
    b = _blur(torch.cat([y, y * y], 1), size, sigma)
    my = b[:, :C]
    return torch.cat([my, b[:, C:] - my * my], 1)


def ssim(x: Float[Tensor, "B C H W"], y: Float[Tensor, "B C H W"], size: int = 11, sigma: float = 1.5,
         y_stats: Tensor | None = None) -> Float[Tensor, "B"]:
    """Mean SSIM per image over channels and the valid (unpadded) window positions.
    ``y_stats``: :func:`ssim_target_stats` of ``y`` (saves two of the five blurs)."""
    if x.shape != y.shape:
        raise ValueError(f"ssim: images must share a shape, got {tuple(x.shape)}, {tuple(y.shape)}")
    _check(x, size)
    C = x.shape[1]
    if y_stats is None:
        y_stats = ssim_target_stats(y, size, sigma)
    b = _blur(torch.cat([x, x * x, x * y], 1), size, sigma)  # one batched blur of the three x-terms
    mx, my, syy = b[:, :C], y_stats[:, :C], y_stats[:, C:]
    sxx = b[:, C:2 * C] - mx * mx
    sxy = b[:, 2 * C:] - mx * my
    c1, c2 = 0.01**2, 0.03**2
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return s.flatten(1).mean(1)


EVAL_CHUNK_PX = 4_000_000  # pixels scored at once (appearance on 32 test views of 1280 x 960: 11.6 GB peak in one batch, 6.2 GB in chunks)


def image_scores(pred: Float[Tensor, "T H W 3"], gt: Float[Tensor, "T H W 3"], with_lpips: bool = True,
                 chunk_px: int | None = None) -> dict[str, Tensor]:
    """Per-image ``psnr``, ``ssim`` (and ``lpips``) [T] of images in [0, 1] (``pred`` clamped),
    scored in chunks of at most ``chunk_px`` pixels (default ``EVAL_CHUNK_PX``; small views: one chunk)."""
    T, H, W = pred.shape[:3]
    step = max(1, (chunk_px or EVAL_CHUNK_PX) // (H * W))
    out: dict[str, list[Tensor]] = {"psnr": [], "ssim": []} | ({"lpips": []} if with_lpips else {})
    for s in range(0, T, step):
        x, y = pred[s:s + step].permute(0, 3, 1, 2).clamp(0, 1), gt[s:s + step].permute(0, 3, 1, 2)
        out["psnr"].append(psnr(x, y))
        out["ssim"].append(ssim(x, y))
        if with_lpips:
            from drawer_lib.metrics.lpips import lpips

            out["lpips"].append(lpips(x, y))
    return {k: torch.cat(v) for k, v in out.items()}
