"""Flat Gaussians covering interior boxes: on the faces, oriented with them, the right colour,
and rendering a closed opaque surface."""

import numpy as np
import pytest
import torch

from helpers import quat_to_rot

from drawer_lib.errors import InputError
from drawer_lib.geometry.boxes import OrientedBox
from drawer_lib.geometry.camera import Camera, Intrinsics, invert_rigid, look_at_opencv
from drawer_lib.splat.render import render
from drawer_lib.splat.sh import sh_to_color
from drawer_lib.splat.gaussians import box_surface_gaussians


def rot_z(deg):
    a = np.deg2rad(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def test_gaussians_lie_on_the_faces_flat_and_coloured():
    c, R, h = np.array([0.3, -0.2, 0.9]), rot_z(30), np.array([0.25, 0.2, 0.01])
    g = box_surface_gaussians(OrientedBox(c, R, h), np.array([0.8, 0.5, 0.2]), spacing=0.02)
    local = (g.means.double().numpy() - c) @ R  # box frame
    on_face = np.isclose(np.abs(local), h, atol=1e-6).any(1)
    assert on_face.all() and np.all(np.abs(local) <= h + 1e-6)
    # the two big faces (+-z) hold 25 x 20 Gaussians each
    assert np.isclose(np.abs(local[:, 2]), 0.01).sum() == 2 * 25 * 20
    for i in range(0, len(g.means), 97):  # each Gaussian's thin axis is its face's normal
        Rg = quat_to_rot(g.quats[i].double().numpy())
        face_axis = np.argmax(np.abs(local[i]) / h)
        assert abs(Rg[:, 2] @ R[:, face_axis]) > 1 - 1e-6
        assert g.scales[i, 2] == pytest.approx(5e-4)
    col = sh_to_color(g.sh, torch.randn(len(g.means), 3), 3)
    torch.testing.assert_close(col, torch.tensor([0.8, 0.5, 0.2]).expand_as(col), atol=1e-6, rtol=0)


def test_shade_and_degenerate_boxes():
    c, R = np.zeros(3), np.eye(3)
    g = box_surface_gaussians(OrientedBox(c, R, np.array([0.1, 0.1, 0.1])), np.ones(3), 0.05, shade=lambda p: 0.5 + 0 * p[:, 0])
    torch.testing.assert_close(sh_to_color(g.sh, torch.ones(len(g.means), 3), 3), torch.full((len(g.means), 3), 0.5))
    flat = box_surface_gaussians(OrientedBox(c, R, np.array([0.1, 0.1, 0.0])), np.ones(3), 0.05)  # a rectangle: 2 faces
    assert len(flat.means) == 2 * 4 * 4
    assert len(box_surface_gaussians(OrientedBox(c, R, np.zeros(3)), np.ones(3), 0.05).means) == 0
    tiny = box_surface_gaussians(OrientedBox(c, R, np.full(3, 1e-4)), np.ones(3), 0.05)  # smaller than the spacing
    assert len(tiny.means) == 6 and torch.isfinite(tiny.scales).all()
    with pytest.raises(InputError):
        box_surface_gaussians(OrientedBox(c, R, np.array([0.1, np.nan, 0.1])), np.ones(3), 0.05)


def test_a_covered_wall_renders_opaque_in_its_colour():
    g = box_surface_gaussians(OrientedBox(np.array([0.0, 0.0, 0.0]), np.eye(3), np.array([0.3, 0.3, 0.005])), np.array([0.2, 0.6, 0.4]), spacing=0.02, opacity=0.95)
    c2w = look_at_opencv(np.array([0.1, 0.0, 1.0]), np.zeros(3), np.array([0.0, 1.0, 0.0]))
    cam = Camera(Intrinsics.from_fovy(np.deg2rad(40), 48, 48), invert_rigid(c2w))
    out = render(g, cam, 3, torch.zeros(3))
    mid = out.rgb[12:36, 12:36]
    assert out.alpha[12:36, 12:36].min() > 0.97
    torch.testing.assert_close(mid, torch.tensor([0.2, 0.6, 0.4]).expand_as(mid), atol=0.03, rtol=0)


def test_toward_covers_only_the_faces_facing_the_point():
    c, R, h = np.zeros(3), np.eye(3), np.array([0.2, 0.2, 0.01])  # a floor slab
    g = box_surface_gaussians(OrientedBox(c, R, h), np.ones(3), 0.05, toward=np.array([0.0, 0.0, 0.5]))  # seen from above
    assert len(g.means) == 8 * 8 and torch.all(g.means[:, 2] > 0.0099)
