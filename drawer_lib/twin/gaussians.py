"""Gaussians of a twin's bodies: read an INRIA-layout PLY back into :class:`Gaussians`, move a
set rigidly (means, orientations and the view-dependent colour), and the rigid motion of a
part's joint at ``q``.

Moving Gaussians by a rotation R: means -> R m + t, orientations -> q_R * q, and the SH colour
c(d) -> c(R^T d), i.e. every degree-l band of the coefficients is multiplied by a (2l+1)^2
matrix. That matrix is found without Wigner formulas: the degree-l real SH span a space that
rotations map to itself, so evaluating the basis at enough directions d_i and at R^T d_i and
solving ``Y(R^T d) = Y(d) D`` in least squares gives D exactly (up to float error);
:func:`sh_rotation` is tested against the definition c'(R d) = c(d).
"""

from pathlib import Path

import numpy as np
import torch
from jaxtyping import Float
from torch import Tensor

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import Camera
from drawer_lib.geometry.joints import joint_transform
from drawer_lib.geometry.rotations import matrix_to_quat, quat_mul
from drawer_lib.io.parts import Part
from drawer_lib.splat.ply import read_gaussian_ply
from drawer_lib.splat.project import project_gaussians_fused
from drawer_lib.splat.rasterize import composite
from drawer_lib.splat.render import Gaussians
from drawer_lib.splat.sh import sh_to_color


def load_gaussian_ply(path: Path) -> Gaussians:
    """The activated Gaussians of an INRIA-layout PLY (:func:`drawer_lib.splat.ply.write_gaussian_ply`)."""
    c = read_gaussian_ply(path)
    need = {"x", "y", "z", "f_dc_0", "opacity", "scale_0", "rot_0"}
    if not need <= set(c):
        raise InputError(f"{path}: not a Gaussian PLY (missing {sorted(need - set(c))})")
    n = len(c["x"])
    k_rest = sum(k.startswith("f_rest_") for k in c) // 3
    t = lambda *ks: torch.from_numpy(np.stack([c[k] for k in ks], -1).astype(np.float32))  # noqa: E731
    rest = (t(*[f"f_rest_{i}" for i in range(3 * k_rest)]).view(n, 3, k_rest).transpose(1, 2)
            if k_rest else torch.zeros(n, 0, 3))
    sh = torch.cat([t("f_dc_0", "f_dc_1", "f_dc_2")[:, None], rest], 1)
    return Gaussians(t("x", "y", "z"), t("rot_0", "rot_1", "rot_2", "rot_3"), torch.exp(t("scale_0", "scale_1", "scale_2")),
                     torch.sigmoid(torch.from_numpy(c["opacity"].astype(np.float32))), sh)


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


def joint_motion(part: Part, q: float) -> tuple[np.ndarray, np.ndarray]:
    """(R [3, 3], t [3]) of the part's body at joint value ``q`` (rad or m)
    (:func:`drawer_lib.geometry.joints.joint_transform`; DESIGN §5: positive q opens); an
    unusable axis or q is an error naming the part."""
    if not part.articulated:
        raise InputError(f"part {part.id}: {part.kind} parts have no joint")
    a = np.asarray(part.axis.direction, np.float64)
    if not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-9 or not np.isfinite(q):
        raise InputError(f"part {part.id}: axis direction {part.axis.direction} or q = {q} is not usable")
    T = joint_transform(part.kind, np.asarray(part.axis.origin, np.float64), a, q)
    return T[:3, :3], T[:3, 3]
