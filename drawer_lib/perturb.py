"""Controlled geometric error for robustness ablations (``appearance.anchor_displacement``, the
``ste_displaced_1cm`` experiment): a smooth random displacement of a mesh along its vertex
normals (a stand-in for the low-frequency bumps of a reconstructed surface). Off by default.
:func:`jitter_mesh`: independent noise on every vertex, of the size another machine's last
bits move a reconstructed mesh by (the stability studies of ``decompose.mesh_jitter`` and
``scripts/decision_stability.py``).

The field is a random Fourier feature approximation of a stationary Gaussian process with a
squared-exponential kernel of length ``wavelength_m``:

    d(x) = rms_m sqrt(2 / K) sum_k cos(w_k . x + b_k),  w_k ~ N(0, I / wavelength_m^2),  b_k ~ U(0, 2 pi)

so E[d] = 0, E[d^2] = rms_m^2 at every point, and the correlation of two points at distance r
tends to exp(-r^2 / (2 wavelength_m^2)) as K grows. Deterministic for a given ``seed``.
"""

import numpy as np
import trimesh
from jaxtyping import Float

from drawer_lib.errors import ConfigError


def smooth_field(points: Float[np.ndarray, "N 3"], rms_m: float, wavelength_m: float, seed: int = 0,
                 n_features: int = 256) -> Float[np.ndarray, "N"]:
    """Values [N] (metres) of the random smooth field at ``points`` [N, 3] (metres)."""
    if not (np.isfinite(rms_m) and rms_m >= 0):
        raise ConfigError(f"displacement rms_m = {rms_m} must be finite and >= 0")
    if not (np.isfinite(wavelength_m) and wavelength_m > 0):
        raise ConfigError(f"displacement wavelength_m = {wavelength_m} must be finite and > 0")
    if n_features < 1:
        raise ConfigError(f"displacement n_features = {n_features} must be >= 1")
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(n_features, 3)) / wavelength_m
    b = rng.uniform(0.0, 2.0 * np.pi, n_features)
    x = np.asarray(points, np.float64)
    return rms_m * np.sqrt(2.0 / n_features) * np.cos(x @ w.T + b).sum(1)


def displace_along_normals(mesh: trimesh.Trimesh, rms_m: float, wavelength_m: float, seed: int = 0,
                           n_features: int = 256) -> tuple[trimesh.Trimesh, Float[np.ndarray, "V"]]:
    """A copy of ``mesh`` whose vertices moved by the smooth field along their (area-weighted)
    normals, and the displacement [V] (metres). Faces and vertex order are unchanged; a vertex
    without a normal (unreferenced, or on zero-area faces only) does not move."""
    v = np.asarray(mesh.vertices, np.float64)
    d = smooth_field(v, rms_m, wavelength_m, seed, n_features)
    n = np.asarray(mesh.vertex_normals, np.float64) if len(mesh.faces) else np.zeros_like(v)
    n = np.where(np.isfinite(n), n, 0.0)
    d = np.where(np.linalg.norm(n, axis=1) > 0.5, d, 0.0)
    return trimesh.Trimesh(v + d[:, None] * n, np.asarray(mesh.faces), process=False), d


def jitter_mesh(mesh: trimesh.Trimesh, sigma: float, seed: int | list[int]) -> trimesh.Trimesh:
    """``mesh`` with every vertex moved by isotropic Gaussian noise of ``sigma`` m (same faces)."""
    if not sigma >= 0:
        raise ValueError(f"jitter_mesh: sigma = {sigma} must be >= 0")
    rng = np.random.default_rng(seed)
    v = np.asarray(mesh.vertices, np.float64) + rng.normal(0.0, sigma, (len(mesh.vertices), 3))
    return trimesh.Trimesh(v, np.asarray(mesh.faces), process=False)
