"""A part's collision handle: the hull of what stands proud of its front, inside its rectangle."""

import numpy as np
import trimesh

from drawer_lib.complete.pipeline import _handle_hull
from drawer_lib.io.parts import Axis, Front, Part


def _door() -> Part:
    f = Front((0.0, 0.0, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.4, 0.6))
    return Part("door_0", "revolute", Axis((-0.2, 0.0, 0.5), (0.0, 0.0, 1.0)), (0.0, 1.5), f)


def test_handle_hull_keeps_the_handle_and_drops_the_margin():
    panel = trimesh.creation.box((0.4, 0.02, 0.6)).apply_translation((0.0, 0.01, 0.5))
    handle = trimesh.creation.box((0.02, 0.03, 0.15)).apply_translation((0.15, -0.025, 0.5))  # 1-4 cm proud
    lip = trimesh.creation.box((0.6, 0.04, 0.03)).apply_translation((0.0, -0.02, 0.19))  # a counter lip below the front
    far = trimesh.creation.box((0.02, 0.02, 0.02)).apply_translation((0.0, -0.15, 0.5))  # 14-16 cm out: not a handle
    body = trimesh.util.concatenate([panel, handle, lip, far])
    (hull,) = _handle_hull(body, _door(), max_proud=0.08)
    v = hull.vertices
    lo, hi = v.min(0), v.max(0)
    np.testing.assert_allclose(lo, [0.14, -0.04, 0.425], atol=1e-9)
    np.testing.assert_allclose(hi, [0.16, -0.01, 0.575], atol=1e-9)
    # nothing proud inside the rectangle: no hull
    assert _handle_hull(trimesh.util.concatenate([panel, lip]), _door(), max_proud=0.08) == []


def test_body_gaussians_split_the_appearance_model_exactly(tmp_path):
    """Gaussians bound to an anchor mesh (a door's front, a wall beside it): each goes to the body
    whose front slab holds its face; the bodies' union without the interior ones is the model;
    the interior ones lie behind the closed front, inside its rectangle, and are marked."""
    import torch

    from drawer_lib.complete.config import CompleteConfig
    from drawer_lib.complete.interiors.templates import build_template
    from drawer_lib.complete.pipeline import _body_gaussians
    from drawer_lib.paths import LAYOUT
    from drawer_lib.splat.ply import write_gaussian_ply
    from drawer_lib.splat.render import Gaussians

    door = _door()  # front at y = 0 facing -y, x in [-0.2, 0.2], z in [0.2, 0.8]
    front = trimesh.creation.box((0.4, 0.001, 0.6)).apply_translation((0.0, 0.0005, 0.5))
    wall = trimesh.creation.box((0.4, 0.001, 0.6)).apply_translation((0.6, 0.0005, 0.5))
    anchor = trimesh.util.concatenate([front, wall])
    F = len(anchor.faces)
    n = 3 * F
    face = np.repeat(np.arange(F), 3)
    means = torch.from_numpy(anchor.triangles_center[face] + np.random.default_rng(0).normal(0, 1e-3, (n, 3)))
    g = Gaussians(means, torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1).double(), torch.full((n, 3), 0.01).double(),
                  torch.full((n,), 0.9).double(), torch.rand(n, 16, 3, generator=torch.Generator().manual_seed(0)).double())
    d = tmp_path / "movable_gs_ste"  # an appearance variant's folder
    (d / LAYOUT["appearance"]["model"]).mkdir(parents=True)
    write_gaussian_ply(d / LAYOUT["appearance"]["gaussians"], g)
    np.savez(d / LAYOUT["appearance"]["binding"], mesh_face=face)
    anchor.export(d / LAYOUT["appearance"]["anchor_mesh"])
    cfg = CompleteConfig()
    it = build_template(door, "cabinet", cfg.interiors.template.front_thickness, 0.4, cfg.interiors.template)
    bodies, interior = _body_gaussians(cfg, d, [door], cfg.cut, [], {door.id: it})
    on_front = np.isin(face, np.flatnonzero(np.abs(anchor.triangles_center[:, 0]) < 0.3))
    model_means = g.means.float().numpy()
    own = bodies["door_0"].means.numpy()[~interior["door_0"]]
    np.testing.assert_allclose(np.sort(own, 0), np.sort(model_means[on_front], 0), atol=1e-6)
    rest = np.concatenate([bodies[k].means.numpy()[~interior[k]] for k in bodies])
    np.testing.assert_allclose(np.sort(rest, 0), np.sort(model_means, 0), atol=1e-6)  # the union is the model
    inner = np.concatenate([bodies[k].means.numpy()[interior[k]] for k in bodies])
    assert len(inner) > 50 and interior["static"].sum() == len(inner)  # a door's cavity is static
    assert (inner[:, 1] > 0.0).all() and (np.abs(inner[:, 0]) < 0.2).all() and (np.abs(inner[:, 2] - 0.5) < 0.3).all()
