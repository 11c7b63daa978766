"""Procedural kitchen layouts: cabinets, fronts with joints, handles, counter, room, objects.

World frame (see :mod:`drawer_lib.geometry`): z up, back wall in the plane y = 0, cabinets at
y < 0 with their fronts facing -y, x to the right of a viewer facing the wall. Everything is
built at the closed state (all joints at 0) as textured meshes grouped into entities; the
MuJoCo builder (:mod:`drawer_lib.synth.model`) and the ground truth (:mod:`drawer_lib.synth.gt`)
both read this one description.

Joint conventions (as in ``drawer.parts/1``): ``axis_dir`` is oriented so that a positive joint value opens the
part; for a revolute front with outward normal n and unit vector r from the hinge edge towards
the free edge, that is ``axis_dir = r x n``. Hinge axes lie on the hinge edge of the front's
outer face, so an opening front never sweeps into its carcass or its neighbours' gaps.
"""

from dataclasses import dataclass, field

import numpy as np

from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Front
from drawer_lib.synth import textures as tex
from drawer_lib.synth.config import BASE_TYPES, FIXED_TYPES, WALL_TYPES, LayoutConfig, SynthConfig
from drawer_lib.synth.meshes import UVMesh, box_between, concat, cylinder, lathe, torus_arc

OUT = np.array([0.0, -1.0, 0.0])  # outward normal of every front
U = np.array([1.0, 0.0, 0.0])  # in-plane horizontal of every front
V = np.array([0.0, 0.0, 1.0])  # in-plane vertical (= OUT x U)
T_CARCASS = 0.018  # carcass panel thickness (m)
T_BACK = 0.008
ROOM_HEIGHT = 2.6


@dataclass
class Piece:
    """A textured closed mesh in world coordinates (closed state) with its material."""

    mesh: UVMesh
    material: str
    role: str  # structure | front | handle | interior | object


@dataclass
class Entity:
    """A group of pieces that moves together. ``entities[0]`` of a layout is the static scene."""

    name: str
    family: str  # static | drawer | door | flap | sliding | appliance | false_front | object
    label: str  # what a detector would call it (typed label)
    pieces: list[Piece] = field(default_factory=list)
    joint: str | None = None  # hinge | slide | free | None (fixed)
    axis_origin: np.ndarray | None = None
    axis_dir: np.ndarray | None = None
    limits: tuple[float, float] | None = None
    front: Front | None = None
    hinge: str | None = None  # left | right | top | bottom for revolute fronts
    instance_id: int = 0
    mass: float = 1.0

    @property
    def articulated(self) -> bool:
        return self.joint in ("hinge", "slide")

    def mesh(self, roles: tuple[str, ...] | None = None) -> UVMesh:
        return concat([p.mesh for p in self.pieces if roles is None or p.role in roles])


def transform_entity(e: Entity, R: np.ndarray, t: np.ndarray) -> None:
    """Move entity ``e`` in place by the rigid transform x -> R x + t (pieces, axis, front)."""
    e.pieces = [Piece(p.mesh.transformed(R, t), p.material, p.role) for p in e.pieces]
    if e.axis_origin is not None:
        e.axis_origin = R @ e.axis_origin + t
    if e.axis_dir is not None:
        e.axis_dir = R @ e.axis_dir
    if e.front is not None:
        f = e.front
        e.front = Front(tuple((R @ np.asarray(f.center) + t).tolist()), tuple((R @ np.asarray(f.normal)).tolist()),
                        tuple((R @ np.asarray(f.u)).tolist()), f.size)


def yaw_matrix(deg: float) -> np.ndarray:
    a = np.deg2rad(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Material:
    name: str
    texture: np.ndarray  # uint8 [N, N, 3], tileable
    size_m: float  # physical size of one texture tile
    specular: float = 0.1
    shininess: float = 0.1


@dataclass(frozen=True)
class Light:
    pos: tuple[float, float, float]
    dir: tuple[float, float, float]
    diffuse: float
    castshadow: bool


@dataclass
class KitchenLayout:
    entities: list[Entity]
    materials: dict[str, Material]
    lights: list[Light]
    room_lo: np.ndarray
    room_hi: np.ndarray
    run_x: tuple[float, float]  # x extent of the cabinets (base run and tall units)
    front_y: float  # y of the base fronts' outer faces
    wall_front_y: float
    seed: int
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))  # kitchen frame -> world (a yaw about z)

    @property
    def static(self) -> Entity:
        return self.entities[0]

    def parts(self) -> list[Entity]:
        return [e for e in self.entities[1:] if e.instance_id > 0]


# ---------------------------------------------------------------------------------------------
# materials


