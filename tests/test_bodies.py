"""The body model (drawer_lib/bodies.py): validation (errors name the part, nothing is written),
mass properties against closed forms, convex decomposition; and the simulation config."""

import dataclasses
import math

import numpy as np
import pytest
import trimesh

import sim_fixtures as F
from drawer_lib.bodies import TwinModel, box_shape, convex_pieces, mass_properties, mesh_shape
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.sim.config import ContactConfig, JointConfig, SimConfig
from drawer_lib.sim.mjcf import build_spec, write_mjcf
from drawer_lib.sim.urdf import write_urdf
from drawer_lib.sim.usd import write_usd


def _with_part(**changes) -> TwinModel:
    walls, part = F.drawer_cabinet()
    return TwinModel(static_collision=[F.floor(), *walls], parts=[dataclasses.replace(part, **changes)])


def _cup_shape() -> object:
    return F.cup(0, 0, 0).collision[0]


BAD = {
    "zero axis": (_with_part, dict(axis_direction=np.zeros(3)), "axis direction"),
    "nan axis": (_with_part, dict(axis_direction=np.array([0.0, math.nan, 0.0])), "axis direction"),
    "nan origin": (_with_part, dict(axis_origin=np.array([math.nan, 0.0, 0.0])), "axis origin"),
    "empty range": (_with_part, dict(limits=(0.3, 0.3)), "empty range"),
    "negative range": (_with_part, dict(limits=(0.0, -0.3)), "empty range"),
    "range without q = 0": (_with_part, dict(limits=(0.1, 0.3)), "closed pose"),
    "nan limit": (_with_part, dict(limits=(0.0, math.nan)), "not finite"),
    "no collision": (_with_part, dict(collision=[]), "no collision geometry"),
    "nan centre": (_with_part, dict(collision=[box_shape([math.nan, 0, 0], [0.1, 0.1, 0.1])]), "not finite"),
    "flat mesh": (_with_part, dict(collision=[mesh_shape([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]],
                                                          [[0, 1, 2], [1, 3, 2]])]), "degenerate"),
    "zero box": (_with_part, dict(collision=[box_shape([0, 0, 0], [0.1, 0.0, 0.1])]), "half extents"),
    "not a rotation": (_with_part, dict(collision=[box_shape([0, 0, 0], [0.1, 0.1, 0.1], np.diag([1.0, 1.0, -1.0]))]),
                       "rotation"),
    "bad face index": (_with_part, dict(visual=[mesh_shape([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]])]), "index"),
    "zero density": (_with_part, dict(density=0.0), "density"),
    "bad kind": (_with_part, dict(kind="ball"), "kind"),
    "reserved id": (_with_part, dict(id="static"), "reserved"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_names_the_part_and_writes_nothing(case, tmp_path):
    make, changes, words = BAD[case]
    twin = make(**changes)
    pid = changes.get("id", "drawer_0")
    for write in (lambda out: write_mjcf(build_spec(twin), out), lambda out: write_urdf(twin, out),
                  lambda out: write_usd(twin, out)):
        out = tmp_path / "twin"
        with pytest.raises(InputError) as e:
            write(out)
        assert repr(pid) in str(e.value) and words in str(e.value), str(e.value)
        assert not out.exists()
        assert list(tmp_path.iterdir()) == []


def test_duplicate_and_non_identifier_ids():
    walls, a = F.drawer_cabinet()
    _, b = F.door_cabinet(pid="drawer_0")
    with pytest.raises(InputError, match="'drawer_0': duplicate id"):
        TwinModel(static_collision=walls, parts=[a, b]).validate()
    with pytest.raises(InputError, match="'cup-1'.*identifier"):
        TwinModel(rigid=[F.cup(0, 0, 0, "cup-1")]).validate()
    with pytest.raises(InputError, match="static scene: collision piece 0.*not finite"):
        TwinModel(static_collision=[box_shape([0, 0, math.inf], [1, 1, 1])]).validate()


def test_shape_contract_errors():
    with pytest.raises(ValueError, match="needs vertices"):
        F.Shape("mesh", vertices=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="must be one of"):
        F.Shape("sphere")


def test_box_mass_properties_are_analytic():
    """A rotated box: mass = rho * 8 hx hy hz, inertia R diag(m/3 (hy^2 + hz^2), ...) R^T; its
    triangles are closed and outward (trimesh volume equals the box's)."""
    R = trimesh.transformations.rotation_matrix(0.7, [1, 2, 3])[:3, :3]
    h = np.array([0.3, 0.1, 0.02])
    s = box_shape([1.0, 2.0, 3.0], h, R)
    p = mass_properties([s], 600.0)
    m = 600.0 * 8 * h.prod()
    assert p.mass == pytest.approx(m, rel=1e-12)
    local = m / 3 * np.diag([h[1] ** 2 + h[2] ** 2, h[0] ** 2 + h[2] ** 2, h[0] ** 2 + h[1] ** 2])
    np.testing.assert_allclose(p.inertia, R @ local @ R.T, atol=1e-12)
    np.testing.assert_allclose(p.com, [1, 2, 3], atol=1e-12)
    np.testing.assert_allclose(p.axes @ np.diag(p.principal) @ p.axes.T, p.inertia, atol=1e-12)
    assert np.linalg.det(p.axes) == pytest.approx(1.0)
    tm = trimesh.Trimesh(*s.triangles(), process=False)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume == pytest.approx(8 * h.prod(), rel=1e-12)


def test_composite_mass_properties_parallel_axis():
    """Two unit cubes side by side = one 2 x 1 x 1 box."""
    a = box_shape([0.5, 0, 0], [0.5, 0.5, 0.5])
    b = box_shape([-0.5, 0, 0], [0.5, 0.5, 0.5])
    one = box_shape([0, 0, 0], [1.0, 0.5, 0.5])
    pa, p1 = mass_properties([a, b], 2.0), mass_properties([one], 2.0)
    assert pa.mass == pytest.approx(p1.mass)
    np.testing.assert_allclose(pa.inertia, p1.inertia, atol=1e-12)


def test_mesh_mass_properties_are_the_hull():
    """A cylinder prism mesh: its hull volume is the 24-gon prism's (r^2 n/2 sin(2 pi/n) h)."""
    s = _cup_shape()
    r, h, n = 0.04, 0.1, 24
    p = mass_properties([s], 800.0)
    assert p.volume == pytest.approx(0.5 * n * r * r * math.sin(2 * math.pi / n) * h, rel=1e-9)
    assert p.com[2] == pytest.approx(h / 2)
    # a concave mesh counts as its hull (what MuJoCo collides)
    ring = trimesh.creation.annulus(0.03, 0.04, 0.1)
    assert mass_properties([mesh_shape(ring.vertices, ring.faces)], 1.0).volume == pytest.approx(
        ring.convex_hull.volume, rel=1e-9)


def test_convex_pieces_of_a_concave_mesh():
    ring = trimesh.creation.annulus(0.03, 0.04, 0.1, sections=16)
    pieces = convex_pieces(ring.vertices, ring.faces, max_hulls=8, resolution=5000, max_recursion_depth=4)
    assert 2 <= len(pieces) <= 8
    vol = sum(mass_properties([p], 1.0).volume for p in pieces)
    assert ring.volume * 0.9 < vol < ring.convex_hull.volume * 0.5  # the hole stays (mostly) empty
    for p in pieces:  # each piece is convex: it is its own hull
        v, f = p.solid()
        assert trimesh.Trimesh(v, f).is_convex
    with pytest.raises(ValueError, match="need vertices"):
        convex_pieces(np.zeros((2, 3)), np.zeros((1, 3), int))


def test_config_validation():
    cfg = SimConfig()
    assert cfg.timestep == 0.002 and cfg.integrator == "implicitfast"
    assert cfg.revolute.speed == pytest.approx(math.radians(50)) and cfg.prismatic.speed == 0.5
    assert cfg.densities.part == 600.0 and cfg.densities.rigid == 800.0
    with pytest.raises(ConfigError, match="integrator"):
        SimConfig(integrator="verlet")
    with pytest.raises(ConfigError, match="limit_timeconst"):
        SimConfig(timestep=0.005, contact=ContactConfig(limit_timeconst=0.004))
    with pytest.raises(ConfigError, match="damping"):
        JointConfig(damping=-1.0, armature=0.0, frictionloss=0.0, speed=1.0)
    with pytest.raises(ConfigError, match="speed"):
        JointConfig(damping=1.0, armature=0.0, frictionloss=0.0, speed=0.0)
