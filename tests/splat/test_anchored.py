"""Face-anchored Gaussians: frames, clipping through the one named function, bounds, subdivision,
degenerate faces."""

import math

import numpy as np
import pytest
import torch

from drawer_lib.geometry.rotations import matrix_to_quat
from drawer_lib.splat.anchored import (AnchorBounds, anchored_gaussians, barycentric_clip, bound_activity, bounds_violation,
                                       clip_through, face_frames, init_anchored, subdivide_to_area)
from drawer_lib.splat.project import quat_scale_to_covar


def mesh():
    V = torch.tensor([[0, 0, 0], [1, 0, 0], [0.3, 0.8, 0], [0.2, 0.1, 0.9], [5, 5, 5]], dtype=torch.float64)
    F = torch.tensor([[0, 1, 2], [0, 1, 3], [1, 2, 3], [4, 4, 0], [0, 1, 1]])  # last two degenerate
    return V, F


def test_clip_through_modes():
    x = torch.tensor([-1.0, 0.5, 2.0], requires_grad=True)
    c = x.clamp(0, 1)
    for mode, val, grad in (("ste", [0, 0.5, 1], [1, 1, 1]), ("hard", [0, 0.5, 1], [0, 1, 0]),
                            ("free", [-1, 0.5, 2], [1, 1, 1])):
        x.grad = None
        y = clip_through(x, x.clamp(0, 1), mode)
        y.sum().backward()
        assert y.tolist() == val and x.grad.tolist() == grad, mode
    with pytest.raises(ValueError):
        clip_through(x, c, "soft")


def test_face_frames_embed_the_triangle_and_skip_degenerate_faces():
    V, F = mesh()
    fr = face_frames(V, F)
    assert fr.face_ids.tolist() == [0, 1, 2]
    P = V[F[fr.face_ids]]
    for k in range(3):  # the 2D triangle maps back onto the 3D vertices
        back = fr.A + fr.tri2d[:, k, :1] * fr.xhat + fr.tri2d[:, k, 1:] * fr.yhat
        torch.testing.assert_close(back, P[:, k])
    Rm = torch.stack([fr.xhat, fr.yhat, fr.normal], -1)
    torch.testing.assert_close(Rm.transpose(1, 2) @ Rm, torch.eye(3, dtype=torch.float64).expand(3, 3, 3))
    assert torch.all(torch.linalg.det(Rm) > 0)
    # quaternion of the frame
    C = quat_scale_to_covar(fr.q_face, torch.tensor([[1.0, 2.0, 3.0]], dtype=torch.float64).repeat(3, 1))
    torch.testing.assert_close(C, Rm @ torch.diag(torch.tensor([1.0, 4.0, 9.0], dtype=torch.float64)) @ Rm.transpose(1, 2))
    # circumradius: all three vertices at distance R from the circumcentre (2D)
    t = fr.tri2d[0]
    a2 = (t**2).sum(-1)
    D = 2 * (t[1, 0] * t[2, 1] - t[2, 0] * t[1, 1])
    ux = (a2[1] * t[2, 1] - a2[2] * t[1, 1]) / D
    uy = (a2[2] * t[1, 0] - a2[1] * t[2, 0]) / D
    assert float(torch.hypot(ux, uy)) == pytest.approx(float(fr.radius[0]))


def test_matrix_to_quat_round_trip_near_180_degrees():
    g = torch.Generator().manual_seed(0)
    q = torch.randn(200, 4, generator=g, dtype=torch.float64)
    q[:50, 0] = 1e-9  # rotations by ~180 degrees
    q = q / q.norm(dim=-1, keepdim=True)
    w, x, y, z = q.unbind(-1)
    R = torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y), 2 * (x * y + w * z),
                     1 - 2 * (x * x + z * z), 2 * (y * z - w * x), 2 * (x * z - w * y), 2 * (y * z + w * x),
                     1 - 2 * (x * x + y * y)], -1).view(-1, 3, 3)
    q2 = matrix_to_quat(R)
    assert torch.allclose((q2 * q).sum(-1).abs(), torch.ones(200, dtype=torch.float64), atol=1e-9)


def test_barycentric_clip_keeps_inside_points_and_moves_outside_ones_onto_the_triangle():
    tri = torch.tensor([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]]).repeat(4, 1, 1)
    p = torch.tensor([[0.2, 0.3], [2.0, 0.5], [-1.0, -1.0], [0.5, 0.5]])
    c = barycentric_clip(p, tri)
    torch.testing.assert_close(c[0], p[0])
    torch.testing.assert_close(c[3], p[3])
    torch.testing.assert_close(barycentric_clip(c, tri), c)  # idempotent
    assert torch.all(c >= -1e-7) and torch.all(c.sum(-1) <= 1 + 1e-6)


