"""Operations on sets of Gaussians (:class:`~drawer_lib.splat.render.Gaussians`, activated,
world frame): subsets and concatenation, each Gaussian's blend weight in a view, rigid motion
(means, orientations and the view-dependent colour), and flat Gaussians covering the faces of a
box (the interiors' walls).

Moving Gaussians by a rotation R: means -> R m + t, orientations -> q_R * q, and the SH colour
c(d) -> c(R^T d), i.e. every degree-l band of the coefficients is multiplied by a (2l+1)^2
matrix. That matrix is found without Wigner formulas: the degree-l real SH span a space that
rotations map to itself, so evaluating the basis at enough directions d_i and at R^T d_i and
solving ``Y(R^T d) = Y(d) D`` in least squares gives D exactly (up to float error);
:func:`sh_rotation` is tested against the definition c'(R d) = c(d).

Box surfaces (:func:`box_surface_gaussians`): the walls of the interiors (drawer boxes, cabinet
cavities, shelves) that no capture saw, covered by flat Gaussians initialised from the interior
texture, so a twin still looks like a cabinet when a part is open (DRAWER merges textured
interior meshes into its Gaussians the same way). Each face of a box gets a regular grid of
flat Gaussians (spacing ``spacing``; in-plane standard deviation 0.6 x spacing, so neighbours
overlap into a closed surface; 0.5 mm along the face normal), opacity ``opacity``,
view-independent colour (SH degree-0 coefficient (c - 0.5) / C0; higher coefficients zero).
"""

import numpy as np
import torch
from jaxtyping import Float
from torch import Tensor

from drawer_lib.errors import InputError
from drawer_lib.geometry.boxes import OrientedBox
from drawer_lib.geometry.camera import Camera
from drawer_lib.geometry.rotations import matrix_to_quat, quat_mul
from drawer_lib.splat.project import project_gaussians_fused
from drawer_lib.splat.rasterize import composite
from drawer_lib.splat.render import Gaussians
from drawer_lib.splat.sh import C0, sh_to_color

THIN = 5e-4  # m, a box-surface Gaussian's extent along the face normal


def subset(g: Gaussians, idx: Tensor | np.ndarray) -> Gaussians:
    """The Gaussians at ``idx`` (indices or a boolean mask)."""
    i = torch.as_tensor(idx)
    return Gaussians(g.means[i], g.quats[i], g.scales[i], g.opacities[i], g.sh[i])


def concat(gs: list[Gaussians]) -> Gaussians:
    """One set of several (equal SH sizes)."""
    return Gaussians(*(torch.cat([getattr(g, k) for g in gs]) for k in ("means", "quats", "scales", "opacities", "sh")))


def blend_weights(g: Gaussians, cam: Camera, near: float = 0.01, far: float = 1e10, eps2d: float = 0.3,
                  tile: int = 16) -> Float[Tensor, "N"]:
    """Each Gaussian's blend weight in view ``cam``, summed over the pixels: sum_p T_p,i alpha_p,i
    (pixels; 0 for one fully hidden or outside the view), as :func:`drawer_lib.splat.render.render`
    composites them (CPU backend). The image is linear in the colours, so this is the gradient of
    the summed image with respect to each Gaussian's colour: one forward and one backward pass."""
    viewmat = torch.as_tensor(cam.w2c, dtype=g.means.dtype)
    with torch.no_grad():
        p = project_gaussians_fused(g.means, g.quats, g.scales, viewmat, cam.intrinsics, near, far, eps2d)
    colors = torch.zeros((len(g.means), 3), dtype=g.means.dtype, requires_grad=True)
    c = composite(p.means2d.detach(), p.conics.detach(), g.opacities.detach(), colors, p.depths.detach(), p.radii,
                  cam.intrinsics.width, cam.intrinsics.height, tile, torch.zeros(p.means2d.shape, dtype=g.means.dtype))
    c.rgb[..., 0].sum().backward()
    return colors.grad[:, 0].detach()