def _sample_materials(rng: np.random.Generator) -> dict[str, Material]:
    woods = [((0.74, 0.57, 0.38), (0.47, 0.31, 0.18)), ((0.46, 0.31, 0.2), (0.24, 0.14, 0.08)),
             ((0.82, 0.7, 0.52), (0.6, 0.46, 0.3))]
    paints = [(0.9, 0.9, 0.87), (0.55, 0.62, 0.52), (0.22, 0.27, 0.4), (0.56, 0.57, 0.59), (0.87, 0.83, 0.72),
              (0.62, 0.3, 0.25)]

    def front_material(name: str) -> Material:
        if rng.random() < 0.45:
            b, d = woods[rng.integers(len(woods))]
            return Material(name, tex.wood(rng, b, d), 0.5)
        return Material(name, tex.painted(rng, paints[rng.integers(len(paints))], mottle=0.14), 0.5, 0.2, 0.3)

    base_front = front_material("front_base")
    wall_front = front_material("front_wall") if rng.random() < 0.4 else Material(
        "front_wall", base_front.texture, base_front.size_m, base_front.specular, base_front.shininess)
    stones = [((0.24, 0.24, 0.26), (0.42, 0.4, 0.38)), ((0.82, 0.8, 0.76), (0.62, 0.6, 0.56)),
              ((0.55, 0.5, 0.44), (0.35, 0.31, 0.27))]
    s1, s2 = stones[rng.integers(len(stones))]
    tile_cols = [(0.92, 0.92, 0.9), (0.55, 0.7, 0.72), (0.76, 0.66, 0.56), (0.32, 0.42, 0.36)]
    metal_col = [(0.72, 0.72, 0.74), (0.13, 0.13, 0.14), (0.7, 0.56, 0.36)][rng.integers(3)]
    floor = (Material("floor", tex.planks(rng, (0.66, 0.5, 0.34), (0.42, 0.29, 0.17)), 1.2) if rng.random() < 0.5
             else Material("floor", tex.tiles(rng, (0.6, 0.58, 0.55), (0.35, 0.34, 0.33), k=2, jitter=0.12), 0.9))
    ceramic_cols = [((0.85, 0.3, 0.25), (0.95, 0.92, 0.85)), ((0.2, 0.4, 0.7), (0.9, 0.9, 0.9)),
                    ((0.95, 0.85, 0.3), (0.3, 0.3, 0.3)), ((0.3, 0.6, 0.4), (0.96, 0.96, 0.9))]
    mats = [
        base_front, wall_front,
        Material("carcass", tex.painted(rng, (0.86, 0.85, 0.82), mottle=0.1), 0.5),
        Material("counter", tex.stone(rng, s1, s2), 0.6, 0.3, 0.5),
        Material("backsplash", tex.tiles(rng, tile_cols[rng.integers(len(tile_cols))], (0.55, 0.55, 0.53)), 0.6, 0.3, 0.5),
        Material("wall", tex.painted(rng, (0.85, 0.83, 0.78), mottle=0.15), 0.8),
        Material("ceiling", tex.painted(rng, (0.9, 0.9, 0.9), mottle=0.08), 1.0),
        floor,
        Material("handle", tex.metal(rng, metal_col), 0.2, 0.5, 0.6),
        Material("appliance", tex.metal(rng, (0.74, 0.75, 0.77)), 0.4, 0.4, 0.5),
        Material("glass", tex.glass(rng), 0.3, 0.6, 0.8),
        Material("plinth", tex.painted(rng, (0.3, 0.3, 0.31), mottle=0.12), 0.5),
        Material("bottle", tex.painted(rng, (0.2, 0.45, 0.3), mottle=0.2), 0.2, 0.5, 0.7),
        Material("cardboard", tex.ceramic(rng, (0.85, 0.7, 0.3), (0.7, 0.15, 0.1), bands=4), 0.25),
    ]
    for k in range(len(ceramic_cols)):
        c, a = ceramic_cols[k]
        mats.append(Material(f"ceramic{k}", tex.ceramic(rng, c, a), 0.2, 0.4, 0.6))
    return {m.name: m for m in mats}


# ---------------------------------------------------------------------------------------------
# fronts and handles


@dataclass(frozen=True)
class Rect:
    """A front rectangle on the plane y = y_out (outer face), x in [x0, x1], z in [z0, z1]."""

    x0: float
    x1: float
    z0: float
    z1: float
    y_out: float

    @property
    def center(self) -> np.ndarray:
        return np.array([(self.x0 + self.x1) / 2, self.y_out, (self.z0 + self.z1) / 2])

    @property
    def w(self) -> float:
        return self.x1 - self.x0

    @property
    def h(self) -> float:
        return self.z1 - self.z0

    def front(self) -> Front:
        return Front(tuple(self.center), tuple(OUT), tuple(U), (self.w, self.h))


def _panel(r: Rect, thickness: float) -> UVMesh:
    """The front panel: outer face at r.y_out, extending ``thickness`` into the cabinet."""
    return box_between([r.x0, r.y_out, r.z0], [r.x1, r.y_out + thickness, r.z1])


def _handle(style: str, p: np.ndarray, along: np.ndarray, length: float, edge: str | None = None,
            r: Rect | None = None, tf: float = 0.019) -> list[UVMesh]:
    """Handle meshes at point ``p`` on a front's outer face.

    bar: a rod on two posts (length = rod length), knob: a round knob, edge: a pull profile
    straddling the front's ``edge`` (top, bottom, left, right) of rect ``r``, centred at p.
    """
    if style == "bar":
        s = 0.032  # standoff
        a, b = p - along * length / 2, p + along * length / 2
        return [
            cylinder(a, a + OUT * s, 0.0045, 12),
            cylinder(b, b + OUT * s, 0.0045, 12),
            cylinder(a - along * 0.014 + OUT * s, b + along * 0.014 + OUT * s, 0.0065, 16),
        ]
    if style in ("knob", "small_knob"):
        k = 1.0 if style == "knob" else 0.55  # a small knob: 18 mm across, 19 mm proud
        stem = cylinder(p, p + OUT * 0.02 * k, 0.006 * k, 12)
        cap = lathe(np.array([[0, 0], [0.011, 0], [0.016, 0.007], [0.014, 0.015], [0, 0.017]]) * k, 20)
        R = np.stack([U, V, OUT], axis=1)  # lathe axis (+z) -> OUT, right-handed
        return [stem, cap.transformed(R, p + OUT * 0.016 * k)]
    if style == "edge":
        assert r is not None and edge is not None
        L, lip, depth = length, 0.022, 0.012
        y0, y_in = r.y_out - depth, r.y_out + tf
        if edge in ("top", "bottom"):
            z_e = r.z1 if edge == "top" else r.z0
            sgn = 1 if edge == "top" else -1
            x0, x1 = p[0] - L / 2, p[0] + L / 2
            plate = box_between([x0, y0, min(z_e, z_e + sgn * 0.0015)], [x1, y_in, max(z_e, z_e + sgn * 0.0015)])
            zl = sorted([z_e + sgn * 0.0015, z_e - sgn * lip])
            lipm = box_between([x0, y0, zl[0]], [x1, y0 + 0.004, zl[1]])
            return [plate, lipm]
        x_e = r.x1 if edge == "right" else r.x0
        sgn = 1 if edge == "right" else -1
        z0, z1 = p[2] - L / 2, p[2] + L / 2
        plate = box_between([min(x_e, x_e + sgn * 0.0015), y0, z0], [max(x_e, x_e + sgn * 0.0015), y_in, z1])
        xl = sorted([x_e + sgn * 0.0015, x_e - sgn * lip])
        lipm = box_between([xl[0], y0, z0], [xl[1], y0 + 0.004, z1])
        return [plate, lipm]
    raise ConfigError(f"unknown handle style {style!r}")


