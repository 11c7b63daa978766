"""Procedural, tileable textures (numpy): wood grain, painted noise, stone, tiles, planks, metal.

All textures are periodic (built from FFT-filtered noise and integer frequencies), so repeated
tiles have no seams, and carry detail at the 1-10 cm scale that structure-from-motion and
photometric fitting need at ~1 cm per pixel. Each returns uint8 [N, N, 3].
"""

import numpy as np


def fft_noise(rng: np.random.Generator, n: int, beta: float = 2.0, stretch=(1.0, 1.0),
              fmin: float = 1.0) -> np.ndarray:
    """Periodic noise with power spectrum ~ 1/f^beta, zero mean and unit std, [n, n].

    ``stretch`` = (sx, sy) > 1 elongates features along x (columns) or y (rows).
    """
    fy = np.fft.fftfreq(n)[:, None] * n * stretch[1]
    fx = np.fft.fftfreq(n)[None, :] * n * stretch[0]
    f = np.sqrt(fx**2 + fy**2)
    amp = np.where(f >= fmin, np.maximum(f, 1e-9) ** (-beta / 2.0), 0.0)
    spec = amp * (rng.normal(size=(n, n)) + 1j * rng.normal(size=(n, n)))
    x = np.real(np.fft.ifft2(spec))
    s = x.std()
    return (x - x.mean()) / (s if s > 0 else 1.0)


def _to_u8(img: np.ndarray) -> np.ndarray:
    return (np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _mix(a, b, t):
    t = np.clip(t, 0, 1)[..., None]
    return np.asarray(a, np.float64) * (1 - t) + np.asarray(b, np.float64) * t


def wood(rng: np.random.Generator, base, dark, n: int = 512, rings: int = 9) -> np.ndarray:
    """Wood grain running along the texture's v (rows) direction."""
    u = np.arange(n)[None, :] / n
    warp = fft_noise(rng, n, beta=3.0, stretch=(1.0, 6.0))
    rings_f = np.sin(2 * np.pi * (rings * u + 0.25 * warp)) * 0.5 + 0.5
    streak = fft_noise(rng, n, beta=1.2, stretch=(1.0, 12.0))
    knots = fft_noise(rng, n, beta=3.5)
    t = 0.55 * rings_f**2 + 0.18 * streak + 0.12 * knots
    img = _mix(base, dark, t)
    img *= 1.0 + 0.05 * fft_noise(rng, n, beta=1.0)[..., None]
    return _to_u8(img)


def painted(rng: np.random.Generator, color, n: int = 256, mottle: float = 0.12) -> np.ndarray:
    """Paint or laminate with a visible mottle (stipple of a roller) plus fine grain."""
    low = fft_noise(rng, n, beta=2.5, fmin=2.0)
    mid = fft_noise(rng, n, beta=1.0, fmin=6.0)
    img = np.asarray(color, np.float64)[None, None, :] * (1.0 + mottle * (0.6 * low + 0.4 * mid))[..., None]
    return _to_u8(img)


def stone(rng: np.random.Generator, c1, c2, n: int = 512) -> np.ndarray:
    """Granite-like stone: cloudy base with dark and light grains."""
    base = _mix(c1, c2, 0.5 + 0.25 * fft_noise(rng, n, beta=2.5))
    g = fft_noise(rng, n, beta=0.3)
    dark = g > 1.6
    light = g < -1.8
    img = base.copy()
    img[dark] *= 0.35
    img[light] = img[light] * 0.4 + 0.6
    return _to_u8(img)


def tiles(rng: np.random.Generator, color, grout, n: int = 512, k: int = 4, grout_w: float = 0.03,
          jitter: float = 0.08) -> np.ndarray:
    """k x k square tiles with grout lines and per-tile shade variation."""
    idx = np.arange(n) / n * k
    fu, fv = idx[None, :] % 1.0, idx[:, None] % 1.0
    tu, tv = np.floor(idx[None, :]).astype(int), np.floor(idx[:, None]).astype(int)
    shade = 1.0 + jitter * rng.normal(size=(k, k))
    img = np.asarray(color, np.float64)[None, None] * shade[tv, tu][..., None]
    img = img * (1.0 + 0.05 * fft_noise(rng, n, beta=1.5))[..., None]
    g = (np.minimum(fu, 1 - fu) < grout_w) | (np.minimum(fv, 1 - fv) < grout_w)
    img[g] = np.asarray(grout, np.float64)
    return _to_u8(img)


def planks(rng: np.random.Generator, base, dark, n: int = 512, k: int = 4) -> np.ndarray:
    """Floor planks: k planks across u, each with its own shade, grain along v, joints."""
    img = wood(rng, base, dark, n, rings=k * 3).astype(np.float64) / 255.0
    u = np.arange(n) / n * k
    shade = 1.0 + 0.12 * rng.normal(size=k)
    img *= shade[np.floor(u).astype(int)][None, :, None]
    joint = np.minimum(u % 1.0, 1 - (u % 1.0)) < 0.012
    img[:, joint] *= 0.45
    # staggered butt joints
    for j in range(k):
        row = int(rng.integers(0, n))
        cols = (np.floor(u) == j)
        img[max(row - 2, 0):row + 2, cols] *= 0.45
    return _to_u8(img)


def metal(rng: np.random.Generator, color, n: int = 256) -> np.ndarray:
    """Brushed metal: fine streaks along u (columns)."""
    s = fft_noise(rng, n, beta=0.8, stretch=(30.0, 1.0))
    img = np.asarray(color, np.float64)[None, None] * (1.0 + 0.07 * s + 0.04 * fft_noise(rng, n, 2.0))[..., None]
    return _to_u8(img)


def ceramic(rng: np.random.Generator, color, accent, n: int = 256, bands: int = 3) -> np.ndarray:
    """Glazed ceramic with painted bands and a light speckle."""
    v = np.arange(n)[:, None] / n
    band = (np.sin(2 * np.pi * bands * v + 0.3 * fft_noise(rng, n, 3.0, (4.0, 1.0))) > 0.55)
    img = np.where(band[..., None], np.asarray(accent, np.float64), np.asarray(color, np.float64))
    img = img * (1.0 + 0.06 * fft_noise(rng, n, beta=1.2))[..., None]
    return _to_u8(img)


def glass(rng: np.random.Generator, n: int = 128) -> np.ndarray:
    """Dark appliance glass with a faint reflection gradient."""
    v = np.arange(n)[:, None] / n
    img = np.full((n, n, 3), 0.07) + 0.05 * v[..., None] + 0.02 * fft_noise(rng, n, 3.0)[..., None]
    return _to_u8(img)
