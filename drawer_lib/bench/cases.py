"""Hand-built hard cases of the type decision: small analytic scenes of fronts that our
procedural kitchens rarely or never make, each with what a correct articulation must say.
The ``fit_decisions`` stage runs them with the weights it fitted and records which pass
(``fit/cases.json``): a regression check of the learned decision on kitchens the generator did
not make, never a target it is tuned on.

A scene: a floor and a back wall, fronts (panels 19 mm thick, outer face at ``y``, facing -y,
each one planar segment as decompose would give it, seen in 40 views under generic labels),
handles (bars or knobs standing 2.3-3.5 cm proud) and static boxes; the whole optionally
turned about the vertical.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.infer import infer_parts
from drawer_lib.io.parts import Part
from drawer_lib.perception.decompose import Segment, face_geometry

GENERIC = {"front": 30}
_CAMERAS = np.array([[0.3, -2.5, 1.2], [-0.6, -2.2, 1.5], [1.2, -2.4, 0.9]])


def box(lo, hi, subdivide: int = 0) -> trimesh.Trimesh:
    """An axis-aligned box mesh from corner ``lo`` to ``hi`` (m), its faces split ``subdivide`` times."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))
    for _ in range(subdivide):
        m = m.subdivide()
    return m


def handle_box(x: float, z: float, y: float, kind: str, length: float = 0.16) -> trimesh.Trimesh:
    """A bar (``h`` | ``v``, 2 cm thick) or a ``knob`` centred at (x, z), standing 2.3-3.5 cm
    proud of a front whose outer face is at ``y``."""
    half = {"h": (length / 2, 0.01), "v": (0.01, length / 2), "knob": (0.012, 0.012)}[kind]
    return box([x - half[0], y - 0.035, z - half[1]], [x + half[0], y - 0.023, z + half[1]], 2)


class Scene:
    """Fronts in front of a floor and a wall, plus static boxes (see the module docstring)."""

    def __init__(self):
        self.meshes = [box([-1.5, -3.0, -0.02], [2.5, 0.02, 0.0]), box([-1.5, 0.0, 0.0], [2.5, 0.02, 2.5])]
        self.fronts: list[int] = []  # index of each front's panel in meshes

    def front(self, x0: float, x1: float, z0: float, z1: float, y: float, handle: tuple | None = None) -> "Scene":
        """A panel over x0..x1, z0..z1 with its outer face at ``y``; ``handle``: (x, z, kind[, length])."""
        self.fronts.append(len(self.meshes))
        self.meshes.append(box([x0, y, z0], [x1, y + 0.019, z1], 3))
        if handle is not None:
            self.meshes.append(handle_box(*handle[:2], y, *handle[2:]))
        return self

    def static(self, lo, hi) -> "Scene":
        self.meshes.append(box(lo, hi, 2))
        return self

    def run(self, cfg: ArticulateConfig, weights: dict[str, dict[str, float]], labels: dict = GENERIC,
            support: int = 40, yaw_deg: float = 0.0) -> tuple[list[Part | None], list[dict], np.ndarray]:
        """(the part of each front or None, the decisions, the scene's rotation [3, 3])."""
        R = trimesh.transformations.rotation_matrix(np.deg2rad(yaw_deg), [0, 0, 1])
        offs = np.cumsum([0] + [len(m.faces) for m in self.meshes])
        mesh = trimesh.util.concatenate(self.meshes)
        mesh.apply_transform(R)
        n = np.asarray(mesh.face_normals)
        out = R[:3, :3] @ np.array([0.0, -1.0, 0.0])
        segs = []
        for k, mi in enumerate(self.fronts):
            f = np.arange(offs[mi], offs[mi + 1])
            f = f[n[f] @ out > 0.99]  # the panel's outer face
            nrm, area, cen, frac = face_geometry(mesh, f, 30.0)
            segs.append(Segment(k, f, 1.0, support, dict(labels), frac > 0.6, nrm, area, cen))
        cams = (R[:3, :3] @ _CAMERAS.T).T
        parts, rep = infer_parts(mesh, segs, cams, cfg, weights=weights)
        by_seg = {p.extra["segment"]: p for p in parts}
        return [by_seg.get(k) for k in range(len(self.fronts))], rep, R[:3, :3]


