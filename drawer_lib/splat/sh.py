"""Real spherical harmonics colours (degree <= 3, the 3DGS / gsplat constants and sign order)."""

import numpy as np
import torch
from jaxtyping import Float
from torch import Tensor

C0 = 0.28209479177387814
C1 = 0.4886025119029199
C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658,
      1.445305721320277, -0.5900435899266435)


def num_sh_bases(degree: int) -> int:
    return (degree + 1) ** 2


def sh_to_color(coeffs: Float[Tensor, "N K 3"], dirs: Float[Tensor, "N 3"], degree: int) -> Float[Tensor, "N 3"]:
    """RGB = max(sum_k c_k Y_k(d) + 0.5, 0) using the first (degree + 1)^2 of the K >= that many
    coefficients; ``dirs`` need not be normalised."""
    if not 0 <= degree <= 3 or coeffs.shape[1] < num_sh_bases(degree):
        raise ValueError(f"sh_to_color: degree {degree} needs {num_sh_bases(degree)} coefficients, got {coeffs.shape[1]}")
    d = dirs / dirs.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    x, y, z = d[:, 0:1], d[:, 1:2], d[:, 2:3]
    out = C0 * coeffs[:, 0]
    if degree >= 1:
        out = out - C1 * y * coeffs[:, 1] + C1 * z * coeffs[:, 2] - C1 * x * coeffs[:, 3]
    if degree >= 2:
        xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
        out = (out + C2[0] * xy * coeffs[:, 4] + C2[1] * yz * coeffs[:, 5] + C2[2] * (2 * zz - xx - yy) * coeffs[:, 6]
               + C2[3] * xz * coeffs[:, 7] + C2[4] * (xx - yy) * coeffs[:, 8])
    if degree >= 3:
        out = (out + C3[0] * y * (3 * xx - yy) * coeffs[:, 9] + C3[1] * xy * z * coeffs[:, 10]
               + C3[2] * y * (4 * zz - xx - yy) * coeffs[:, 11] + C3[3] * z * (2 * zz - 3 * xx - 3 * yy) * coeffs[:, 12]
               + C3[4] * x * (4 * zz - xx - yy) * coeffs[:, 13] + C3[5] * z * (xx - yy) * coeffs[:, 14]
               + C3[6] * x * (xx - 3 * yy) * coeffs[:, 15])
    return (out + 0.5).clamp_min(0.0)


class _ShFn(torch.autograd.Function):
    """The fused SH colour of coefficients [N, K, 3] (``rest`` None) or given as dc [N, 1, 3] and
    rest [N, K - 1, 3]: then each gets its own contiguous gradient, so that the [N, K, 3]
    gradient of their concatenation is never formed."""

    @staticmethod
    def forward(ctx, coeffs, rest, dirs, degree):
        from drawer_lib.splat import _project_kernels as PK

        c, d = coeffs.detach().contiguous().numpy(), dirs.detach().contiguous().numpy()
        c0, cr = (c[:, :1], c[:, 1:]) if rest is None else (c, rest.detach().contiguous().numpy())
        out = np.empty((c.shape[0], 3), c.dtype)
        PK.sh_forward(c0, cr, d, degree, out)
        ctx.state = (c, c0, cr, d, degree, rest is None)
        return torch.from_numpy(out)

    @staticmethod
    def backward(ctx, g):
        from drawer_lib.splat import _project_kernels as PK

        c, c0, cr, d, degree, joined = ctx.state
        gd = np.empty_like(d)
        gc = np.empty_like(c)
        g0, gr = (gc[:, :1], gc[:, 1:]) if joined else (gc, np.empty_like(cr))
        PK.sh_backward(c0, cr, d, degree, g.detach().to(torch.from_numpy(c).dtype).contiguous().numpy(), g0, gr, gd)
        return torch.from_numpy(gc), None if joined else torch.from_numpy(gr), torch.from_numpy(gd), None


def sh_to_color_fused(coeffs: Float[Tensor, "N K 3"], dirs: Float[Tensor, "N 3"], degree: int,
                      rest: Float[Tensor, "N R 3"] | None = None) -> Float[Tensor, "N 3"]:
    """:func:`sh_to_color` in one numba kernel (forward and backward, gradients to both inputs).
    With ``rest``, ``coeffs`` holds only the DC coefficients [N, 1, 3] and ``rest`` the others
    [N, K - 1, 3] (the colours of their concatenation; the gradients go to each directly)."""
    n_coef = coeffs.shape[1] if rest is None else 1 + rest.shape[1]
    if rest is not None and (coeffs.shape[1] != 1 or rest.shape[0] != coeffs.shape[0] or rest.shape[2] != 3):
        raise ValueError(f"sh_to_color_fused: dc {tuple(coeffs.shape)} and rest {tuple(rest.shape)} must be [N, 1, 3] "
                         "and [N, K - 1, 3]")
    if not 0 <= degree <= 3 or n_coef < num_sh_bases(degree):
        raise ValueError(f"sh_to_color: degree {degree} needs {num_sh_bases(degree)} coefficients, got {n_coef}")
    if coeffs.dtype != dirs.dtype or (rest is not None and rest.dtype != dirs.dtype):
        raise TypeError("sh_to_color_fused: coeffs and dirs must share a dtype")
    return _ShFn.apply(coeffs, rest, dirs, degree)
