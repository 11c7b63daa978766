"""Tiny analytic twins for the sim tests (world frame: m, +z up; fronts face -y).

A carcass is 5 boxes (bottom, top, two sides, back; open at y = 0). A drawer is a box open at
the top (front, back, two sides, bottom) sliding out along -y; a door is a panel in front of a
carcass hinged at its left vertical edge (on its back face); a flap is a panel hinged at its
bottom edge (opens down); a cup is a cylinder mesh standing on the floor or a counter.
"""

import math

import numpy as np
import trimesh

from drawer_lib.io.parts import Axis, Front, Part, PartsFile
from drawer_lib.bodies import PartBody, RigidBody, Shape, TwinModel, box_shape, mesh_shape

T = 0.018  # carcass and front panel thickness
TD = 0.012  # drawer walls
GAP = 0.002  # clearance between a front and its carcass
DENSITY = 600.0


def slab(lo, hi) -> Shape:
    """Axis-aligned box between corners ``lo`` and ``hi``."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return box_shape((lo + hi) / 2, (hi - lo) / 2)


def carcass(x0: float, x1: float, z0: float, z1: float, depth: float) -> list[Shape]:
    """5 walls spanning x [x0, x1], y [0, depth], z [z0, z1], open at the front (y = 0)."""
    return [slab((x0, 0, z0), (x1, depth, z0 + T)), slab((x0, 0, z1 - T), (x1, depth, z1)),
            slab((x0, 0, z0 + T), (x0 + T, depth, z1 - T)), slab((x1 - T, 0, z0 + T), (x1, depth, z1 - T)),
            slab((x0 + T, depth - T, z0 + T), (x1 - T, depth, z1 - T))]


def drawer_box(x0: float, x1: float, z0: float, z1: float, y0: float, y1: float) -> list[Shape]:
    """A box open at the top: front, back, two sides and a bottom of thickness TD."""
    return [slab((x0, y0, z0), (x1, y0 + TD, z1)), slab((x0, y1 - TD, z0), (x1, y1, z1)),
            slab((x0, y0 + TD, z0), (x0 + TD, y1 - TD, z1)), slab((x1 - TD, y0 + TD, z0), (x1, y1 - TD, z1)),
            slab((x0 + TD, y0 + TD, z0), (x1 - TD, y1 - TD, z0 + TD))]


def as_visual(shapes: list[Shape]) -> list[Shape]:
    return [mesh_shape(*s.triangles()) for s in shapes]


def floor() -> Shape:
    return box_shape((0.0, 0.0, -0.05), (3.0, 3.0, 0.05))


def drawer_cabinet(cx: float = 0.0, travel: float = 0.4, reverse: bool = False, sink: float = 0.0,
                   pid: str = "drawer_0") -> tuple[list[Shape], PartBody]:
    """Carcass 0.6 x 0.5 x 0.3 m on the floor at x = cx and its drawer (3 mm side clearance),
    sliding out along -y by ``travel``; ``reverse`` points the axis into the back wall; ``sink``
    moves the drawer down into the carcass bottom by that much (m)."""
    x0, x1, depth, h = cx - 0.3, cx + 0.3, 0.5, 0.3
    walls = carcass(x0, x1, 0.0, h, depth)
    c = 0.003
    z0 = T + c - sink
    shapes = drawer_box(x0 + T + c, x1 - T - c, z0, 0.25, 0.0, 0.45)
    part = PartBody(id=pid, kind="prismatic", axis_origin=np.array([cx, 0.0, 0.135]),
                    axis_direction=np.array([0.0, 1.0 if reverse else -1.0, 0.0]), limits=(0.0, travel),
                    visual=as_visual(shapes), collision=shapes, density=DENSITY)
    return walls, part


def door_cabinet(cx: float = 1.2, pid: str = "door_0") -> tuple[list[Shape], PartBody]:
    """Carcass 0.5 x 0.5 x 0.7 m at x = cx with a door in front of it, hinged on the left edge of
    its back face, opening outward (-y) by up to 90°."""
    x0, x1, h = cx - 0.25, cx + 0.25, 0.7
    walls = carcass(x0, x1, 0.0, h, 0.5)
    panel = slab((x0 + 0.0015, -GAP - T, GAP), (x1 - 0.0015, -GAP, h - GAP))
    part = PartBody(id=pid, kind="revolute", axis_origin=np.array([x0, -GAP, h / 2]),
                    axis_direction=np.array([0.0, 0.0, -1.0]), limits=(0.0, math.pi / 2),
                    visual=as_visual([panel]), collision=[panel], density=DENSITY)
    return walls, part


def flap_cabinet(cx: float = -1.2, pid: str = "flap_0") -> tuple[list[Shape], PartBody]:
    """A wall-cabinet carcass 0.5 x 0.35 x 0.4 m at z 0.6-1.0 with a flap hinged at the bottom edge
    of its back face, opening down (outward) by up to 90°."""
    x0, x1, z0, z1 = cx - 0.25, cx + 0.25, 0.6, 1.0
    walls = carcass(x0, x1, z0, z1, 0.35)
    panel = slab((x0 + 0.0015, -GAP - T, z0 + GAP), (x1 - 0.0015, -GAP, z1 - 0.0015))
    part = PartBody(id=pid, kind="revolute", axis_origin=np.array([cx, -GAP, z0 + GAP]),
                    axis_direction=np.array([1.0, 0.0, 0.0]), limits=(0.0, math.pi / 2),
                    visual=as_visual([panel]), collision=[panel], density=DENSITY)
    return walls, part


def cup(x: float, y: float, z: float, pid: str = "cup_0", radius: float = 0.04, height: float = 0.1,
        density: float = 800.0) -> RigidBody:
    """A solid cylinder (24-gon prism mesh) standing with its bottom at height z."""
    m = trimesh.creation.cylinder(radius=radius, height=height, sections=24)
    v = np.asarray(m.vertices) + [x, y, z + height / 2]
    s = mesh_shape(v, np.asarray(m.faces))
    return RigidBody(id=pid, visual=[s], collision=[s], density=density)


def kitchen(**drawer_kw) -> TwinModel:
    """Floor + drawer cabinet + door cabinet + flap wall cabinet + a counter with a cup on it and
    a cup on the floor."""
    walls_d, drawer = drawer_cabinet(**drawer_kw)
    walls_o, door = door_cabinet()
    walls_f, flap = flap_cabinet()
    counter = slab((2.0, 0.0, 0.0), (2.6, 0.6, 0.9))
    static = [floor(), *walls_d, *walls_o, *walls_f, counter]
    return TwinModel(static_visual=as_visual(static), static_collision=static, parts=[drawer, door, flap],
                     rigid=[cup(2.3, 0.3, 0.9, "cup_0"), cup(0.0, -1.0, 0.0, "cup_1")])


def single(part_fn, **kw) -> TwinModel:
    walls, part = part_fn(**kw)
    static = [floor(), *walls]
    return TwinModel(static_visual=as_visual(static), static_collision=static, parts=[part])


def parts_of(model: TwinModel) -> PartsFile:
    """parts.json entries for the fixture's bodies (fronts from each part's first collision box)."""
    out = []
    for b in model.parts:
        s = max(b.collision, key=lambda s: np.prod(np.asarray(s.box.half)[[0, 2]]))
        c = np.asarray(s.box.center) + np.array([0.0, -s.box.half[1], 0.0])
        out.append(Part(b.id, b.kind, Axis(tuple(b.axis_origin), tuple(b.axis_direction)), tuple(b.limits),
                        Front(tuple(c), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (2 * s.box.half[0], 2 * s.box.half[2]))))
    for r in model.rigid:
        v = r.visual[0].vertices
        lo, hi = v.min(0), v.max(0)
        out.append(Part(r.id, "rigid", center=tuple((lo + hi) / 2), bounds=(tuple(lo), tuple(hi))))
    return PartsFile(tuple(out))