def _fibonacci_dirs(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (3 - np.sqrt(5)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


def _sh_basis(dirs: np.ndarray, degree: int) -> np.ndarray:
    """[M, (degree + 1)^2] the real SH basis of :func:`drawer_lib.splat.sh.sh_to_color` at ``dirs``."""
    K = (degree + 1) ** 2
    eps = 0.1  # coefficient k = eps e_k: |eps Y_k| < 0.5 stays clear of the colour's clamp at 0
    eye = eps * torch.eye(K, dtype=torch.float64)[None].expand(len(dirs), K, K)
    d = torch.from_numpy(dirs)
    zero = torch.zeros(len(dirs), K, dtype=torch.float64)
    cols = [(sh_to_color(torch.stack([eye[:, :, k], zero, zero], -1), d, degree)[:, 0] - 0.5) / eps for k in range(K)]
    return torch.stack(cols, -1).numpy()


def sh_rotation(R: Float[np.ndarray, "3 3"], degree: int) -> np.ndarray:
    """[(degree + 1)^2, (degree + 1)^2] block-diagonal D with c'_k = sum_j D[k, j] c_j such that
    the colour of the rotated coefficients in direction R d equals the original in direction d."""
    K = (degree + 1) ** 2
    dirs = _fibonacci_dirs(64)
    Y = _sh_basis(dirs, degree)  # Y(d)
    Yr = _sh_basis(dirs @ np.asarray(R, np.float64), degree)  # Y(R^T d): rows d_i^T R = (R^T d_i)^T
    D = np.zeros((K, K))
    for lvl in range(degree + 1):
        s = slice(lvl * lvl, (lvl + 1) ** 2)
        # c'(d) = c(R^T d): Y(d) c' = Y(R^T d) c for every c -> c' = lstsq(Y, Y(R^T d)) c
        D[s, s] = np.linalg.lstsq(Y[:, s], Yr[:, s], rcond=None)[0]
    return D


def transform(g: Gaussians, R: Float[np.ndarray, "3 3"], t: Float[np.ndarray, "3"]) -> Gaussians:
    """The Gaussians moved rigidly by x -> R x + t (means, orientations, SH colour)."""
    Rt = torch.as_tensor(np.asarray(R), dtype=g.means.dtype)
    means = g.means @ Rt.T + torch.as_tensor(np.asarray(t), dtype=g.means.dtype)
    qr = torch.as_tensor(matrix_to_quat(np.asarray(R, np.float64)), dtype=g.quats.dtype)
    quats = quat_mul(qr.expand_as(g.quats), g.quats)
    K = g.sh.shape[1]
    degree = int(round(np.sqrt(K))) - 1
    if (degree + 1) ** 2 != K:
        raise InputError(f"Gaussians with {K} SH coefficients: not a full degree")
    D = torch.as_tensor(sh_rotation(R, degree), dtype=g.sh.dtype)
    sh = torch.einsum("kj,njc->nkc", D, g.sh)
    return Gaussians(means, quats, g.scales, g.opacities, sh)


def box_surface_gaussians(box: OrientedBox, color: Float[np.ndarray, "3"], spacing: float = 0.02,
                          opacity: float = 0.95, sh_degree: int = 3, shade=None,
                          toward: Float[np.ndarray, "3"] | None = None) -> Gaussians:
    """Flat Gaussians covering the faces of ``box`` (see the module docstring).
    ``color``: RGB in [0, 1]; ``shade(points [M, 3]) -> [M]`` an optional factor in [0, 1]
    per Gaussian (e.g. darker deeper inside a cabinet); ``toward``: cover only the faces whose
    outward normal points toward this point (a wall's inner faces, seen from inside its cavity:
    its outer faces lie in or outside the carcass, where they would show through)."""
    if not spacing > 0 or not np.all(np.isfinite(box.half)) or np.any(box.half < 0):
        raise InputError(f"box_surface_gaussians: spacing {spacing} or half extents {box.half.tolist()} not usable")
    means, quats, scales = [], [], []
    for c, n, ab, hab in box.faces():
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