class _Builder:
    """Accumulates entities while the layout is laid out."""

    def __init__(self, rng: np.random.Generator, L: LayoutConfig, handle_style: str, rng2: np.random.Generator):
        # draws for the keys added later (tall types, microwaves, yaw, missing handles, the new
        # module types' options) come from their own stream ``rng2``, so older kitchens stay the same
        self.rng, self.L, self.style, self.rng2 = rng, L, handle_style, rng2
        self.static = Entity("static", "static", "background")
        self.entities: list[Entity] = []
        self.counts: dict[str, int] = {}

    def add_static(self, mesh: UVMesh, material: str, role: str = "structure") -> None:
        self.static.pieces.append(Piece(mesh, material, role))

    def _name(self, family: str) -> str:
        k = self.counts.get(family, 0)
        self.counts[family] = k + 1
        return f"{family}_{k}"

    def _front_pieces(self, r: Rect, material: str, where: str, along: str, length: float) -> list[Piece]:
        """The front panel of rect r with its handle (:meth:`_handle_pieces`), in the kitchen's
        handle style, or none with probability ``no_handle_p``; a ``recessed`` pull is a slot
        through the panel's outer 12 mm (the panel is built around it) with the pocket's back
        as the handle."""
        tf, style = self.L.front_thickness, self.style
        if self.L.no_handle_p > 0 and self.rng2.random() < self.L.no_handle_p:
            style = "none"
        if style == "none":
            return [Piece(_panel(r, tf), material, "front")]
        if style != "recessed":
            return [Piece(_panel(r, tf), material, "front")] + self._handle_pieces(r, where, along, length)
        x, z, length = self._handle_place(r, where, along, length)
        half = (length / 2, 0.014) if along == "h" else (0.014, length / 2)
        sx0, sx1 = max(x - half[0], r.x0 + 0.02), min(x + half[0], r.x1 - 0.02)
        sz0, sz1 = max(z - half[1], r.z0 + 0.02), min(z + half[1], r.z1 - 0.02)
        y0, y1, yp = r.y_out, r.y_out + tf, r.y_out + 0.012
        boxes = [([r.x0, y0, r.z0], [sx0, y1, r.z1]), ([sx1, y0, r.z0], [r.x1, y1, r.z1]),
                 ([sx0, y0, r.z0], [sx1, y1, sz0]), ([sx0, y0, sz1], [sx1, y1, r.z1])]
        out = [Piece(box_between(lo, hi), material, "front") for lo, hi in boxes]
        return out + [Piece(box_between([sx0, yp, sz0], [sx1, y1, sz1]), "handle", "handle")]

    def _handle_place(self, r: Rect, where: str, along: str, length: float) -> tuple[float, float, float]:
        """(x, z) of a handle's centre on rect r and its length. A handle stays on its front: one
        whose end would stand more than 1 cm beyond it (a long bar placed near an edge) moves
        inward until 2 cm of the front remain past its end."""
        inset = 0.045
        c = r.center
        x = {"left": r.x0 + inset, "right": r.x1 - inset}.get(where.split("-")[-1], c[0])
        top_z = r.z1 - max(0.045, min(r.h / 2 - 0.001, 0.06))
        z = {"top": top_z, "bottom": r.z0 + max(0.045, min(r.h / 2 - 0.001, 0.06))}.get(where.split("-")[0], c[2])
        length = min(length, (r.w if along == "h" else r.h) - 0.06)
        lo, hi = (r.x0, r.x1) if along == "h" else (r.z0, r.z1)
        at = x if along == "h" else z
        if at - length / 2 < lo - 0.01 or at + length / 2 > hi + 0.01:
            at = float(np.clip(at, lo + length / 2 + 0.02, hi - length / 2 - 0.02))
            x, z = (at, z) if along == "h" else (x, at)
        return float(x), float(z), float(length)

    def _handle_pieces(self, r: Rect, where: str, along: str, length: float) -> list[Piece]:
        """Place a handle on rect r. ``where``: top|bottom|center|left|right|mid-left|...;
        ``along``: 'h' or 'v' (direction of a bar or edge pull)."""
        tf, style = self.L.front_thickness, self.style
        c = r.center
        d = U if along == "h" else V
        x, z, length = self._handle_place(r, where, along, length)
        if style == "edge":
            # a pull profile on the edge nearest to where a hand would pull
            if along == "v":
                edge = "left" if where.endswith("left") else "right"
            else:
                edge = "bottom" if where.startswith("bottom") else "top"
            if edge in ("top", "bottom"):
                p = np.array([c[0] if along == "h" else x, r.y_out, r.z1 if edge == "top" else r.z0])
                meshes = _handle("edge", p, U, min(length, r.w - 0.04), edge, r, tf)
            else:
                p = np.array([r.x1 if edge == "right" else r.x0, r.y_out, z])
                meshes = _handle("edge", p, V, min(length, r.h - 0.04), edge, r, tf)
        else:
            p = np.array([x, r.y_out, z])
            meshes = _handle(style, p, d, length)
        return [Piece(m, "handle", "handle") for m in meshes]

    def add_front(self, family: str, r: Rect, material: str, *, hinge: str | None = None,
                  fixed: bool = False, carcass: tuple[float, float, float] | None = None,
                  limit: float | None = None, handle_where: str = "center", handle_along: str = "h",
                  handle_len: float = 0.16, slide_dir: float = 0.0, label: str = "") -> Entity:
        """One front with its handle: ``family`` drawer|door|flap|sliding, or with ``fixed``
        appliance|false_front (no joint; listed in the GT ignore boxes).

        ``hinge``: left|right|top|bottom for revolute fronts. ``carcass`` = (x0, x1, depth) of
        the cabinet interior a drawer box fits in. ``slide_dir`` (+1/-1) moves a sliding door
        along +x/-x.
        """
        assert fixed == (family in ("appliance", "false_front")), family
        tf = self.L.front_thickness
        default_label = {"drawer": "drawer", "false_front": "drawer", "door": "door", "flap": "door",
                         "sliding": "door", "appliance": "door"}[family]
        e = Entity(self._name(family), family, label or default_label)
        e.pieces += self._front_pieces(r, material, handle_where, handle_along, handle_len)
        e.front = r.front()
        if fixed:
            return self._push(e)
        c = r.center
        if family == "drawer":
            assert carcass is not None
            x0, x1, depth = carcass
            dd = depth - 0.05
            wall = 0.012
            bx0, bx1 = x0 + 0.013, x1 - 0.013
            bz0, bz1 = r.z0 + 0.02, max(r.z0 + 0.06, r.z1 - 0.035)
            y_in = r.y_out + tf
            for lo, hi in [([bx0, y_in, bz0], [bx0 + wall, y_in + dd, bz1]),
                           ([bx1 - wall, y_in, bz0], [bx1, y_in + dd, bz1]),
                           ([bx0 + wall, y_in + dd - wall, bz0], [bx1 - wall, y_in + dd, bz1]),
                           ([bx0 + wall, y_in, bz0], [bx1 - wall, y_in + dd - wall, bz0 + wall])]:
                e.pieces.append(Piece(box_between(lo, hi), "carcass", "interior"))
            e.joint, e.axis_origin, e.axis_dir = "slide", c.copy(), OUT.copy()
            e.limits = (0.0, round(0.85 * dd, 4))
        elif family == "sliding":
            e.joint, e.axis_origin, e.axis_dir = "slide", c.copy(), U * np.sign(slide_dir)
            e.limits = (0.0, round(limit, 4))
        else:  # revolute: door or flap
            e.joint = "hinge"
            edge_pt = {"left": [r.x0, r.y_out, c[2]], "right": [r.x1, r.y_out, c[2]],
                       "bottom": [c[0], r.y_out, r.z0], "top": [c[0], r.y_out, r.z1]}[hinge]
            e.axis_origin = np.array(edge_pt, np.float64)
            to_free = c - e.axis_origin
            to_free[1] = 0.0
            to_free /= np.linalg.norm(to_free)
            e.axis_dir = np.cross(to_free, OUT)
            e.limits = (0.0, round(float(limit), 4))
            e.hinge = hinge
        e.mass = max(0.3, 700.0 * r.w * r.h * tf) + (2.0 if family == "drawer" else 0.0)  # kg, MDF
        return self._push(e)

    def _push(self, e: Entity) -> Entity:
        self.entities.append(e)
        return e