@pytest.mark.parametrize("mode", ["ste", "hard"])
def test_every_gaussian_stays_in_its_bounds_after_wild_parameters(mode):
    V, F = mesh()
    fr = face_frames(V, F)
    b = AnchorBounds()
    p = init_anchored(fr, torch.rand(3, 3, dtype=torch.float64))
    g = torch.Generator().manual_seed(0)
    p.means_2d = p.means_2d + torch.randn(3, 2, generator=g, dtype=torch.float64) * 5
    p.elevate = torch.randn(3, generator=g, dtype=torch.float64) * 10
    p.log_scales = p.log_scales + 8
    p.angles = torch.randn(3, 3, generator=g, dtype=torch.float64) * 3
    a = anchored_gaussians(p, fr, b, mode)
    assert bounds_violation(a, p, fr, b) is None
    # the normal axis of every Gaussian is within the cone of its face normal
    q = a.gaussians.quats
    w, x, y, z = (q / q.norm(dim=-1, keepdim=True)).unbind(-1)
    ax = torch.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], -1)
    ang = torch.arccos((ax * fr.normal).sum(-1).clamp(-1, 1))
    assert torch.all(ang <= b.cone + 1e-9)
    # unconstrained Gaussians do leave the bounds (the check can fail)
    assert "bound" in bounds_violation(anchored_gaussians(p, fr, b, "free"), p, fr, b)


def test_bound_activity_counts_raw_parameters_on_or_beyond_each_bound():
    V, F = mesh()
    fr = face_frames(V, F)
    b = AnchorBounds()
    p = init_anchored(fr, torch.rand(3, 3, dtype=torch.float64))
    p.log_scales = torch.log(fr.radius[:, None] * torch.tensor([0.5, 0.5, 0.001], dtype=torch.float64))
    act = bound_activity(p, fr, b)
    assert act == {"position": 0.0, "offset": 0.0, "scale_plane": 0.0, "scale_normal": 0.0, "tilt": 0.0, "any": 0.0}
    p.means_2d = p.means_2d.clone()
    p.means_2d[0] = fr.tri2d[0, 1] + 0.1 * fr.radius[0]  # outside the triangle, past vertex B
    p.elevate = torch.tensor([0.0, 3.0, 0.0], dtype=torch.float64) * fr.radius
    p.angles = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, -0.2]], dtype=torch.float64)
    act = bound_activity(p, fr, b)
    assert act["position"] == pytest.approx(1 / 3) and act["offset"] == pytest.approx(1 / 3)
    assert act["tilt"] == pytest.approx(1 / 3) and act["any"] == 1.0 and act["scale_plane"] == 0.0


def test_init_is_at_the_centroids_with_face_rotation():
    V, F = mesh()
    fr = face_frames(V, F)
    p = init_anchored(fr, torch.full((3, 3), 0.7, dtype=torch.float64))
    a = anchored_gaussians(p, fr, AnchorBounds())
    torch.testing.assert_close(a.gaussians.means, V[F[fr.face_ids]].mean(1))
    torch.testing.assert_close(a.gaussians.quats / a.gaussians.quats.norm(dim=-1, keepdim=True), fr.q_face)
    assert a.gaussians.opacities.tolist() == pytest.approx([0.1] * 3)
    # the DC term gives back the colour
    assert float(0.28209479177387814 * p.sh_dc[0, 0, 0] + 0.5) == pytest.approx(0.7)


def test_subdivision_reaches_the_area_and_keeps_the_surface():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.2]], float)
    F = np.array([[0, 1, 2], [1, 3, 2]])
    V2, F2, parent = subdivide_to_area(V, F, max_area=0.01)
    P = V2[F2]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    P0 = V[F]
    area0 = 0.5 * np.linalg.norm(np.cross(P0[:, 1] - P0[:, 0], P0[:, 2] - P0[:, 0]), axis=1)
    assert area.max() <= 0.01 and area.sum() == pytest.approx(area0.sum())
    assert np.bincount(parent).tolist() == [64, 64]
    assert len(V2) == len(np.unique(np.round(V2, 12), axis=0))  # midpoints shared, no duplicates
    # consistent winding: children normals agree with their parent's
    n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    n0 = np.cross(P0[:, 1] - P0[:, 0], P0[:, 2] - P0[:, 0])
    assert np.all(np.einsum("ij,ij->i", n, n0[parent]) > 0)


