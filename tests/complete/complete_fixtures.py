"""Analytic fixtures of the complete tests: a box cabinet with a drawer and a door (its visible
surfaces, finely tessellated, as a reconstruction gives them), boxes and shells of known volume.
Lengths in metres; the cabinet's fronts face -y, +z is up."""

import math

import numpy as np
import trimesh

from drawer_lib.articulation.joints import hinge_axis
from drawer_lib.io.parts import Axis, Front, Part, PartsFile


def quad(corners, edge: float = 0.02) -> trimesh.Trimesh:
    """A planar quad (4 corners, counter-clockwise seen from its front side) tessellated to
    edges <= ``edge``."""
    c = np.asarray(corners, np.float64)
    v, f = trimesh.remesh.subdivide_to_size(c, np.array([[0, 1, 2], [0, 2, 3]]), max_edge=edge)
    return trimesh.Trimesh(v, f, process=False)


def box_mesh(lo, hi, edge: float = 0.02) -> trimesh.Trimesh:
    """A closed axis-aligned box, outward faces, tessellated to edges <= ``edge``."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    b = trimesh.creation.box(bounds=np.stack([lo, hi]))
    v, f = trimesh.remesh.subdivide_to_size(b.vertices, b.faces, max_edge=edge)
    return trimesh.Trimesh(v, f, process=False)


def rect_y(x0, x1, z0, z1, y, facing: float, edge=0.02) -> trimesh.Trimesh:
    """A rectangle in the plane y = const facing ``facing`` (-1: toward -y)."""
    c = [[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]]
    return quad(c if facing < 0 else c[::-1], edge)


def rect_x(y0, y1, z0, z1, x, facing: float, edge=0.02) -> trimesh.Trimesh:
    c = [[x, y0, z0], [x, y1, z0], [x, y1, z1], [x, y0, z1]]
    return quad(c if facing > 0 else c[::-1], edge)


def rect_z(x0, x1, y0, y1, z, facing: float, edge=0.02) -> trimesh.Trimesh:
    c = [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]]
    return quad(c if facing > 0 else c[::-1], edge)


class Scene:
    """Named groups of faces concatenated into one mesh: ``mesh`` and ``groups[name]`` = face ids."""

    def __init__(self, pieces: dict[str, trimesh.Trimesh]):
        self.groups, V, F, nv, nf = {}, [], [], 0, 0
        for name, m in pieces.items():
            V.append(np.asarray(m.vertices))
            F.append(np.asarray(m.faces) + nv)
            self.groups[name] = np.arange(nf, nf + len(m.faces))
            nv += len(m.vertices)
            nf += len(m.faces)
        self.mesh = trimesh.Trimesh(np.concatenate(V), np.concatenate(F), process=False)


# the cabinet: x in [0, 0.6], y in [0, 0.6] (front face at y = 0), z in [0, 0.8]; wall at y = 0.6
DRAWER = dict(x=(0.05, 0.55), z=(0.5, 0.7))
DOOR = dict(x=(0.05, 0.55), z=(0.05, 0.45))
PANEL_T = 0.02  # the fronts stand 2 cm proud of the carcass: outer faces at y = -0.02


def cabinet_scene(edge: float = 0.02) -> Scene:
    """Visible surfaces of a cabinet against a wall on a floor, with a drawer (top) and a door
    (bottom, hinged left) whose panels and handles are closed boxes, a shelf surface inside the
    carcass (inside the drawer's box) and a floater in front of the door (in its swing)."""
    p = {
        "floor": rect_z(-0.4, 1.0, -1.0, 0.6, 0.0, +1, 0.05),
        "wall": rect_y(-0.4, 1.0, 0.0, 1.4, 0.6, -1, 0.05),
        "top": rect_z(0.0, 0.6, 0.0, 0.6, 0.8, +1, edge),
        "side_l": rect_x(0.0, 0.6, 0.0, 0.8, 0.0, -1, edge),
        "side_r": rect_x(0.0, 0.6, 0.0, 0.8, 0.6, +1, edge),
        # the carcass front frame around the two fronts
        "frame_l": rect_y(0.0, 0.05, 0.0, 0.8, 0.0, -1, edge),
        "frame_r": rect_y(0.55, 0.6, 0.0, 0.8, 0.0, -1, edge),
        "frame_b": rect_y(0.05, 0.55, 0.0, 0.05, 0.0, -1, edge),
        "frame_m": rect_y(0.05, 0.55, 0.45, 0.5, 0.0, -1, edge),
        "frame_t": rect_y(0.05, 0.55, 0.7, 0.8, 0.0, -1, edge),
        "drawer_panel": box_mesh([0.05, -PANEL_T, 0.5], [0.55, 0.0, 0.7], edge),
        "drawer_handle": box_mesh([0.24, -0.045, 0.64], [0.36, -PANEL_T, 0.66], 0.01),
        "door_panel": box_mesh([0.05, -PANEL_T, 0.05], [0.55, 0.0, 0.45], edge),
        "door_handle": box_mesh([0.49, -0.045, 0.2], [0.51, -PANEL_T, 0.3], 0.01),
        "shelf": rect_z(0.02, 0.58, 0.02, 0.58, 0.6, +1, edge),
        "floater": box_mesh([0.35, -0.25, 0.25], [0.40, -0.20, 0.30], 0.01),
    }
    return Scene(p)


def drawer_part(travel: float = 0.4, carcass: float | None = None) -> Part:
    (x0, x1), (z0, z1) = DRAWER["x"], DRAWER["z"]
    f = Front(((x0 + x1) / 2, -PANEL_T, (z0 + z1) / 2), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (x1 - x0, z1 - z0))
    extra = {"family": "drawer"} | ({"carcass_depth": carcass} if carcass is not None else {})
    return Part("drawer_0", "prismatic", Axis(f.center, f.normal), (0.0, travel), f, extra=extra)


def door_part(limit: float = math.pi / 2) -> Part:
    (x0, x1), (z0, z1) = DOOR["x"], DOOR["z"]
    f = Front(((x0 + x1) / 2, -PANEL_T, (z0 + z1) / 2), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (x1 - x0, z1 - z0))
    return Part("door_0", "revolute", hinge_axis(f, "left"), (0.0, limit), f, extra={"family": "door"})


def cabinet_parts(**kw) -> PartsFile:
    return PartsFile((drawer_part(**kw), door_part()))


# ----------------------------------------------------------------------- exact swept volumes


def in_prismatic_sweep(P, lo, hi, direction, travel):
    """Exact: points [N, 3] that an axis-aligned box [lo, hi] passes through when translated by
    s * direction, s in [0, travel] (slab test of the segment p - s d against the box)."""
    P = np.asarray(P, np.float64)
    d = np.asarray(direction, np.float64)
    s0, s1 = np.zeros(len(P)), np.full(len(P), float(travel))
    for i in range(3):
        if abs(d[i]) < 1e-15:
            ok = (P[:, i] >= lo[i]) & (P[:, i] <= hi[i])
            s1 = np.where(ok, s1, -1.0)
            continue
        a, b = (P[:, i] - hi[i]) / d[i], (P[:, i] - lo[i]) / d[i]
        s0, s1 = np.maximum(s0, np.minimum(a, b)), np.minimum(s1, np.maximum(a, b))
    return s0 <= s1


def in_revolute_sweep(P, lo, hi, origin, direction, q_max, n_q: int = 3000):
    """Points [N, 3] that an axis-aligned box [lo, hi] passes through when turned about the axis
    by q in [0, q_max] (``n_q`` samples: the error is q_max / n_q x radius, ~0.3 mm here)."""
    origin = np.asarray(origin, np.float64)
    k = np.asarray(direction, np.float64)
    rel = np.asarray(P, np.float64) - origin
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]) - origin
    # only points within the box's axial range and largest radius can be swept
    a, ca = rel @ k, corners @ k
    r, cr = np.linalg.norm(rel - np.outer(a, k), axis=1), np.linalg.norm(corners - np.outer(ca, k), axis=1)
    idx = np.flatnonzero((a >= ca.min() - 1e-9) & (a <= ca.max() + 1e-9) & (r <= cr.max() + 1e-9))
    out = np.zeros(len(rel), bool)
    for q in np.linspace(0.0, q_max, n_q):  # rotate the points by -q (Rodrigues)
        c, s = math.cos(-q), math.sin(-q)
        R = c * np.eye(3) + s * np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]]) + (1 - c) * np.outer(k, k)
        X = rel[idx] @ R.T + origin
        hit = np.all((X >= lo) & (X <= hi), axis=1)
        out[idx[hit]] = True
        idx = idx[~hit]
    return out


# ------------------------------------------------------------------------------- rigid shells


def cup_shell(r: float = 0.04, h: float = 0.1, sections: int = 64) -> trimesh.Trimesh:
    """A closed-top cylinder standing on z = 0 with its bottom cap removed (open at the bottom)."""
    c = trimesh.creation.cylinder(radius=r, height=h, sections=sections)
    c.apply_translation([0, 0, h / 2])
    keep = ~((c.face_normals[:, 2] < -0.99) & (c.triangles_center[:, 2] < 1e-9))
    return trimesh.Trimesh(c.vertices, c.faces[keep], process=False)


def sphere_shell(r: float = 0.05, cut: float = 0.1, subdivisions: int = 4) -> trimesh.Trimesh:
    """A sphere resting on z = 0 (centre at z = r) without its lowest cap, below z = cut * r
    (a reconstruction misses the contact region)."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=r)
    s.apply_translation([0, 0, r])
    keep = s.vertices[s.faces][:, :, 2].min(1) >= cut * r
    return trimesh.Trimesh(s.vertices, s.faces[keep], process=False)