# ---------------------------------------------------------------------------------------------
# modules


def _carcass(b: _Builder, x0: float, x1: float, z0: float, z1: float, depth: float) -> None:
    t = T_CARCASS
    y0 = -depth
    b.add_static(box_between([x0, y0, z0], [x0 + t, 0.0, z1]), "carcass")
    b.add_static(box_between([x1 - t, y0, z0], [x1, 0.0, z1]), "carcass")
    b.add_static(box_between([x0 + t, y0, z0], [x1 - t, -T_BACK, z0 + t]), "carcass")
    b.add_static(box_between([x0 + t, y0, z1 - t], [x1 - t, -T_BACK, z1]), "carcass")
    b.add_static(box_between([x0 + t, -T_BACK, z0], [x1 - t, 0.0, z1]), "carcass")


def _revolute_limit(b: _Builder) -> float:
    return float(np.deg2rad(b.rng.choice(b.L.revolute_limits_deg)))


def _halves(r: Rect, g: float) -> tuple[Rect, Rect]:
    """Left and right halves of a front rectangle with a gap ``g`` between them."""
    xm = (r.x0 + r.x1) / 2
    return Rect(r.x0, xm - g / 2, r.z0, r.z1, r.y_out), Rect(xm + g / 2, r.x1, r.z0, r.z1, r.y_out)


def _flap(b: _Builder, r: Rect, material: str, hinge: str) -> None:
    """A flap hinged at its top (lifts up to 100 deg) or bottom (drops down 90 deg), with the
    handle on the opposite edge."""
    limit = np.deg2rad(100.0) if hinge == "top" else np.pi / 2
    b.add_front("flap", r, material, hinge=hinge, limit=float(limit), handle_where="bottom" if hinge == "top" else "top",
                handle_along="h", handle_len=min(0.32, r.w * 0.5))


