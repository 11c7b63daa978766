"""Rigid objects as closed solids: open shells standing on a plane become watertight solids of
the right volume, with mass properties and convex pieces."""

import math

import numpy as np
import pytest
import trimesh
from complete_fixtures import Scene, cup_shell, quad, sphere_shell

from drawer_lib.complete.config import RigidConfig
from drawer_lib.complete.rigid import build_rigid, build_rigids, clean_shell, close_shell, rigid_faces, unpinch
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.parts import Part, PartsFile

CFG = RigidConfig(max_hulls=4, resolution=20_000, fidelity_points=2000)


def _on_plane(obj: trimesh.Trimesh, half: float = 0.2, edge: float = 0.02) -> tuple[trimesh.Trimesh, np.ndarray]:
    """(the object on a square plane at z = 0, face labels: 7 for the object, -1 for the plane)."""
    s = Scene({"plane": quad([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], edge),
               "obj": obj})
    labels = np.full(len(s.mesh.faces), -1)
    labels[s.groups["obj"]] = 7
    return s.mesh, labels


def _part(obj: trimesh.Trimesh, pid: str = "cup_0", labels=None) -> Part:
    lo, hi = obj.bounds
    return Part(pid, "rigid", center=tuple((lo + hi) / 2), bounds=(tuple(lo), tuple(hi)),
                extra={"segment": 7, "labels": labels or {"cup": 12, "mug": 3}})


def test_open_cup_becomes_a_closed_solid_of_the_right_volume():
    r, h, n = 0.04, 0.1, 64
    cup = cup_shell(r, h, n)
    assert not cup.is_watertight
    mesh, labels = _on_plane(cup)
    res = build_rigid(_part(cup), mesh, CFG, face_labels=labels)
    assert res.method == "extrude" and res.support_source == "faces" and res.support_z == pytest.approx(0.0, abs=1e-12)
    assert res.solid.is_watertight and res.solid.is_winding_consistent
    prism = 0.5 * n * math.sin(2 * math.pi / n) * r * r * h  # the polygonal cylinder
    assert res.volume == pytest.approx(prism, rel=1e-9)
    assert res.volume == pytest.approx(math.pi * r * r * h, rel=0.01)
    rho = CFG.density["cup"]
    assert res.density == rho and res.mass == pytest.approx(rho * res.volume)
    np.testing.assert_allclose(res.center_mass, [0, 0, h / 2], atol=1e-6)
    Izz = 0.5 * res.mass * r * r  # solid cylinder about its axis
    assert res.inertia[2, 2] == pytest.approx(Izz, rel=0.01)
    assert 1 <= len(res.pieces) <= CFG.max_hulls
    assert res.fidelity["chamfer_l1"] < 0.004
    st = res.stats()
    assert st["n_hulls"] == len(res.pieces) and st["label"] == "cup"


def test_sphere_resting_on_a_plane_without_its_contact_cap():
    r, cut = 0.05, 0.1
    sph = sphere_shell(r, cut, subdivisions=4)
    mesh, labels = _on_plane(sph)
    res = build_rigid(_part(sph, "ball_0", {"fruit": 4}), mesh, CFG, face_labels=labels)
    assert res.method == "extrude" and res.solid.is_watertight
    # the missing cap (below height hc) is replaced by a cylinder of the hole's radius a down to the plane
    zc = sph.vertices[:, 2][np.isin(np.arange(len(sph.vertices)), np.unique(sph.faces))].min()
    hc = zc
    a = math.sqrt(hc * (2 * r - hc))
    expected = 4 / 3 * math.pi * r**3 - math.pi * hc**2 * (3 * r - hc) / 3 + math.pi * a * a * hc
    assert res.volume == pytest.approx(expected, rel=0.02)
    assert res.density == CFG.density["fruit"]
    assert res.center_mass[2] == pytest.approx(r, abs=0.004)


def test_a_box_seen_from_the_front_only_is_closed_by_a_curtain():
    """Back and bottom missing: the boundary loop runs along the back edges and the floor;
    projecting it down closes the box exactly."""
    b = trimesh.creation.box(bounds=[[-0.05, -0.04, 0.0], [0.05, 0.04, 0.12]])
    v, f = trimesh.remesh.subdivide_to_size(b.vertices, b.faces, 0.01)
    b = trimesh.Trimesh(v, f, process=False)
    keep = ~((b.face_normals[:, 1] > 0.99) | (b.face_normals[:, 2] < -0.99))
    shell = trimesh.Trimesh(b.vertices, b.faces[keep], process=False)
    mesh, labels = _on_plane(shell)
    res = build_rigid(_part(shell, "box_0", {"box": 1}), mesh, CFG, face_labels=labels)
    assert res.method == "extrude"
    assert res.volume == pytest.approx(0.1 * 0.08 * 0.12, rel=1e-6)


