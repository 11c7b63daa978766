"""Gaussians anchored on mesh faces (DRAWER §3.2; the official ``splatfacto_on_mesh_uc``).

Each Gaussian belongs to one face f and is parametrised in the face's fixed frame (x̂ along
edge AB, ŷ = n × x̂, n the unit normal; the triangle embedded in 2D as A=(0,0), B=(c,0), C):

- position: a 2D point clipped to the triangle (barycentric coordinates clipped to [0, 1] and
  renormalised) plus an offset along n clipped to +- ``elevate_coef`` R;
- scales: exp(log-scale) clipped from above to ``upper_scale`` (R, R, ``flat_coef`` R): the
  normal axis is very thin;
- rotation: q_face ⊗ q_tilt ⊗ q_spin, the tilt of the normal axis clipped to ``cone`` rad.

R is the face's circumradius (the official code's choice; the paper
says inradius — we follow the code). Every clip goes through :func:`clip_through`, whose
``mode`` is ``ste`` (forward = clipped value, gradient passed straight to the raw parameter:
x + sg(c(x) − x), the paper's method), ``hard`` (plain clip: zero gradient outside the bounds,
the "movable GS" ablation) or ``free`` (no clip: unconstrained Gaussians).
"""

from dataclasses import dataclass

import numpy as np
import torch
from jaxtyping import Float, Int
from torch import Tensor

from drawer_lib.geometry.rotations import axis_angle_to_quat, matrix_to_quat, quat_mul
from drawer_lib.splat.render import Gaussians
from drawer_lib.splat.sh import C0

CLIP_MODES = ("ste", "hard", "free")


def clip_through(x: Tensor, clipped: Tensor, mode: str) -> Tensor:
    """The one place where a parameter meets its bound. ``ste``: value ``clipped``, gradient of
    ``x`` (identity); ``hard``: ``clipped`` with its own gradient; ``free``: ``x``."""
    if mode == "ste":
        # written as c + (x - sg(x)) rather than x + sg(c - x): the forward value is then exactly
        # c in floating point, however far x has wandered outside the bound
        return clipped.detach() + (x - x.detach())
    if mode == "hard":
        return clipped
    if mode == "free":
        return x
    raise ValueError(f"clip mode {mode!r} must be one of {CLIP_MODES}")


@dataclass
class FaceFrames:
    """Fixed per-face quantities of the (valid, non-degenerate) faces of a mesh."""

    A: Tensor  # [F, 3] first vertex
    xhat: Tensor  # [F, 3]
    yhat: Tensor  # [F, 3]
    normal: Tensor  # [F, 3]
    tri2d: Tensor  # [F, 3, 2] the triangle in its own frame
    radius: Tensor  # [F] circumradius
    area: Tensor  # [F]
    q_face: Tensor  # [F, 4] wxyz of the rotation with columns (x̂, ŷ, n)
    face_ids: Tensor  # [F] index of each frame's face in the input mesh

    @property
    def centroid(self) -> Tensor:
        return self.A + (self.tri2d.mean(1)[:, :1] * self.xhat + self.tri2d.mean(1)[:, 1:] * self.yhat)