def test_tiny_and_huge_faces_are_handled():
    for s in (1e-6, 1e3):
        V = torch.tensor([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=torch.float64) * s
        fr = face_frames(V, torch.tensor([[0, 1, 2]]), min_area=0.0)
        assert float(fr.radius[0]) == pytest.approx(s * math.sqrt(2) / 2)
        p = init_anchored(fr, torch.rand(1, 3, dtype=torch.float64))
        a = anchored_gaussians(p, fr, AnchorBounds())
        assert all(torch.isfinite(t).all() for t in (a.gaussians.means, a.gaussians.scales, a.gaussians.quats))


def test_ply_round_trip_in_the_inria_layout(tmp_path):
    import open3d as o3d

    from drawer_lib.splat.ply import gaussian_ply_fields, read_ply_columns, write_gaussian_ply, write_face_binding
    from drawer_lib.splat.render import Gaussians

    g = torch.Generator().manual_seed(0)
    n = 7
    sh = torch.randn(n, 16, 3, generator=g)
    G = Gaussians(torch.randn(n, 3, generator=g), torch.randn(n, 4, generator=g), torch.rand(n, 3, generator=g) + 0.01,
                  torch.rand(n, generator=g) * 0.9 + 0.05, sh)
    write_gaussian_ply(tmp_path / "g.ply", G)
    d = read_ply_columns(tmp_path / "g.ply")
    assert list(d) == gaussian_ply_fields(15) and len(d["x"]) == n
    np.testing.assert_allclose(d["f_rest_0"], sh[:, 1, 0].numpy(), rtol=1e-6)  # channel-major rest
    np.testing.assert_allclose(d["f_rest_15"], sh[:, 1, 1].numpy(), rtol=1e-6)
    np.testing.assert_allclose(1 / (1 + np.exp(-d["opacity"])), G.opacities.numpy(), rtol=1e-5)
    np.testing.assert_allclose(np.exp(d["scale_1"]), G.scales[:, 1].numpy(), rtol=1e-5)
    # an independent reader (Open3D's 3DGS-aware tensor point cloud)
    pc = o3d.t.io.read_point_cloud(str(tmp_path / "g.ply"))
    np.testing.assert_allclose(pc.point.positions.numpy(), G.means.numpy(), rtol=1e-6)
    assert "f_dc" in pc.point and "opacity" in pc.point
    V, F = mesh()
    fr = face_frames(V, F)
    p = init_anchored(fr, torch.rand(3, 3, dtype=torch.float64))
    write_face_binding(tmp_path / "binding.npz", p.face, fr.face_ids, p.means_2d, p.elevate)
    assert np.load(tmp_path / "binding.npz")["mesh_face"].tolist() == [0, 1, 2]


def test_ste_forward_value_is_exactly_the_clip_far_outside_the_bound():
    x = torch.tensor([1e6, -3e7, 0.25], dtype=torch.float32, requires_grad=True)
    c = x.clamp(0.0, 1e-3)
    y = clip_through(x, c, "ste")
    assert torch.equal(y, c)
    y.sum().backward()
    assert x.grad.tolist() == [1.0, 1.0, 1.0]


@pytest.mark.parametrize("mode", ["ste", "free"])
@pytest.mark.parametrize("dtype,tol", [(torch.float64, 1e-10), (torch.float32, 2e-5)])
def test_fused_anchored_kernels_equal_the_pytorch_reference(mode, dtype, tol):
    """The numba forward and VJP of anchored_gaussians against its PyTorch code, with parameters
    inside and far outside their bounds (every clip active somewhere), angles at 0 included."""
    V, F = mesh()
    fr = face_frames(V.to(dtype), F)
    b = AnchorBounds()
    g = torch.Generator().manual_seed(1)
    p = init_anchored(fr, torch.rand(3, 3, dtype=torch.float64).to(dtype))
    n = 60
    face = torch.randint(0, 3, (n,), generator=g)
    p.face = face
    p.means_2d = (fr.tri2d[face].mean(1) + torch.randn(n, 2, generator=g, dtype=torch.float64).to(dtype) * 0.5)
    p.elevate = torch.randn(n, generator=g, dtype=torch.float64).to(dtype) * 2
    p.log_scales = (torch.randn(n, 3, generator=g, dtype=torch.float64) * 2 - 2).to(dtype)
    p.angles = (torch.randn(n, 3, generator=g, dtype=torch.float64) * 0.5).to(dtype)
    p.angles[:5] = 0.0
    p.opacity_logit = torch.randn(n, generator=g, dtype=torch.float64).to(dtype) * 3
    p.sh_dc, p.sh_rest = p.sh_dc[face], p.sh_rest[face]
    names = ("means_2d", "elevate", "log_scales", "angles", "opacity_logit")
    outs, grads = [], []
    cot = None
    for fused in (True, False):
        for k in names:
            setattr(p, k, getattr(p, k).detach().clone().requires_grad_(True))
        a = anchored_gaussians(p, fr, b, mode, fused=fused)
        o = (a.gaussians.means, a.gaussians.quats, a.gaussians.scales, a.gaussians.opacities, a.pos2d, a.elevate, a.tilt)
        if cot is None:
            cot = [torch.randn(t.shape, generator=g, dtype=torch.float64).to(dtype) for t in o]
        outs.append(o)
        grads.append(torch.autograd.grad(sum((t * c).sum() for t, c in zip(o, cot)), [getattr(p, k) for k in names]))
    for x, y in zip(*outs):
        torch.testing.assert_close(x, y, rtol=tol, atol=tol)
    for name, x, y in zip(names, *grads):
        torch.testing.assert_close(x, y, rtol=tol * 10, atol=tol * 10 * (1 + float(y.abs().max())), msg=name)