def _revolute(p: Part | None, hinge: str) -> bool:
    return p is not None and p.kind == "revolute" and p.extra.get("hinge") == hinge


def _family(p: Part | None, family: str) -> bool:
    return p is not None and p.extra.get("family") == family


def full_height_door(cfg, w) -> bool:
    """A fridge / pantry door 2.0 m high is a door hinged at its far edge, not dropped for its size."""
    (p,), _, _ = Scene().front(0.0, 0.6, 0.1, 2.1, -0.6, (0.555, 1.1, "v", 0.6)).run(cfg, w)
    return (_revolute(p, "left") and np.allclose(p.front.size, (0.6, 2.0), atol=0.03)
            and np.allclose(p.axis.direction, [0, 0, -1], atol=1e-3))


def oven_door_top_bar(cfg, w) -> bool:
    """An oven door with a bar near its top edge, under generic labels, is a bottom-hinged flap;
    the storage drawer below it stays a drawer."""
    s = Scene().front(0.0, 0.6, 0.1, 0.24, -0.6, (0.3, 0.19, "h", 0.3))
    s.front(0.0, 0.6, 0.243, 0.8, -0.6, (0.3, 0.745, "h", 0.3)).static([0.0, -0.6, 0.803], [0.6, -0.581, 0.9])
    (drawer, oven), _, _ = s.run(cfg, w)
    return (_family(drawer, "drawer") and _revolute(oven, "bottom")
            and np.allclose(oven.axis.origin, [0.3, -0.6, 0.243], atol=0.02))


def single_sliding_door(rail_proud: float = 0.012) -> Scene:
    """A wall cabinet 0.9 m wide with a shelf, its left half closed by one sliding door (outer
    face at y = -0.39, a vertical pull at its left edge) on a track along its top that stands
    ``rail_proud`` (m) proud of the door."""
    s = Scene()
    s.static([0.0, -0.35, 1.45], [0.018, 0.0, 2.15]).static([0.882, -0.35, 1.45], [0.9, 0.0, 2.15])
    s.static([0.0, -0.35, 1.45], [0.9, 0.0, 1.468]).static([0.0, -0.35, 1.78], [0.9, -0.008, 1.798])
    s.static([0.0, -0.39 - rail_proud, 2.12], [0.9, -0.35, 2.15])  # the rail, the cabinet's full width
    return s.front(0.0015, 0.46, 1.4515, 2.117, -0.39, (0.045, 1.78, "v", 0.13))


def sliding_without_partner(cfg, w) -> bool:
    """A sliding door on its own track in front of a wall cabinet slides over the open shelf."""
    (p,), _, _ = single_sliding_door().run(cfg, w)
    return _family(p, "sliding") and np.allclose(p.axis.direction, [1, 0, 0], atol=1e-3) and 0.3 < p.limits[1] < 0.5


def knobless_drawer_stack(cfg, w) -> bool:
    """A stack of three drawers whose knobs the mesh does not show are still drawers."""
    s = Scene()
    for z0, z1 in ((0.1, 0.33), (0.333, 0.56), (0.563, 0.79)):
        s.front(0.0, 0.5, z0, z1, -0.6)
    parts, _, _ = s.run(cfg, w)
    return all(_family(p, "drawer") for p in parts)


def push_to_open_door(cfg, w) -> bool:
    """A lone wall door without a handle (push-to-open) is a revolute part, not a fixed panel."""
    (p,), _, _ = Scene().static([0.0, -0.35, 1.43], [0.45, 0.0, 1.45]).front(0.0, 0.45, 1.45, 2.15, -0.35).run(cfg, w)
    return p is not None and p.kind == "revolute"