def face_frames(verts: Float[Tensor, "V 3"], faces: Int[Tensor, "F 3"], min_area: float = 1e-12) -> FaceFrames:
    """Frames of the faces whose area exceeds ``min_area`` (m^2); degenerate faces (zero area,
    repeated vertices) are left out — ``face_ids`` says which faces remain."""
    P = verts[faces]  # [F, 3, 3]
    A, B, C = P[:, 0], P[:, 1], P[:, 2]
    cr = torch.cross(B - A, C - A, dim=-1)
    area = 0.5 * cr.norm(dim=-1)
    ab = (B - A).norm(dim=-1)
    keep = (area > min_area) & (ab > 0) & torch.isfinite(area)
    ids = torch.nonzero(keep)[:, 0]
    A, B, C, cr, area = A[ids], B[ids], C[ids], cr[ids], area[ids]
    n = cr / (2 * area)[:, None]
    xh = (B - A) / (B - A).norm(dim=-1, keepdim=True)
    yh = torch.cross(n, xh, dim=-1)
    a, b, c = (C - B).norm(dim=-1), (A - C).norm(dim=-1), (B - A).norm(dim=-1)
    xc = ((C - A) * xh).sum(-1)
    yc = ((C - A) * yh).sum(-1)
    tri = torch.stack([torch.zeros_like(xc), torch.zeros_like(xc), c, torch.zeros_like(xc), xc, yc], -1).view(-1, 3, 2)
    R = a * b * c / (4 * area)
    q = matrix_to_quat(torch.stack([xh, yh, n], -1))
    return FaceFrames(A, xh, yh, n, tri, R, area, q, ids)


