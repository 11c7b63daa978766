"""complete/ round trip: bodies, shapes, Gaussians and interiors come back as written."""

import json

import numpy as np
import pytest
import torch
import trimesh

from drawer_lib.complete.io import read_complete, write_complete
from drawer_lib.errors import InputError
from drawer_lib.bodies import PartBody, RigidBody, TwinModel, box_shape, mesh_shape
from drawer_lib.splat.render import Gaussians
from drawer_lib.splat.ply import read_gaussian_ply


def rot_z(deg):
    a = np.deg2rad(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def test_round_trip(tmp_path):
    cup = trimesh.creation.cylinder(0.04, 0.1)
    front = trimesh.creation.box((0.5, 0.02, 0.7))
    model = TwinModel(
        static_visual=[mesh_shape(front.vertices + [0, 0.5, 0], front.faces)],
        static_collision=[box_shape([0, 0.5, 0.4], [1, 0.3, 0.4], rot_z(20))],
        parts=[PartBody("door_0", "revolute", np.array([0.25, -0.1, 0.4]), np.array([0, 0, -1.0]), (0.0, 1.5),
                        [mesh_shape(front.vertices, front.faces)], [box_shape([0, 0, 0.4], [0.25, 0.01, 0.35])], 600.0)],
        rigid=[RigidBody("object_0", [mesh_shape(cup.vertices, cup.faces)], [mesh_shape(cup.vertices, cup.faces)], 800.0)])
    g = torch.Generator().manual_seed(0)
    gs = {"static": Gaussians(torch.randn(10, 3, generator=g), torch.nn.functional.normalize(torch.randn(10, 4, generator=g), dim=-1),
                              torch.rand(10, 3, generator=g) * 0.01 + 1e-3, torch.rand(10, generator=g) * 0.9 + 0.05,
                              torch.randn(10, 16, 3, generator=g))}
    out = tmp_path / "complete"
    out.mkdir()
    write_complete(out, model, gs, {"door_0": {"template": "cabinet", "depth": 0.55}}, {"note": 1})
    m, gfiles, d = read_complete(out)
    assert [p.id for p in m.parts] == ["door_0"] and [r.id for r in m.rigid] == ["object_0"]
    p = m.parts[0]
    np.testing.assert_allclose(p.axis_direction, [0, 0, -1])
    np.testing.assert_allclose(p.limits, (0, 1.5))
    np.testing.assert_allclose(m.static_collision[0].box.rotation, rot_z(20), atol=1e-12)
    np.testing.assert_allclose(m.rigid[0].collision[0].vertices, cup.vertices, atol=1e-6)
    assert d["bodies"][1]["interior"]["depth"] == 0.55 and d["info"] == {"note": 1}
    r = read_gaussian_ply(gfiles["static"])
    torch.testing.assert_close(r.means, gs["static"].means, atol=1e-6, rtol=0)
    assert set(gfiles) == {"static"}  # bodies without Gaussians have none
    m.validate()


def test_errors_name_the_file(tmp_path):
    with pytest.raises(InputError, match="complete.json"):
        read_complete(tmp_path)
    (tmp_path / "complete.json").write_text(json.dumps({"schema": "other", "bodies": []}))
    with pytest.raises(InputError, match="schema"):
        read_complete(tmp_path)
