"""Gaussians on boxes: the interiors' walls (drawer boxes, cabinet cavities, shelves) that no
capture saw, covered by flat Gaussians initialised from the interior texture, so a twin still
looks like a cabinet when a part is open (DRAWER merges textured interior meshes into its
Gaussians the same way, reference §5.5).

Each face of a box gets a regular grid of flat Gaussians (spacing ``spacing``; in-plane
standard deviation 0.6 x spacing, so neighbours overlap into a closed surface; 0.5 mm along
the face normal), opacity ``opacity``, view-independent colour (SH degree-0 coefficient
(c - 0.5) / C0; higher coefficients zero).
"""

import numpy as np
import torch
from jaxtyping import Float

from drawer_lib.errors import InputError
from drawer_lib.splat.render import Gaussians
from drawer_lib.splat.sh import C0
from drawer_lib.geometry.rotations import matrix_to_quat

THIN = 5e-4  # m, the Gaussians' extent along the face normal


def box_faces(center: Float[np.ndarray, "3"], rotation: Float[np.ndarray, "3 3"], half: Float[np.ndarray, "3"]
              ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """The 6 faces of an oriented box as (centre [3], outward normal [3], in-plane axes [2, 3],
    in-plane half extents [2]); ``rotation``'s columns are the box axes, ``half`` in metres."""
    R, h = np.asarray(rotation, np.float64), np.asarray(half, np.float64)
    out = []
    for ax in range(3):
        a, b = [k for k in range(3) if k != ax]
        for s in (1.0, -1.0):
            n = s * R[:, ax]
            out.append((np.asarray(center, np.float64) + n * h[ax], n, np.stack([R[:, a], R[:, b]]), h[[a, b]]))
    return out


def box_surface_gaussians(center: Float[np.ndarray, "3"], rotation: Float[np.ndarray, "3 3"], half: Float[np.ndarray, "3"],
                          color: Float[np.ndarray, "3"], spacing: float = 0.02, opacity: float = 0.95, sh_degree: int = 3,
                          shade=None, toward: Float[np.ndarray, "3"] | None = None) -> Gaussians:
    """Flat Gaussians covering the faces of one oriented box (see the module docstring).
    ``color``: RGB in [0, 1]; ``shade(points [M, 3]) -> [M]`` an optional factor in [0, 1]
    per Gaussian (e.g. darker deeper inside a cabinet); ``toward``: cover only the faces whose
    outward normal points toward this point (a wall's inner faces, seen from inside its cavity:
    its outer faces lie in or outside the carcass, where they would show through)."""
    if not spacing > 0 or not np.all(np.isfinite(half)) or np.any(np.asarray(half) < 0):
        raise InputError(f"box_surface_gaussians: spacing {spacing} or half extents {half} not usable")
    means, quats, scales = [], [], []
    for c, n, ab, hab in box_faces(center, rotation, half):
        if np.any(hab <= 0) or (toward is not None and float(n @ (np.asarray(toward, np.float64) - c)) <= 0):
            continue
        nu, nv = (np.maximum(np.ceil(2 * hab / spacing), 1)).astype(int)
        su, sv = (np.arange(nu) + 0.5) / nu * 2 - 1, (np.arange(nv) + 0.5) / nv * 2 - 1
        uu, vv = np.meshgrid(su * hab[0], sv * hab[1], indexing="ij")
        p = c + uu.reshape(-1, 1) * ab[0] + vv.reshape(-1, 1) * ab[1]
        Rf = np.stack([ab[0], np.cross(n, ab[0]), n], 1)  # frame: x, y in the face, z = normal
        means.append(p)
        quats.append(np.broadcast_to(matrix_to_quat(Rf), (len(p), 4)))
        scales.append(np.broadcast_to([0.6 * 2 * hab[0] / nu, 0.6 * 2 * hab[1] / nv, THIN], (len(p), 3)))
    K = (sh_degree + 1) ** 2
    if not means:
        return Gaussians(torch.zeros(0, 3), torch.zeros(0, 4), torch.zeros(0, 3), torch.zeros(0), torch.zeros(0, K, 3))
    m = np.concatenate(means)
    col = np.broadcast_to(np.clip(np.asarray(color, np.float64), 0, 1), (len(m), 3)).copy()
    if shade is not None:
        col *= np.clip(np.asarray(shade(m), np.float64), 0, 1)[:, None]
    sh = np.zeros((len(m), K, 3))
    sh[:, 0] = (col - 0.5) / C0
    f = lambda x: torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))  # noqa: E731
    return Gaussians(f(m), f(np.concatenate(quats)), f(np.concatenate(scales)), torch.full((len(m),), float(opacity)), f(sh))