def subdivide_to_area(verts: np.ndarray, faces: np.ndarray, max_area: float, max_rounds: int = 8
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split every face larger than ``max_area`` 1 -> 4 at its edge midpoints (shared between
    neighbours), repeatedly (at most ``max_rounds``). Returns (verts, faces, parent face id)."""
    V = np.asarray(verts, np.float64)
    Fc = np.asarray(faces, np.int64)
    parent = np.arange(len(Fc))
    for _ in range(max_rounds):
        P = V[Fc]
        area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
        big = area > max_area
        if not big.any():
            break
        fb = Fc[big]
        edges = np.concatenate([fb[:, [0, 1]], fb[:, [1, 2]], fb[:, [2, 0]]])
        key = np.sort(edges, 1)
        # unique edges as one int64 each (a n + b orders like the rows (a, b)): the same result as
        # np.unique(key, axis=0), ~10x faster (no structured-row sort)
        n = np.int64(len(V))
        uk, inv = np.unique(key[:, 0] * n + key[:, 1], return_inverse=True)
        uniq = np.stack([uk // n, uk % n], 1)
        inv = inv.reshape(-1)
        mids = 0.5 * (V[uniq[:, 0]] + V[uniq[:, 1]])
        mid_id = len(V) + inv.reshape(3, -1).T  # [Fb, 3]: midpoints of (01, 12, 20)
        V = np.concatenate([V, mids])
        v0, v1, v2 = fb[:, 0], fb[:, 1], fb[:, 2]
        m01, m12, m20 = mid_id[:, 0], mid_id[:, 1], mid_id[:, 2]
        new = np.concatenate([np.stack([v0, m01, m20], 1), np.stack([m01, v1, m12], 1), np.stack([m20, m12, v2], 1),
                              np.stack([m01, m12, m20], 1)])
        Fc = np.concatenate([Fc[~big], new])
        parent = np.concatenate([parent[~big], np.tile(parent[big], 4)])
    return V, Fc, parent


@dataclass(frozen=True)
class AnchorBounds:
    """Bounds in units of the face circumradius R: offset along the normal within +-
    ``elevate_coef`` R; scales <= ``upper_scale`` x (R, R, ``flat_coef`` R); tilt <= ``cone``."""

    elevate_coef: float = 2.0
    upper_scale: float = 2.0
    flat_coef: float = 0.005
    cone: float = 0.17453292519943295  # 10 degrees


@dataclass
class AnchoredParams:
    """Raw (trainable) parameters, row-aligned with ``face`` (index into FaceFrames)."""

    means_2d: Tensor  # [N, 2]
    elevate: Tensor  # [N]
    log_scales: Tensor  # [N, 3]
    angles: Tensor  # [N, 3] spin theta, tilt azimuth alpha, tilt phi
    sh_dc: Tensor  # [N, 1, 3]
    sh_rest: Tensor  # [N, K - 1, 3]
    opacity_logit: Tensor  # [N]
    face: Tensor  # [N] long, not trained

    def trainable(self) -> dict[str, Tensor]:
        return {k: v for k, v in vars(self).items() if k != "face"}


def init_anchored(frames: FaceFrames, colors: Float[Tensor, "F 3"], sh_degree: int = 3,
                  opacity: float = 0.1) -> AnchoredParams:
    """One Gaussian per face at its centroid; isotropic scale = mean distance to the 3 nearest
    face centroids; DC colour from ``colors`` (per frame, in [0, 1])."""
    from scipy.spatial import cKDTree

    F = frames.A.shape[0]
    cen = frames.centroid.detach().double().numpy()
    k = min(4, F)
    d, _ = cKDTree(cen).query(cen, k=k)
    spacing = d[:, 1:].mean(1) if k > 1 else np.full(F, float(frames.radius.mean()))
    spacing = np.maximum(spacing, 1e-7)
    dt = frames.A.dtype
    K = (sh_degree + 1) ** 2
    return AnchoredParams(
        means_2d=frames.tri2d.mean(1).clone(),
        elevate=torch.zeros(F, dtype=dt),
        log_scales=torch.log(torch.tensor(spacing, dtype=dt))[:, None].repeat(1, 3),
        angles=torch.zeros(F, 3, dtype=dt),
        sh_dc=((colors.to(dt) - 0.5) / C0)[:, None, :],
        sh_rest=torch.zeros(F, K - 1, 3, dtype=dt),
        opacity_logit=torch.full((F,), float(np.log(opacity / (1 - opacity))), dtype=dt),
        face=torch.arange(F),
    )


def barycentric_clip(p: Float[Tensor, "N 2"], tri: Float[Tensor, "N 3 2"]) -> Float[Tensor, "N 2"]:
    """Barycentric coordinates of ``p`` in ``tri`` clipped to [0, 1], renormalised to sum 1,
    mapped back (the official code's projection; not the Euclidean one)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (v0 * v0).sum(-1), (v0 * v1).sum(-1), (v1 * v1).sum(-1)
    d20, d21 = (v2 * v0).sum(-1), (v2 * v1).sum(-1)
    den = (d00 * d11 - d01 * d01).clamp_min(1e-30)
    l1 = (d11 * d20 - d01 * d21) / den
    l2 = (d00 * d21 - d01 * d20) / den
    lam = torch.stack([1 - l1 - l2, l1, l2], -1).clamp(0, 1)
    lam = lam / lam.sum(-1, keepdim=True).clamp_min(1e-30)
    return (lam[..., None] * tri).sum(1)


@dataclass
class Anchored:
    """What the forward parametrisation gives: Gaussians plus the clipped quantities."""

    gaussians: Gaussians
    pos2d: Tensor  # [N, 2] clipped in-face position
    elevate: Tensor  # [N]
    scales: Tensor  # [N, 3]
    tilt: Tensor  # [N]


class _AnchoredFn(torch.autograd.Function):
    """The fused numba kernels of :func:`anchored_gaussians` (modes ``ste`` and ``free``)."""

    @staticmethod
    def forward(ctx, means_2d, elevate, log_scales, angles, opacity_logit, face, frames, bounds, clip):
        from drawer_lib.splat import _anchored_kernels as AK

        dt = means_2d.dtype
        n = means_2d.shape[0]
        npy = lambda t: t.detach().contiguous().numpy()  # noqa: E731
        raw = [npy(t) for t in (means_2d, elevate, log_scales, angles, opacity_logit)]
        fr = [npy(t) for t in (frames.A, frames.xhat, frames.yhat, frames.normal, frames.tri2d, frames.radius,
                               frames.q_face)]
        fc = npy(face)
        outs = [torch.empty(s, dtype=dt) for s in ((n, 3), (n, 4), (n, 3), (n,), (n, 2), (n,), (n,))]
        aux = np.empty((n if any(ctx.needs_input_grad[:5]) else 0, AK.N_AUX))  # kept for the backward pass
        AK.anchored_forward(*raw, fc, *fr, float(bounds.elevate_coef), float(bounds.upper_scale),
                            float(bounds.flat_coef), float(bounds.cone), clip, *(o.numpy() for o in outs), aux)
        ctx.state = (aux, fc, fr[1], fr[2], fr[3], fr[6], dt, n)
        return tuple(outs)

    @staticmethod
    def backward(ctx, g_means, g_quats, g_scales, g_opac, g_pos2d, g_elev, g_tilt):
        from drawer_lib.splat import _anchored_kernels as AK

        aux, fc, xh, yh, nm, qf, dt, n = ctx.state
        npdt = xh.dtype
        shapes = ((n, 3), (n, 4), (n, 3), (n,), (n, 2), (n,), (n,))
        gs = [np.zeros(s, npdt) if g is None else g.detach().to(dt).contiguous().numpy()
              for g, s in zip((g_means, g_quats, g_scales, g_opac, g_pos2d, g_elev, g_tilt), shapes)]
        res = [np.empty(s, npdt) for s in ((n, 2), (n,), (n, 3), (n, 3), (n,))]
        AK.anchored_backward(aux, fc, xh, yh, nm, qf, *gs, *res)
        return (*(torch.from_numpy(r) for r in res), None, None, None, None)


def anchored_gaussians(p: AnchoredParams, frames: FaceFrames, bounds: AnchorBounds, mode: str = "ste",
                       fused: bool = True) -> Anchored:
    """Raw parameters -> activated 3D Gaussians (positions, rotations, scales in the world).
    ``fused``: modes ``ste`` and ``free`` on CPU tensors run the numba kernels of
    ``_anchored_kernels`` (equal to this PyTorch code up to float rounding); False, or mode
    ``hard``, runs the PyTorch code."""
    if fused and mode in ("ste", "free") and p.means_2d.device.type == "cpu":
        ts = (p.means_2d, p.elevate, p.log_scales, p.angles, p.opacity_logit)
        if all(t.dtype == frames.A.dtype for t in ts):
            means, q, s, opac, pos2d, e, phi_c = _AnchoredFn.apply(*ts, p.face, frames, bounds, mode == "ste")
            sh = torch.cat([p.sh_dc, p.sh_rest], 1)
            return Anchored(Gaussians(means, q, s, opac, sh, sh_parts=(p.sh_dc, p.sh_rest)), pos2d, e, s, phi_c)
    f = p.face
    tri, R = frames.tri2d[f], frames.radius[f]
    pos2d = clip_through(p.means_2d, barycentric_clip(p.means_2d, tri), mode)
    e = clip_through(p.elevate, torch.maximum(torch.minimum(p.elevate, bounds.elevate_coef * R), -bounds.elevate_coef * R),
                     mode)
    means = frames.A[f] + pos2d[:, :1] * frames.xhat[f] + pos2d[:, 1:] * frames.yhat[f] + e[:, None] * frames.normal[f]
    s = torch.exp(p.log_scales)
    cap = bounds.upper_scale * torch.stack([R, R, bounds.flat_coef * R], -1)
    s = clip_through(s, torch.minimum(s, cap), mode)
    theta, alpha, phi = p.angles.unbind(-1)
    phi_c = clip_through(phi, phi.clamp(0.0, bounds.cone), mode)
    q_spin = axis_angle_to_quat(torch.stack([torch.zeros_like(theta), torch.zeros_like(theta), theta], -1))
    q_tilt = axis_angle_to_quat(torch.stack([torch.cos(alpha), torch.sin(alpha), torch.zeros_like(alpha)], -1) * phi_c[:, None])
    q = quat_mul(frames.q_face[f], quat_mul(q_tilt, q_spin))
    sh = torch.cat([p.sh_dc, p.sh_rest], 1)
    g = Gaussians(means, q, s, torch.sigmoid(p.opacity_logit), sh)
    return Anchored(g, pos2d, e, s, phi_c)


def distance_to_triangle_2d(p: Tensor, tri: Tensor) -> Tensor:
    """Euclidean distance [N] from 2D points [N, 2] to filled triangles [N, 3, 2] (0 inside);
    edge functions and segment distances, well conditioned even for sliver triangles."""
    p, tri = p.double(), tri.double()
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    cross = lambda u, v: u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]  # noqa: E731
    orient = torch.sign(cross(b - a, c - a))
    inside = ((orient * cross(b - a, p - a) >= 0) & (orient * cross(c - b, p - b) >= 0)
              & (orient * cross(a - c, p - c) >= 0))

    def seg(u, v):
        d = v - u
        t = (((p - u) * d).sum(-1) / (d * d).sum(-1).clamp_min(1e-300)).clamp(0, 1)
        return (p - (u + t[:, None] * d)).norm(dim=-1)

    dist = torch.minimum(torch.minimum(seg(a, b), seg(b, c)), seg(c, a))
    return torch.where(inside, torch.zeros_like(dist), dist)


def bounds_violation(a: Anchored, p: AnchoredParams, frames: FaceFrames, bounds: AnchorBounds,
                     tol: float = 1e-5) -> str | None:
    """None when every Gaussian of ``a`` lies within its face bounds (relative tolerance
    ``tol``), else a message naming the first one outside and the bound it breaks."""
    f = p.face
    R = frames.radius[f]
    tri = frames.tri2d[f]
    inside = distance_to_triangle_2d(a.pos2d, tri) <= tol * R.double() + 1e-7
    ok_e = a.elevate.abs() <= bounds.elevate_coef * R * (1 + tol)
    cap = bounds.upper_scale * torch.stack([R, R, bounds.flat_coef * R], -1)
    ok_s = (a.scales <= cap * (1 + tol)).all(-1)
    ok_t = (a.tilt >= -tol) & (a.tilt <= bounds.cone + tol)
    for name, ok in (("in-face position", inside), ("normal offset", ok_e), ("scale", ok_s), ("tilt", ok_t)):
        if not bool(ok.all()):
            i = int(torch.nonzero(~ok)[0, 0])
            return f"Gaussian {i} (face {int(f[i])}) violates its {name} bound"
    return None


@torch.no_grad()
def bound_activity(p: AnchoredParams, frames: FaceFrames, bounds: AnchorBounds, tol: float = 1e-6) -> dict[str, float]:
    """Fraction of Gaussians whose *raw* parameter lies on or beyond each bound (where the clip
    is active: zero gradient under ``hard``, identity under ``ste``). Keys: ``position``
    (outside the triangle), ``offset``, ``scale_plane`` (an in-plane axis at its cap),
    ``scale_normal``, ``tilt`` (outside [0, cone]), ``any``."""
    f = p.face
    n = max(int(f.shape[0]), 1)
    R = frames.radius[f].double()
    out_pos = distance_to_triangle_2d(p.means_2d.detach(), frames.tri2d[f]) > tol * R
    out_e = p.elevate.detach().double().abs() >= bounds.elevate_coef * R * (1 - tol)
    s = torch.exp(p.log_scales.detach().double())
    cap = bounds.upper_scale * torch.stack([R, R, bounds.flat_coef * R], -1)
    at_cap = s >= cap * (1 - tol)
    phi = p.angles.detach()[:, 2].double()
    out_t = (phi < 0) | (phi > bounds.cone)
    masks = {"position": out_pos, "offset": out_e, "scale_plane": at_cap[:, :2].any(-1), "scale_normal": at_cap[:, 2],
             "tilt": out_t}
    res = {k: float(v.sum()) / n for k, v in masks.items()}
    anyv = torch.zeros_like(out_pos)
    for v in masks.values():
        anyv |= v
    res["any"] = float(anyv.sum()) / n
    return res