def push_to_open_door_under_drawer(cfg, w) -> bool:
    """A base unit's door without a handle under a drawer with one is a revolute part: in a
    stack a front without a handle reads as a push-to-open drawer, but at 0.6 m it is taller
    than drawers are, so neither a drawer nor a fixed panel."""
    s = Scene().front(0.0, 0.6, 0.1, 0.7, -0.6).front(0.0, 0.6, 0.703, 0.86, -0.6, (0.3, 0.8, "h", 0.3))
    (door, drawer), _, _ = s.run(cfg, w)
    return door is not None and door.kind == "revolute" and _family(drawer, "drawer")


def shallow_drawer_off_centre_knob(cfg, w) -> bool:
    """A drawer 15 cm tall whose knob was found by a side edge (a neighbour's, or a knot in the
    wood read as one) is still a drawer: a side-hinged door or a top-hinged flap that shallow
    has no room for its hinges."""
    (p,), _, _ = Scene().front(0.0, 0.6, 0.7, 0.85, -0.6, (0.55, 0.8, "knob")).run(cfg, w)
    return _family(p, "drawer")


def microwave_door(yaw: float) -> Callable:
    def case(cfg, w) -> bool:
        s = Scene().static([0.0, -0.5, 0.9], [0.5, -0.14, 1.19]).static([-0.3, -0.62, 0.86], [1.0, 0.0, 0.9])
        (p,), _, R = s.front(0.008, 0.365, 0.915, 1.175, -0.52, (0.33, 1.045, "v", 0.18)).run(cfg, w, yaw_deg=yaw)
        return (_revolute(p, "left") and np.allclose(p.axis.direction, [0, 0, -1], atol=1e-3)
                and np.allclose(p.axis.origin, R @ np.array([0.008, -0.52, 1.045]), atol=0.02)
                and np.allclose(p.front.normal, R @ np.array([0, -1.0, 0]), atol=1e-3))

    case.__doc__ = f"A microwave door on the counter, the kitchen turned by {yaw:g} deg, is hinged at its left edge."
    return case


def mirrored_wall_doors(cfg, w) -> bool:
    """Two wall doors side by side with pulls at their outer edges hinge where they meet."""
    s = Scene().front(0.0, 0.448, 1.45, 2.15, -0.35, (0.045, 1.55, "v", 0.13))
    (a, b), _, _ = s.front(0.452, 0.9, 1.45, 2.15, -0.35, (0.855, 1.55, "v", 0.13)).run(cfg, w)
    return _revolute(a, "right") and _revolute(b, "left")


def wall_door_bottom_corner_bar(cfg, w) -> bool:
    """A tall wall door with a horizontal bar a quarter of the way along its bottom edge is a
    door, not a top-hinged flap."""
    (p,), _, _ = Scene().front(0.0, 0.45, 1.45, 2.15, -0.35, (0.11, 1.5, "h", 0.13)).run(cfg, w)
    return _revolute(p, "right")


@dataclass(frozen=True)
class Case:
    name: str
    check: Callable[[ArticulateConfig, dict], bool]

    @property
    def doc(self) -> str:
        return " ".join((self.check.__doc__ or "").split())


CASES = (Case("full_height_door", full_height_door), Case("oven_door_top_bar", oven_door_top_bar),
         Case("sliding_without_partner", sliding_without_partner), Case("knobless_drawer_stack", knobless_drawer_stack),
         Case("push_to_open_door", push_to_open_door),
         Case("push_to_open_door_under_drawer", push_to_open_door_under_drawer),
         Case("shallow_drawer_off_centre_knob", shallow_drawer_off_centre_knob),
         *(Case(f"microwave_door_yaw_{y:g}", microwave_door(y)) for y in (0.0, 30.0, -40.0)),
         Case("mirrored_wall_doors", mirrored_wall_doors),
         Case("wall_door_bottom_corner_bar", wall_door_bottom_corner_bar))


def run_cases(cfg: ArticulateConfig, weights: dict[str, dict[str, float]]) -> list[dict]:
    """[{name, what, passed}] of every case with ``weights``."""
    return [{"name": c.name, "what": c.doc, "passed": bool(c.check(cfg, weights))} for c in CASES]