def _base_module(b: _Builder, kind: str, x0: float, x1: float) -> None:
    L, g = b.L, b.L.front_gap
    z0 = L.plinth_height
    z1 = z0 + L.carcass_height
    D = L.base_depth
    _carcass(b, x0, x1, z0, z1, D)
    y = -D - L.front_thickness
    mat = "front_base"
    inner = (x0 + T_CARCASS, x1 - T_CARCASS, D)
    full = Rect(x0 + g / 2, x1 - g / 2, z0 + g / 2, z1 - g / 2, y)

    def door(r: Rect, hinge: str, fixed: bool = False, material: str = mat):
        free = "right" if hinge == "left" else "left"
        b.add_front("door", r, material, hinge=hinge, fixed=fixed, limit=_revolute_limit(b),
                    handle_where=f"top-{free}", handle_along="v", handle_len=0.128)

    def drawer(r: Rect, fixed: bool = False):
        b.add_front("false_front" if fixed else "drawer", r, mat, carcass=inner, fixed=fixed, handle_where="top" if r.h > 0.2 else "center",
                    handle_along="h", handle_len=min(0.32, max(0.128, r.w * 0.45)))

    if kind == "door":
        door(full, "left" if b.rng.random() < 0.5 else "right")
    elif kind == "double_door":
        left, right = _halves(full, g)
        door(left, "left")
        door(right, "right")
    elif kind == "drawers":
        n = 3 if L.carcass_height > 0.5 else 2
        fr = np.array([0.22, 0.34, 0.44]) if n == 3 else np.array([0.45, 0.55])
        zs = z1 - np.concatenate([[0], np.cumsum(fr)]) * (z1 - z0)
        for k in range(n):
            drawer(Rect(full.x0, full.x1, zs[k + 1] + g / 2, zs[k] - g / 2, y))
    elif kind in ("drawer_door", "sink"):
        zm = z1 - 0.2 * (z1 - z0)
        drawer(Rect(full.x0, full.x1, zm + g / 2, full.z1, y), fixed=(kind == "sink"))
        lower = Rect(full.x0, full.x1, full.z0, zm - g / 2, y)
        if kind == "sink" or lower.w > 0.7:
            left, right = _halves(lower, g)
            door(left, "left")
            door(right, "right")
        else:
            door(lower, "left" if b.rng.random() < 0.5 else "right")
    elif kind == "flap_down":
        _flap(b, full, mat, "bottom")
    elif kind == "oven":
        # a storage drawer at the bottom, the oven door (bottom-hinged, a bar near its top edge)
        # and a control strip above it
        zd = z0 + 0.14
        zs = z1 - 0.1
        drawer(Rect(full.x0, full.x1, full.z0, zd - g / 2, y))
        door_r = Rect(full.x0, full.x1, zd + g / 2, zs - g / 2, y)
        e = b.add_front("flap", door_r, "appliance", hinge="bottom", limit=float(np.pi / 2), handle_where="top",
                        handle_along="h", handle_len=door_r.w * 0.75, label="door")
        win = Rect(door_r.x0 + 0.06, door_r.x1 - 0.06, door_r.z0 + 0.08, door_r.z1 - 0.12, y)
        e.pieces.append(Piece(box_between([win.x0, y - 0.001, win.z0], [win.x1, y + 0.002, win.z1]), "glass", "front"))
        b.add_static(box_between([full.x0, y, zs + g / 2], [full.x1, y + L.front_thickness, full.z1]), "appliance")
    elif kind == "dishwasher":
        # a full-height bottom-hinged door: integrated (the kitchen's front) or stainless
        material = mat if b.rng2.random() < 0.5 else "appliance"
        b.add_front("flap", full, material, hinge="bottom", limit=float(np.pi / 2), handle_where="top",
                    handle_along="h", handle_len=min(0.4, full.w * 0.6), label="door")
    elif kind == "appliance":
        e = b.add_front("appliance", full, "appliance", fixed=True, handle_where="top", handle_along="h",
                        handle_len=full.w * 0.7)
        strip = Rect(full.x0 + 0.02, full.x1 - 0.02, full.z1 - 0.09, full.z1 - 0.05, y)
        e.pieces.append(Piece(box_between([strip.x0, y - 0.001, strip.z0], [strip.x1, y + 0.002, strip.z1]), "glass", "front"))
    else:
        raise ConfigError(f"unknown base module type {kind!r} (known: {BASE_TYPES})")


def _wall_module(b: _Builder, kind: str, x0: float, x1: float) -> None:
    L, g = b.L, b.L.front_gap
    z0, z1, D = L.wall_bottom, L.wall_bottom + L.wall_height, L.wall_depth
    _carcass(b, x0, x1, z0, z1, D)
    tf = L.front_thickness
    y = -D - tf
    mat = "front_wall"
    full = Rect(x0 + g / 2, x1 - g / 2, z0 + g / 2, z1 - g / 2, y)

    def door(r: Rect, hinge: str, glass: bool = False):
        free = "right" if hinge == "left" else "left"
        e = b.add_front("door", r, mat, hinge=hinge, limit=_revolute_limit(b), handle_where=f"bottom-{free}",
                        handle_along="v", handle_len=0.128)
        if glass:  # a glass pane in a 6 cm frame (a vitrine door)
            fr = min(0.06, 0.25 * r.w, 0.25 * (r.z1 - r.z0))
            e.pieces.append(Piece(box_between([r.x0 + fr, r.y_out - 0.001, r.z0 + fr], [r.x1 - fr, r.y_out + 0.002, r.z1 - fr]),
                                  "glass", "front"))

    if kind in ("door", "glass_door"):
        door(full, "left" if b.rng.random() < 0.5 else "right", kind == "glass_door")
    elif kind in ("double_door", "glass_double"):
        left, right = _halves(full, g)
        door(left, "left", kind == "glass_double")
        door(right, "right", kind == "glass_double")
    elif kind in ("flap_up", "flap_down"):
        _flap(b, full, mat, "top" if kind == "flap_up" else "bottom")
    elif kind == "sliding":
        # two panels on two tracks; the outer one (left) slides right, the inner one left
        xm = (x0 + x1) / 2
        ov = 0.02  # overlap in the middle
        inner = Rect(xm - ov / 2, full.x1, full.z0, full.z1, y)
        outer = Rect(full.x0, xm + ov / 2, full.z0, full.z1, y - tf - 0.004)
        travel = inner.w - ov - 0.02
        b.add_front("sliding", outer, mat, limit=travel, slide_dir=+1.0, handle_where="bottom-left",
                    handle_along="v", handle_len=0.128)
        b.add_front("sliding", inner, mat, limit=travel, slide_dir=-1.0, handle_where="bottom-right",
                    handle_along="v", handle_len=0.128)
    elif kind == "sliding_single":
        # one panel on a rail in front of the cabinet, covering one half; the other half is an
        # open shelf it slides over (no partner front to see)
        rail_h = 0.04  # a top-hung track: an aluminium profile 4 cm tall, 1.5 cm proud of the panel
        ys = y - tf - 0.004
        b.add_static(box_between([x0, ys - 0.015, z1 - rail_h], [x1, y, z1]), "handle")  # the rail
        xm = (x0 + x1) / 2
        ov = 0.02
        left = b.rng2.random() < 0.5
        panel = (Rect(full.x0, xm + ov / 2, full.z0, z1 - rail_h - g, ys) if left
                 else Rect(xm - ov / 2, full.x1, full.z0, z1 - rail_h - g, ys))
        travel = (x1 - xm) - ov - 0.02
        where = ["center-left", "center-right"][int(b.rng2.integers(2))]
        b.add_front("sliding", panel, mat, limit=travel, slide_dir=+1.0 if left else -1.0, handle_where=where,
                    handle_along="v", handle_len=0.128)
        zm = (z0 + z1) / 2  # a shelf in the open cabinet
        b.add_static(box_between([x0 + T_CARCASS, -D, zm - 0.009], [x1 - T_CARCASS, -T_BACK, zm + 0.009]), "carcass")
    else:
        raise ConfigError(f"unknown wall module type {kind!r} (known: {WALL_TYPES})")


