"""Projection of 3D Gaussians to the image (EWA splatting), differentiable, in PyTorch.

Conventions: quaternions wxyz (normalised here), scales are standard deviations (not logs),
``viewmat`` is the OpenCV world-to-camera [4, 4] tensor, ``intr`` the camera's
:class:`~drawer_lib.geometry.camera.Intrinsics` (pixel centres at integer + 0.5, this library's
convention, also gsplat's). The 2D covariance is
J W Sigma W^T J^T + eps2d I (gsplat's "classic" 0.3 px low-pass), with the Jacobian's x/z and
y/z clamped to the image plus 30 % of its size (3DGS, gsplat) so Gaussians far outside the frustum do not
blow up. Culled Gaussians (behind ``near``, beyond ``far``, off-screen, degenerate covariance)
get radius 0 and no gradient.
"""

from dataclasses import dataclass

import numpy as np
import torch
from jaxtyping import Float
from torch import Tensor

from drawer_lib.geometry.camera import Intrinsics
from drawer_lib.geometry.rotations import quat_to_matrix


@dataclass
class Projected:
    means2d: Tensor  # [N, 2] pixels
    conics: Tensor  # [N, 3] (a, b, c) of the inverse 2D covariance
    depths: Tensor  # [N] camera z
    radii: Tensor  # [N] int32, 0 = culled (ceil of 3.33 sigma of the larger 2D axis, pixels)
    cov2d: Tensor | None  # [N, 2, 2] with the low-pass (None from the fused kernel)


def quat_scale_to_covar(quats: Float[Tensor, "N 4"], scales: Float[Tensor, "N 3"]) -> Float[Tensor, "N 3 3"]:
    """Sigma = R diag(s^2) R^T with R from the (normalised) wxyz quaternion."""
    M = quat_to_matrix(quats) * scales[:, None, :]
    return M @ M.transpose(1, 2)


def project_gaussians(means: Float[Tensor, "N 3"], covars: Float[Tensor, "N 3 3"], viewmat: Float[Tensor, "4 4"],
                      intr: Intrinsics, near: float = 0.01, far: float = 1e10, eps2d: float = 0.3,
                      radius_clip: float = 0.0) -> Projected:
    """The PyTorch reference projection (differentiable in every input, ``viewmat`` included)."""
    fx, fy, cx, cy = intr.params
    width, height = intr.width, intr.height
    Rw, tw = viewmat[:3, :3], viewmat[:3, 3]
    pc = means @ Rw.T + tw  # [N, 3]
    z = pc[:, 2]
    valid = (z > near) & (z < far)
    zs = torch.where(valid, z, torch.ones_like(z))
    # the Jacobian is taken at x/z, y/z clamped to the image plus 30 % of its size on each side
    tx = (pc[:, 0] / zs).clamp(-(cx / fx + 0.3 * width / fx), (width - cx) / fx + 0.3 * width / fx)
    ty = (pc[:, 1] / zs).clamp(-(cy / fy + 0.3 * height / fy), (height - cy) / fy + 0.3 * height / fy)
    zero = torch.zeros_like(zs)
    J = torch.stack([fx / zs, zero, -fx * tx / zs, zero, fy / zs, -fy * ty / zs], -1).view(-1, 2, 3)
    JW = J @ Rw
    cov2d = JW @ covars @ JW.transpose(1, 2)
    cov2d = cov2d + eps2d * torch.eye(2, dtype=cov2d.dtype)
    a, b, c = cov2d[:, 0, 0], cov2d[:, 0, 1], cov2d[:, 1, 1]
    det = a * c - b * b
    valid = valid & (det > 0) & torch.isfinite(det)
    det_s = torch.where(valid, det, torch.ones_like(det))
    conics = torch.stack([c / det_s, -b / det_s, a / det_s], -1)
    mid = 0.5 * (a + c)
    lam = mid + torch.sqrt((mid * mid - det_s).clamp_min(0.01))
    radius = torch.ceil(3.33 * torch.sqrt(lam.detach()))  # sqrt(2 ln 255) = 3.329: alpha < 1/255 beyond, at any opacity
    means2d = torch.stack([fx * pc[:, 0] / zs + cx, fy * pc[:, 1] / zs + cy], -1)
    m = means2d.detach()
    on = (m[:, 0] + radius > 0) & (m[:, 0] - radius < width) & (m[:, 1] + radius > 0) & (m[:, 1] - radius < height)
    valid = valid & on & (radius > radius_clip) & torch.isfinite(m).all(-1)
    radii = torch.where(valid, radius, torch.zeros_like(radius)).to(torch.int32)
    # culled Gaussians keep finite placeholders (they are in no tile, so get no gradient)
    keep = valid[:, None]
    return Projected(torch.where(keep, means2d, torch.zeros_like(means2d)),
                     torch.where(keep, conics, torch.zeros_like(conics)), z, radii, cov2d)


class _ProjectFn(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means, quats, scales, viewmat, intr, near, far, eps2d):
        from drawer_lib.splat import _project_kernels as PK

        n = means.shape[0]
        m, q, s = (t.detach().contiguous().numpy() for t in (means, quats, scales))
        V = viewmat.detach().to(torch.float64).contiguous().numpy()
        means2d = np.zeros((n, 2), m.dtype)
        conics = np.zeros((n, 3), m.dtype)
        depths = np.zeros(n, m.dtype)
        radii = np.zeros(n, np.int32)
        PK.project_forward(m, q, s, V, *map(float, intr.params), intr.width, intr.height, near, far, eps2d, means2d,
                           conics, depths, radii)
        ctx.state = (m, q, s, V, intr, eps2d, radii)
        return torch.from_numpy(means2d), torch.from_numpy(conics), torch.from_numpy(depths), torch.from_numpy(radii)

    @staticmethod
    def backward(ctx, g_means2d, g_conics, g_depths, _g_radii):
        from drawer_lib.splat import _project_kernels as PK

        m, q, s, V, intr, eps2d, radii = ctx.state
        f = lambda g: g.detach().to(torch.from_numpy(m).dtype).contiguous().numpy()  # noqa: E731
        gm, gq, gs = np.empty_like(m), np.empty_like(q), np.empty_like(s)
        PK.project_backward(m, q, s, V, *map(float, intr.params), intr.width, intr.height, eps2d, radii, f(g_means2d),
                            f(g_conics), f(g_depths), gm, gq, gs)
        return torch.from_numpy(gm), torch.from_numpy(gq), torch.from_numpy(gs), None, None, None, None, None


def project_gaussians_fused(means: Float[Tensor, "N 3"], quats: Float[Tensor, "N 4"], scales: Float[Tensor, "N 3"],
                            viewmat: Float[Tensor, "4 4"], intr: Intrinsics, near: float = 0.01, far: float = 1e10,
                            eps2d: float = 0.3) -> Projected:
    """:func:`project_gaussians` of ``quat_scale_to_covar(quats, scales)`` in one numba kernel
    (forward and backward); no gradient to ``viewmat``; ``cov2d`` is not returned (None)."""
    if means.device.type != "cpu":
        raise ValueError("project_gaussians_fused runs on CPU tensors")
    if viewmat.requires_grad:
        raise ValueError("project_gaussians_fused: no gradient to viewmat; use project_gaussians (camera optimisation)")
    means2d, conics, depths, radii = _ProjectFn.apply(means, quats, scales, viewmat, intr, near, far, eps2d)
    return Projected(means2d, conics, depths, radii, None)
