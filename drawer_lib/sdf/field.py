"""The neural SDF field: a multi-resolution grid encoding, a small SDF MLP, a colour head.

    s(x)   = s0(x) + mlp_sdf(enc(x))[0]          s0: geometric initialisation
    rgb    = sigmoid(mlp_rgb(mlp_sdf(enc(x))[1:], SH_2(view dir)))

Geometric initialisation: s0 is the signed distance of an inside-out capsule (the points within
``radius`` of a segment; a sphere when the segment is a point) around the cameras, positive in
the free space around them, as DRAWER's inside_outside init; a capsule along a long camera path
keeps every camera inside it, where one sphere of the viewing depth would leave the ends of a
wide kitchen's run inside the solid (sdf/train.py: init_axis). The last SDF layer starts at zero, so training starts from an exact SDF (|grad s| = 1) whatever the
encoding's random init. The SDF head has one hidden softplus layer, so its Jacobian is written
out and grad s = ds0/dx + J_mlp . d enc / dx is exact and cheap (no double backward).
"""

import torch
import torch.nn.functional as F
from jaxtyping import Float
from torch import Tensor, nn

from drawer_lib.sdf.encoding import MultiResGrid

SOFTPLUS_BETA = 100.0


def sh2(d: Float[Tensor, "N 3"]) -> Float[Tensor, "N 9"]:
    """Real spherical harmonics up to degree 2 of unit directions (the usual 3DGS constants)."""
    x, y, z = d.unbind(-1)
    return torch.stack([
        torch.full_like(x, 0.28209479), -0.48860251 * y, 0.48860251 * z, -0.48860251 * x,
        1.09254843 * x * y, -1.09254843 * y * z, 0.31539157 * (2 * z * z - x * x - y * y),
        -1.09254843 * x * z, 0.54627421 * (x * x - y * y)], -1)


class SDFField(nn.Module):
    def __init__(self, lo: Tensor, hi: Tensor, sphere_center: Tensor, sphere_radius: float, n_levels: int = 8,
                 n_features: int = 2, cell_coarse: float = 0.32, cell_fine: float = 0.02, log2_table: int = 19,
                 hidden: int = 64, geo_features: int = 15, color_hidden: int = 64, view_dependent: bool = True,
                 backend: str = "numba"):
        super().__init__()
        self.enc = MultiResGrid(lo, hi, n_levels, n_features, cell_coarse, cell_fine, log2_table, backend=backend)
        c = torch.as_tensor(sphere_center, dtype=torch.float32)
        self.register_buffer("center", c.expand(2, 3).clone() if c.dim() == 1 else c)  # [2, 3]: the segment
        self.radius = float(sphere_radius)
        D = self.enc.out_dim
        self.l1 = nn.Linear(D, hidden)
        self.l2 = nn.Linear(hidden, 1 + geo_features)
        nn.init.zeros_(self.l2.weight)
        nn.init.zeros_(self.l2.bias)
        self.view_dependent = view_dependent
        self.c1 = nn.Linear(geo_features + (9 if view_dependent else 0), color_hidden)
        self.c2 = nn.Linear(color_hidden, 3)

    def _base(self, x: Tensor) -> tuple[Tensor, Tensor]:
        a, ab = self.center[0], self.center[1] - self.center[0]
        h = ((x - a) @ ab / (ab @ ab).clamp_min(1e-12)).clamp(0.0, 1.0)
        r = x - a - h[:, None] * ab  # from the closest point of the segment
        n = r.norm(dim=-1, keepdim=True).clamp_min(1e-9)
        return self.radius - n[:, 0], -r / n  # inside-out capsule: s0 and its gradient

    def sdf(self, x: Float[Tensor, "N 3"]) -> Float[Tensor, "N"]:
        """Signed distance only (no colour, no gradient): for sampling and mesh extraction."""
        f, _ = self.enc(x)
        h = F.softplus(self.l1(f), beta=SOFTPLUS_BETA)
        return self._base(x)[0] + self.l2(h)[:, 0]

    def forward(self, x: Float[Tensor, "N 3"], dirs: Float[Tensor, "N 3"] | None = None,
                with_grad: bool = True) -> tuple[Tensor, Tensor | None, Tensor | None]:
        """(sdf [N], grad sdf [N, 3] or None, rgb [N, 3] or None when dirs is None)."""
        f, df = self.enc(x, with_grad=with_grad)
        pre = self.l1(f)
        h = F.softplus(pre, beta=SOFTPLUS_BETA)
        out = self.l2(h)
        s0, g0 = self._base(x)
        s = s0 + out[:, 0]
        grad = None
        if with_grad:
            # ds/df = (w2[0] * softplus'(pre)) @ W1, softplus' = sigmoid(beta * pre)
            J = (self.l2.weight[0] * torch.sigmoid(SOFTPLUS_BETA * pre)) @ self.l1.weight  # [N, D]
            grad = g0 + torch.einsum("nd,ndk->nk", J, df)
        rgb = None
        if dirs is not None:
            geo = out[:, 1:]
            if self.view_dependent:
                geo = torch.cat([geo, sh2(F.normalize(dirs, dim=-1))], -1)
            rgb = torch.sigmoid(self.c2(F.relu(self.c1(geo))))
        return s, grad, rgb