def _tall_unit(b: _Builder, x0: float, x1: float, top: float, kind: str | None = None) -> None:
    """A tall unit between x0 and x1: of ``kind`` (one of TALL_TYPES), or drawn from
    ``tall_types`` when None."""
    L, g = b.L, b.L.front_gap
    z0, D = L.plinth_height, L.base_depth
    _carcass(b, x0, x1, z0, top, D)
    y = -D - L.front_thickness
    zm = z0 + 0.72
    hinge = "left" if b.rng.random() < 0.5 else "right"
    free = "right" if hinge == "left" else "left"
    if kind is None and set(L.tall_types) != {"split"}:
        names = [k for k, w in L.tall_types.items() if w > 0]
        p = np.array([L.tall_types[k] for k in names], np.float64)
        kind = names[b.rng2.choice(len(names), p=p / p.sum())]
    if kind is not None and kind != "split":
        _tall_doors(b, kind, Rect(x0 + g / 2, x1 - g / 2, z0 + g / 2, top - g / 2, y), hinge)
        return
    upper = Rect(x0 + g / 2, x1 - g / 2, zm + g / 2, top - g / 2, y)
    lower = Rect(x0 + g / 2, x1 - g / 2, z0 + g / 2, zm - g / 2, y)
    style = b.style
    b.style = "bar"  # fridge doors carry long bars
    b.add_front("door", upper, "front_base", hinge=hinge, limit=_revolute_limit(b), handle_where=f"bottom-{free}",
                handle_along="v", handle_len=0.45)
    if b.rng.random() < 0.5:
        b.add_front("drawer", lower, "front_base", carcass=(x0 + T_CARCASS, x1 - T_CARCASS, D), handle_where="top",
                    handle_along="h", handle_len=0.3)
    else:
        b.add_front("door", lower, "front_base", hinge=hinge, limit=_revolute_limit(b), handle_where=f"top-{free}",
                    handle_along="v", handle_len=0.3)
    b.style = style


def _tall_doors(b: _Builder, kind: str, full: Rect, hinge: str) -> None:
    """A tall unit's doors: fridge1 (one full-height door, a long bar), fridge2 (a fridge door
    over a freezer door, bars by the gap between them), pantry (one full-height door in the
    kitchen's handle style, at hand height)."""
    free = "right" if hinge == "left" else "left"
    g = b.L.front_gap
    lim = _revolute_limit(b)
    if kind == "pantry":
        b.add_front("door", full, "front_base", hinge=hinge, limit=lim, handle_where=f"center-{free}",
                    handle_along="v", handle_len=0.3)
        return
    style = b.style
    b.style = "bar"  # fridge doors carry long bars
    if kind == "fridge1":
        b.add_front("door", full, "front_base", hinge=hinge, limit=lim, handle_where=f"center-{free}",
                    handle_along="v", handle_len=0.8)
    else:  # fridge2
        zm = full.z0 + 0.38 * full.h
        upper = Rect(full.x0, full.x1, zm + g / 2, full.z1, full.y_out)
        lower = Rect(full.x0, full.x1, full.z0, zm - g / 2, full.y_out)
        b.add_front("door", upper, "front_base", hinge=hinge, limit=lim, handle_where=f"bottom-{free}",
                    handle_along="v", handle_len=0.5)
        b.add_front("door", lower, "front_base", hinge=hinge, limit=lim, handle_where=f"top-{free}",
                    handle_along="v", handle_len=0.35)
    b.style = style


def _microwave(b: _Builder, at: np.ndarray, yaw_deg: float) -> None:
    """A microwave oven standing on the counter at ``at`` (the centre of its base), turned by
    ``yaw_deg``: a static body with a control panel and a door hinged on its left edge."""
    W, Dm, Hm = 0.5, 0.36, 0.29
    R, t = yaw_matrix(yaw_deg), np.asarray(at, np.float64)
    body = Entity("tmp", "static", "")
    body.pieces.append(Piece(box_between([-W / 2, -Dm / 2, 0.0], [W / 2, Dm / 2, Hm]), "appliance", "structure"))
    body.pieces.append(Piece(box_between([W / 2 - 0.12, -Dm / 2 - 0.006, 0.02], [W / 2 - 0.01, -Dm / 2, Hm - 0.02]),
                             "glass", "structure"))
    transform_entity(body, R, t)
    b.static.pieces += body.pieces
    td = 0.02
    door = Rect(-W / 2 + 0.008, W / 2 - 0.135, 0.015, Hm - 0.015, -Dm / 2 - td)
    style = b.style
    if style in ("knob", "small_knob"):
        b.style = "bar"  # a microwave door has no knob
    e = b.add_front("door", door, "appliance", hinge="left", limit=float(np.deg2rad(100.0)),
                    handle_where="center-right", handle_along="v", handle_len=0.18)
    b.style = style
    e.pieces.append(Piece(box_between([door.x0 + 0.04, door.y_out - 0.001, door.z0 + 0.04],
                                      [door.x1 - 0.07, door.y_out + 0.002, door.z1 - 0.04]), "glass", "front"))
    transform_entity(e, R, t)


# ---------------------------------------------------------------------------------------------
# objects