def test_faces_from_bounds_without_labels_skip_the_support():
    cup = cup_shell()
    mesh, labels = _on_plane(cup)
    p = _part(cup)
    by_bounds = rigid_faces(p, mesh, CFG, face_labels=None)
    by_label = rigid_faces(p, mesh, CFG, face_labels=labels)
    # the top cap and the wall: the plane under the cup (at the bounds' bottom) is not the cup
    assert set(by_bounds.tolist()) == set(by_label.tolist())
    res = build_rigid(p, mesh, CFG, fidelity=False)
    assert res.volume == pytest.approx(build_rigid(p, mesh, CFG, face_labels=labels, fidelity=False).volume)


def test_touching_holes_and_zero_area_faces_still_close():
    cup = cup_shell(0.04, 0.1, 32)
    V, F = np.asarray(cup.vertices), np.asarray(cup.faces)
    # a second hole in the wall touching the bottom rim at one vertex: drop one wall triangle
    # with a single vertex on the rim (a pinch vertex where two loops meet)
    on_rim = np.isclose(V[F][:, :, 2], 0.0).sum(1)
    k = np.flatnonzero((on_rim == 1) & (np.abs(cup.face_normals[:, 2]) < 0.1))[0]
    F2 = np.delete(F, k, axis=0)
    # plus a zero-area face (three distinct but collinear vertices) and an index-degenerate one
    nv = len(V)
    V2 = np.concatenate([V, [[0.5, 0.5, 0.5], [0.6, 0.5, 0.5], [0.7, 0.5, 0.5]]])
    F2 = np.concatenate([F2, [[0, 0, 1]]])
    shell = trimesh.Trimesh(V2, F2, process=False)
    Vc, Fc = clean_shell(np.asarray(shell.vertices), np.asarray(shell.faces))
    Fu, src = unpinch(Fc)
    assert len(src) == len(Vc) + 1  # exactly one vertex split
    solid, method, _ = close_shell(shell.vertices, shell.faces, 0.0, CFG)
    assert method == "extrude" and solid.is_watertight
    prism = 0.5 * 32 * math.sin(2 * math.pi / 32) * 0.04**2 * 0.1
    assert solid.volume == pytest.approx(prism, rel=0.02)  # the side hole is capped flat
    # a degenerate (collinear) face on its own does not break the closing
    F3 = np.concatenate([F, [[nv, nv + 1, nv + 2]]])
    solid, method, _ = close_shell(V2, F3, 0.0, CFG)
    assert method == "extrude" and solid.is_watertight
    assert solid.volume == pytest.approx(prism, rel=1e-9)


def test_broken_shell_falls_back_to_the_hull_of_shell_and_footprint():
    rng = np.random.default_rng(0)
    c = rng.uniform([-0.05, -0.05, 0.01], [0.05, 0.05, 0.1], size=(40, 3))
    tris = c[:, None, :] + rng.normal(scale=0.005, size=(40, 3, 3))  # 40 separate triangles
    shell = trimesh.Trimesh(tris.reshape(-1, 3), np.arange(120).reshape(-1, 3), process=False)
    mesh, labels = _on_plane(shell)
    res = build_rigid(_part(shell, "junk_0", {"junk": 1}), mesh, CFG, face_labels=labels)
    assert res.method == "hull" and "boundary" in res.reason
    assert res.solid.is_watertight and res.solid.is_convex
    assert len(res.pieces) == 1 and res.density == CFG.default_density
    assert res.solid.bounds[0][2] == pytest.approx(0.0, abs=1e-9)  # down to the support


def test_tiny_object():
    cup = cup_shell(0.01, 0.02, 24)
    mesh, labels = _on_plane(cup, half=0.05, edge=0.005)
    res = build_rigid(_part(cup), mesh, CFG, face_labels=labels)
    assert res.method == "extrude"
    assert res.volume == pytest.approx(math.pi * 0.01**2 * 0.02, rel=0.02)
    assert np.all(np.isfinite(res.inertia)) and np.all(np.linalg.eigvalsh(res.inertia) > 0)


def test_empty_segment_and_bad_inputs_name_the_part():
    cup = cup_shell()
    mesh, labels = _on_plane(cup)
    p = Part("ghost_3", "rigid", center=(0, 0, 0), bounds=((0, 0, 0), (0.1, 0.1, 0.1)), extra={"segment": 99})
    with pytest.raises(InputError, match="ghost_3"):
        build_rigid(p, mesh, CFG, face_labels=labels)
    far = Part("far_1", "rigid", center=(5, 5, 5), bounds=((5, 5, 5), (5.1, 5.1, 5.1)))
    with pytest.raises(InputError, match="far_1"):
        build_rigid(far, mesh, CFG)
    with pytest.raises(InputError, match="cup_0"):
        rigid_faces(_part(cup), mesh, CFG, face_labels=labels[:-1])
    flat = quad([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.05, 0.05, 0.0], [0.0, 0.05, 0.0]], 0.01)
    fm, fl = _on_plane(flat)
    with pytest.raises(InputError, match="flat_0"):
        build_rigid(_part(flat, "flat_0"), fm, CFG, face_labels=fl)
    with pytest.raises(ConfigError):
        RigidConfig(max_hulls=0)
    with pytest.raises(ConfigError):
        RigidConfig(density={"cup": -1.0})
    assert build_rigids(PartsFile(()), mesh, CFG) == []
