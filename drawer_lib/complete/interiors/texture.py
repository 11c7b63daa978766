"""The interiors' colours (:func:`interior_colours`): what the walls no capture saw look like,
from the colours of the part's front, darkened with depth (ambient occlusion), with a tileable
procedural patch. ``texturer: learned`` is the slot of DRAWER's learned texturer (MatFuse)."""

import zlib
from dataclasses import dataclass

import numpy as np
from jaxtyping import Float
from scipy.ndimage import gaussian_filter

from drawer_lib.complete.interiors.config import TextureConfig
from drawer_lib.complete.interiors.templates import Interior
from drawer_lib.errors import ConfigError


@dataclass(frozen=True)
class InteriorTexture:
    """``base``: {wall name: RGB in [0, 1]} (already darkened); ``patch``: [P, P, 3] tileable
    multiplicative detail with mean 1 (a wall's texture = base x patch); ``source``: whose
    colours were used (front | default)."""

    base: dict
    patch: np.ndarray
    source: str


def _ao(z: float, cfg: TextureConfig) -> float:
    return float(1.0 - cfg.ao_strength * (1.0 - np.exp(-max(z, 0.0) / cfg.ao_length)))


def interior_colours(interior: Interior, front_rgb: Float[np.ndarray, "N 3"], cfg: TextureConfig) -> InteriorTexture:
    """Per-wall base colours and a procedural patch for ``interior`` from the colours of its
    front (RGB samples in [0, 1]: its Gaussians' base colours) when there are ``min_samples``
    of them, else mid grey; each wall darkened by the ambient occlusion at its depth
    (``top_shade`` more on the ceiling); the patch carries the samples' per-channel spread (at
    most 15 %), smoothed.
    ``texturer: learned`` raises :class:`ConfigError` naming the missing model."""
    if cfg.texturer == "learned":
        raise ConfigError(
            f"complete.interiors.texture.texturer = 'learned' needs the learned texturer model "
            f"{cfg.learned_model!r} (DRAWER's MatFuse: Hugging Face gvecchio/MatFuse, checkpoint matfuse-full.ckpt), "
            "which is not installed; use texturer: observed")
    samples, source = None, "default"
    s = np.asarray(front_rgb, np.float64).reshape(-1, 3)
    s = s[np.all(np.isfinite(s), axis=1)]
    if len(s) >= cfg.min_samples:
        samples, source = np.clip(s, 0, 1), "front"
    mean = samples.mean(0) if samples is not None else np.full(3, 0.5)
    spread = np.minimum(samples.std(0) / np.maximum(mean, 1e-3), 0.15) if samples is not None else np.full(3, 0.03)
    depth_of = {"back": interior.start + interior.depth, "front": interior.start}
    mid = interior.start + interior.depth / 2
    base = {}
    for nm in interior.wall_names:
        k = _ao(depth_of.get(nm, mid) - interior.start, cfg)
        if nm == "top":
            k *= cfg.top_shade
        base[nm] = np.clip(mean * k, 0, 1)
    rng = np.random.default_rng([cfg.seed, zlib.crc32(interior.part_id.encode())])
    P = cfg.patch_size
    noise = rng.standard_normal((P, P, 3))
    if cfg.patch_grain > 0:
        noise = np.stack([gaussian_filter(noise[..., c], cfg.patch_grain, mode="wrap") for c in range(3)], -1)
    noise = (noise - noise.mean((0, 1))) / np.maximum(noise.std((0, 1)), 1e-12)
    patch = np.clip(1.0 + noise * spread, 0.0, 2.0)
    return InteriorTexture(base, patch, source)