def _object_mesh(kind: str, mat_rng: np.random.Generator) -> tuple[list[tuple[UVMesh, str]], float, float]:
    """Meshes (local frame, base at z = 0) of a rigid object, its footprint radius and mass."""
    ceramic = f"ceramic{mat_rng.integers(4)}"
    if kind == "cup":
        body = lathe(np.array([[0, 0], [0.036, 0], [0.04, 0.004], [0.042, 0.095], [0.037, 0.095],
                               [0.035, 0.012], [0, 0.012]]), 28)
        handle = torus_arc(0.026, 0.0055, np.deg2rad(200)).translated([0.036, 0, 0.05])
        return [(body, ceramic), (handle, ceramic)], 0.07, 0.3
    if kind == "bottle":
        body = lathe(np.array([[0, 0], [0.033, 0], [0.035, 0.006], [0.035, 0.18], [0.03, 0.21], [0.013, 0.24],
                               [0.013, 0.27], [0.015, 0.272], [0.015, 0.29], [0, 0.29]]), 24)
        return [(body, "bottle")], 0.04, 0.8
    if kind == "kettle":
        body = lathe(np.array([[0, 0], [0.075, 0], [0.085, 0.02], [0.085, 0.1], [0.07, 0.17], [0.04, 0.19],
                               [0.03, 0.2], [0.012, 0.215], [0, 0.215]]), 28)
        spout = cylinder([0.07, 0, 0.06], [0.13, 0, 0.15], 0.011, 12)
        R = np.array([[-1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0]])
        handle = torus_arc(0.055, 0.008, np.deg2rad(180)).transformed(R, np.array([-0.06, 0, 0.11]))
        return [(body, "appliance"), (spout, "appliance"), (handle, "handle")], 0.13, 1.2
    if kind == "box":
        m = box_between([-0.05, -0.035, 0.0], [0.05, 0.035, 0.24])
        return [(m, "cardboard")], 0.07, 0.4
    raise ConfigError(f"unknown object kind {kind!r}")


def _place_objects(b: _Builder, n: int, x_lo: float, x_hi: float, y_lo: float, y_hi: float, z: float,
                   occupied: list[tuple[float, float, float]]) -> list[Entity]:
    rng = b.rng
    out = []
    kinds = ["cup", "bottle", "kettle", "box"]
    for _ in range(n):
        kind = kinds[rng.integers(len(kinds))]
        meshes, rad, mass = _object_mesh(kind, rng)
        for _try in range(200):
            x, yy = rng.uniform(x_lo + rad, x_hi - rad), rng.uniform(y_lo + rad, y_hi - rad)
            if all((x - ox) ** 2 + (yy - oy) ** 2 > (rad + orad + 0.03) ** 2 for ox, oy, orad in occupied):
                break
        else:
            continue  # no room left on the counter
        occupied.append((x, yy, rad))
        ang = rng.uniform(0, 2 * np.pi)
        R = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1.0]])
        t = np.array([x, yy, z])
        e = Entity(b._name(kind), "object", kind, joint="free", mass=mass)
        e.pieces = [Piece(m.transformed(R, t), mat, "object") for m, mat in meshes]
        out.append(e)
        b.entities.append(e)
    return out


# ---------------------------------------------------------------------------------------------


def _sample_types(rng: np.random.Generator, n: int, weights: dict[str, float], required: list[str],
                  fixed: int) -> list[str]:
    types: list[str | None] = [None] * n
    slots = list(rng.permutation(n))
    for t in required:
        if len(slots) > fixed:
            types[slots.pop()] = t
    for _ in range(fixed):
        if slots:
            types[slots.pop()] = "appliance" if rng.random() < 0.5 else "sink"
    names = [k for k, w in weights.items() if w > 0]
    p = np.array([weights[k] for k in names], np.float64)
    for s in slots:
        types[s] = names[rng.choice(len(names), p=p / p.sum())] if names else "door"
    return [t for t in types if t is not None]


def _width(rng: np.random.Generator, L: LayoutConfig, kind: str) -> float:
    if kind in ("double_door", "glass_double", "sink", "sliding", "sliding_single"):
        return float(rng.choice(L.double_widths))
    if kind in ("appliance", "oven", "dishwasher"):
        return 0.6
    return float(rng.choice(L.module_widths))


NOT_REPEATED = FIXED_TYPES + ("oven", "dishwasher")  # kinds a run of equal modules neither copies nor replaces


def repeat_runs(rng: np.random.Generator, kinds: list[str], widths: list[float], p: float,
                required: list[str], max_total: float = np.inf) -> tuple[list[str], list[float]]:
    """Runs of equal modules (``LayoutConfig.repeat_p``): left to right, module ``k`` takes module
    ``k - 1``'s kind and width with probability ``p``, unless either is in :data:`NOT_REPEATED`,
    module ``k`` holds the only module of a required kind, or the run (widths in m) would be
    longer than ``max_total`` after the copy (a wall run must fit over the base run, or modules
    are dropped from it). One draw per module from ``rng`` (after any earlier copy, so a run can grow).
    Returns new lists; the inputs are not changed."""
    kinds, widths = list(kinds), list(widths)
    for k in range(1, len(kinds)):
        copy = rng.random() < p
        if not copy or kinds[k - 1] in NOT_REPEATED or kinds[k] in NOT_REPEATED:
            continue
        if kinds[k] in required and kinds.count(kinds[k]) == 1:
            continue
        if sum(widths) - widths[k] + widths[k - 1] > max_total:
            continue
        kinds[k], widths[k] = kinds[k - 1], widths[k - 1]
    return kinds, widths


def sample_layout(cfg: SynthConfig) -> KitchenLayout:
    """Draw a kitchen from ``cfg.seed`` (reproducible: same seed and config, same kitchen)."""
    rng = np.random.default_rng(cfg.seed)
    L = cfg.layout
    materials = _sample_materials(np.random.default_rng([cfg.seed, 1]))
    style = L.handle_styles[rng.integers(len(L.handle_styles))]
    b = _Builder(rng, L, style, np.random.default_rng([cfg.seed, 3]))

    shared = [t for t in L.require_types if t in BASE_TYPES and t in WALL_TYPES]
    req_base = [t for t in L.require_types if t in BASE_TYPES and t not in WALL_TYPES] + shared
    req_wall = [t for t in L.require_types if t in WALL_TYPES and t not in BASE_TYPES]
    if L.modules is None:
        base_kinds = _sample_types(rng, L.base_modules, L.base_types, req_base, L.fixed_fronts)
        wall_kinds = _sample_types(rng, L.wall_modules, L.wall_types, req_wall, 0)
        base_w = [_width(rng, L, k) for k in base_kinds]
        wall_w = [_width(rng, L, k) for k in wall_kinds]
        if L.repeat_p > 0:  # its own stream: repeat_p 0 leaves every kitchen as it was
            rr = np.random.default_rng([cfg.seed, 5])
            base_kinds, base_w = repeat_runs(rr, base_kinds, base_w, L.repeat_p, req_base)
            wall_kinds, wall_w = repeat_runs(rr, wall_kinds, wall_w, L.repeat_p, req_wall, sum(base_w))
    else:  # written by hand (LayoutConfig.modules)
        base_kinds, base_w = [str(t) for t, _ in L.modules["base"]], [float(w) for _, w in L.modules["base"]]
        wall = L.modules.get("wall") or []
        wall_kinds, wall_w = [str(t) for t, _ in wall], [float(w) for _, w in wall]

    run = float(sum(base_w))
    xs = np.concatenate([[0.0], np.cumsum(base_w)])
    for k, kind in enumerate(base_kinds):
        _base_module(b, kind, xs[k], xs[k + 1])

    # wall run centred over the base run; drop modules (not required ones first) until it fits
    while sum(wall_w) > run and wall_kinds:
        drop = next((i for i in reversed(range(len(wall_kinds))) if wall_kinds[i] not in req_wall), len(wall_kinds) - 1)
        wall_kinds.pop(drop)
        wall_w.pop(drop)
    wx = (run - sum(wall_w)) / 2 + np.concatenate([[0.0], np.cumsum(wall_w)])
    for k, kind in enumerate(wall_kinds):
        _wall_module(b, kind, wx[k], wx[k + 1])

    top = L.plinth_height + L.tall_height
    x_lo, x_hi = 0.0, run
    tall_w = L.tall_width
    if L.modules is None:
        sides = [] if L.tall_units == 0 else (["left", "right"] if L.tall_units == 2 else [["left", "right"][rng.integers(2)]])
        tall_kinds: list[str | None] = [None] * len(sides)
    else:
        tall = L.modules.get("tall") or []
        sides, tall_kinds = [str(sd) for sd, _ in tall], [str(t) for _, t in tall]
    for side, kind in zip(sides, tall_kinds):
        if side == "left":
            _tall_unit(b, -tall_w, 0.0, top, kind)
            x_lo = -tall_w
        else:
            _tall_unit(b, run, run + tall_w, top, kind)
            x_hi = run + tall_w

    # plinths, counter, backsplash
    D, tf = L.base_depth, L.front_thickness
    zc = L.plinth_height + L.carcass_height
    b.add_static(box_between([x_lo, -D + 0.05, 0.0], [x_hi, -D + 0.068, L.plinth_height]), "plinth")
    over = 0.02 if not sides else 0.0
    b.add_static(box_between([-over if "left" not in sides else 0.0, -D - tf - 0.02, zc],
                             [run + (over if "right" not in sides else 0.0), 0.0, zc + L.counter_thickness]),
                 "counter")
    b.add_static(box_between([0.0, -0.008, zc + L.counter_thickness], [run, 0.0, L.wall_bottom]), "backsplash")

    # room
    room_lo = np.array([x_lo - 1.6, -5.0, 0.0])
    room_hi = np.array([x_hi + 1.6, 0.0, ROOM_HEIGHT])
    th = 0.1
    b.add_static(box_between([room_lo[0] - th, room_lo[1] - th, -th], [room_hi[0] + th, th, 0.0]), "floor")
    b.add_static(box_between([room_lo[0] - th, room_lo[1] - th, ROOM_HEIGHT], [room_hi[0] + th, th, ROOM_HEIGHT + th]),
                 "ceiling")
    # back wall with a cut-out where the backsplash sits is unnecessary: the backsplash lies in front of it
    b.add_static(box_between([room_lo[0], 0.0, 0.0], [room_hi[0], th, ROOM_HEIGHT]), "wall")
    b.add_static(box_between([room_lo[0], room_lo[1] - th, 0.0], [room_hi[0], room_lo[1], ROOM_HEIGHT]), "wall")
    b.add_static(box_between([room_lo[0] - th, room_lo[1], 0.0], [room_lo[0], 0.0, ROOM_HEIGHT]), "wall")
    b.add_static(box_between([room_hi[0], room_lo[1], 0.0], [room_hi[0] + th, 0.0, ROOM_HEIGHT]), "wall")

    occupied: list[tuple[float, float, float]] = []
    for _ in range(L.microwaves):
        r_mw = 0.31  # footprint radius
        for _try in range(100):
            x = b.rng2.uniform(r_mw, run - r_mw) if run > 2 * r_mw else run / 2
            if all(abs(x - ox) > r_mw + orad + 0.03 for ox, _, orad in occupied):
                break
        else:
            continue
        yaw = b.rng2.uniform(*L.microwave_yaw_deg)
        _microwave(b, np.array([x, -D / 2 - 0.01, zc + L.counter_thickness]), yaw)
        occupied.append((x, -D / 2 - 0.01, r_mw))
    _place_objects(b, L.n_objects, 0.0, run, -D + 0.02, -0.03, zc + L.counter_thickness, occupied)

    # instance ids: articulated parts, then fixed fronts, then objects (GT instance maps use these)
    iid = 1
    for fam_group in (("drawer", "door", "flap", "sliding"), ("appliance", "false_front"), ("object",)):
        for e in b.entities:
            if e.family in fam_group:
                e.instance_id = iid
                iid += 1

    lights = []
    for k, lx in enumerate(np.linspace(x_lo + 0.3, x_hi - 0.3, 3)):
        lights.append(Light((float(lx), -1.3, 2.45), (0.0, 0.35, -1.0), 0.5, k != 1))
    pose = np.eye(4)
    if tuple(L.yaw_deg) != (0.0, 0.0):  # the kitchen turned about the vertical through the run's centre
        R = yaw_matrix(b.rng2.uniform(*L.yaw_deg))
        c = np.array([(x_lo + x_hi) / 2, 0.0, 0.0])
        pose[:3, :3], pose[:3, 3] = R, c - R @ c
        for e in [b.static] + b.entities:
            transform_entity(e, R, pose[:3, 3])
        lights = [Light(tuple((R @ np.asarray(li.pos) + pose[:3, 3]).tolist()), tuple((R @ np.asarray(li.dir)).tolist()),
                        li.diffuse, li.castshadow) for li in lights]
    return KitchenLayout([b.static] + b.entities, materials, lights, room_lo, room_hi, (x_lo, x_hi),
                         -D - tf, -L.wall_depth - tf, cfg.seed, pose)
