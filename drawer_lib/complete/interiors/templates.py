"""Interior templates behind an articulated front (the table of :mod:`drawer_lib.complete.interiors`):
which template a part gets, its boxes at a given depth, and the :class:`Interior` record.

Frame: a part's template lives in its front's frame, origin at the centre of the front's outer
face, coordinates (a, b, z) along (u, v, -normal): z is the distance behind the outer face. A
template occupies z in [start, start + depth]; its *free depth* = start - front thickness +
depth - wall = from the front's inner face to the back wall's inner face. Shapes are
world-frame boxes at q = 0 (all closed) with proper rotations [u, v, normal].
"""

from dataclasses import dataclass, field

import numpy as np
from jaxtyping import Float

from drawer_lib.bodies import Shape
from drawer_lib.complete.interiors.config import TemplateConfig
from drawer_lib.errors import NonFiniteError
from drawer_lib.geometry.boxes import OrientedBox, front_frame
from drawer_lib.io.parts import Front, Part

TEMPLATES = ("drawer", "cabinet", "appliance")
MIN_HALF = 5e-4  # no box is thinner than 1 mm


def check_part(part: Part) -> None:
    """Raise :class:`NonFiniteError` naming the part when its front, axis or limits hold NaN or
    inf, and ValueError when it is not an articulated part with a front."""
    if not part.articulated or part.front is None:
        raise ValueError(f"part {part.id}: interiors need an articulated part with a front (kind {part.kind!r})")
    f = part.front
    for name, val in (("front.center", f.center), ("front.normal", f.normal), ("front.u", f.u),
                      ("front.size", f.size), ("axis.origin", part.axis.origin if part.axis else ()),
                      ("axis.direction", part.axis.direction if part.axis else ()), ("limits", part.limits or ())):
        a = np.asarray(val, np.float64)
        if not np.all(np.isfinite(a)):
            raise NonFiniteError(f"part {part.id}: {name} = {list(a)} is not finite")
    if min(f.size) <= 0:
        raise ValueError(f"part {part.id}: front.size = {list(f.size)} must be positive")


def local_box(origin: Float[np.ndarray, "3"], R: Float[np.ndarray, "3 3"], lo, hi) -> OrientedBox:
    """The box [lo, hi] in front coordinates (a, b, z = depth behind the outer face)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    mid = (lo + hi) / 2
    half = np.maximum((hi - lo) / 2, MIN_HALF)
    return OrientedBox(origin + R @ np.array([mid[0], mid[1], -mid[2]]), R, half)


def template_kind(part: Part, floor_z: float | None, cfg: TemplateConfig) -> tuple[str, str]:
    """(template, reason): ``drawer`` | ``cabinet`` | ``appliance`` (table in the module doc)."""
    f = part.front
    n, u = np.asarray(f.normal), np.asarray(f.u)
    d = np.asarray(part.axis.direction)
    if part.kind == "prismatic":
        if d @ n >= cfg.drawer_normal_cos:
            return "drawer", "prismatic along the outward normal"
        return "cabinet", "sliding door: a shallow cabinet behind its track"
    horizontal = abs(d @ u) > 0.7
    below = (np.asarray(part.axis.origin) - np.asarray(f.center)) @ f.v < 0
    if horizontal and below:
        bottom_z = float(f.corners()[:, 2].min())
        if floor_z is not None and bottom_z - floor_z <= cfg.appliance_max_bottom:
            return "appliance", f"bottom-hinged, lower edge {bottom_z - floor_z:.2f} m above the floor: oven-like"
        return "cabinet", "bottom-hinged flap above the floor"
    return "cabinet", "hinged door or flap"


def travel(part: Part) -> float:
    """How far a drawer's front moves inward-outward at its upper limit (m); 0 for others."""
    if part.kind != "prismatic":
        return 0.0
    return float(max(part.limits[1], 0.0) * max(np.asarray(part.axis.direction) @ np.asarray(part.front.normal), 0.0))


@dataclass(frozen=True)
class Interior:
    """One part's interior. ``walls`` (world boxes at q = 0) with ``wall_names``; ``body``: the
    part's id (a drawer box moves with it) or "static"; ``free``: the empty inside; ``outer``:
    the template's whole extent (what to carve out of the static collision); ``occupied``: the
    outer box swept over the part's travel (drawer) — what neighbours must not enter."""

    part_id: str
    template: str
    body: str
    walls: list[Shape]
    wall_names: list[str]
    free: OrientedBox
    outer: OrientedBox
    occupied: OrientedBox
    start: float
    depth: float
    wall: float
    front_thickness: float
    shelves: int
    record: dict = field(default_factory=dict)

    @property
    def free_depth(self) -> float:
        """From the front's inner face to the back wall's inner face (m)."""
        return float(self.start - self.front_thickness + self.depth - self.wall)

    def to_json(self) -> dict:
        return {"part": self.part_id, "template": self.template, "body": self.body, "start": self.start,
                "depth": self.depth, "free_depth": self.free_depth, "wall": self.wall, "shelves": self.shelves,
                "walls": [{"name": nm, **s.box.to_json()} for nm, s in zip(self.wall_names, self.walls)],
                "free": self.free.to_json(), "outer": self.outer.to_json(), **self.record}


Footprint = tuple[float, float, float, float]  # (a0, a1, b0, b1) in the front's (u, v) coordinates


def full_footprint(front: Front) -> Footprint:
    w, h = front.size
    return (-w / 2, w / 2, -h / 2, h / 2)


def _inset(lo: float, hi: float, a: float, b: float, frac: float) -> tuple[float, float]:
    ext = hi - lo
    return lo + min(a, frac * ext), hi - min(b, frac * ext)


def template_footprint(template: str, fp: Footprint, cfg: TemplateConfig) -> Footprint:
    """The template's outer extent in the front's (u, v): a drawer box inset in the opening,
    a cavity inset by ``cavity_inset``."""
    a0, a1, b0, b1 = fp
    if template == "drawer":
        a0, a1 = _inset(a0, a1, cfg.drawer_side, cfg.drawer_side, cfg.max_inset_frac)
        b0, b1 = _inset(b0, b1, cfg.drawer_bottom, cfg.drawer_top, cfg.max_inset_frac)
    else:
        a0, a1 = _inset(a0, a1, cfg.cavity_inset, cfg.cavity_inset, cfg.max_inset_frac)
        b0, b1 = _inset(b0, b1, cfg.cavity_inset, cfg.cavity_inset, cfg.max_inset_frac)
    return a0, a1, b0, b1


def occupied_box(part: Part, template: str, start: float, depth: float, fp: Footprint, cfg: TemplateConfig
                 ) -> OrientedBox:
    """The space a template takes: its outer box, for a drawer swept over its travel."""
    o, R = np.asarray(part.front.center, np.float64), front_frame(part.front.normal, part.front.u)
    a0, a1, b0, b1 = template_footprint(template, fp, cfg)
    tr = travel(part) if template == "drawer" else 0.0
    return local_box(o, R, (a0, b0, start - tr), (a1, b1, start + depth))


def build_template(part: Part, template: str, start: float, depth: float, cfg: TemplateConfig,
                   footprint: Footprint | None = None, wall: float | None = None, shelves: bool = True) -> Interior:
    """The boxes of ``template`` behind ``part``'s front, occupying z in [start, start + depth]
    within ``footprint`` (default: the whole front). ``wall`` overrides ``cfg.wall``;
    ``shelves=False`` leaves a cabinet empty (DRAWER's 1 x 1 grid)."""
    if template not in TEMPLATES:
        raise ValueError(f"part {part.id}: unknown template {template!r} (known: {TEMPLATES})")
    if not (np.isfinite(start) and np.isfinite(depth)) or depth <= 0:
        raise NonFiniteError(f"part {part.id}: template depth {depth} / start {start} must be finite and > 0")
    o, R = np.asarray(part.front.center, np.float64), front_frame(part.front.normal, part.front.u)
    fp = footprint if footprint is not None else full_footprint(part.front)
    a0, a1, b0, b1 = template_footprint(template, fp, cfg)
    wall = cfg.wall if wall is None else wall
    z0, z1 = float(start), float(start + depth)
    boxes: list[tuple[str, tuple, tuple]] = []
    if template == "drawer":
        t = min(wall, cfg.max_wall_frac * min(a1 - a0, b1 - b0, depth))
        boxes += [("bottom", (a0, b0, z0), (a1, b0 + t, z1)),
                  ("front", (a0, b0 + t, z0), (a1, b1, z0 + t)),
                  ("back", (a0, b0 + t, z1 - t), (a1, b1, z1)),
                  ("left", (a0, b0 + t, z0 + t), (a0 + t, b1, z1 - t)),
                  ("right", (a1 - t, b0 + t, z0 + t), (a1, b1, z1 - t))]
        free = local_box(o, R, (a0 + t, b0 + t, z0 + t), (a1 - t, b1, z1 - t))
        n_shelves = 0
        body = part.id
    else:
        t = min(wall, cfg.max_wall_frac * min(a1 - a0, b1 - b0, depth))
        zc = min(z0 + cfg.cavity_clearance, z1 - t - 1e-4)  # the sides start clear of the panel
        boxes += [("back", (a0, b0, z1 - t), (a1, b1, z1)),
                  ("left", (a0, b0, zc), (a0 + t, b1, z1 - t)),
                  ("right", (a1 - t, b0, zc), (a1, b1, z1 - t)),
                  ("bottom", (a0 + t, b0, zc), (a1 - t, b0 + t, z1 - t)),
                  ("top", (a0 + t, b1 - t, zc), (a1 - t, b1, z1 - t))]
        inner_h = (b1 - b0) - 2 * t
        n_shelves = 0
        if template == "cabinet" and shelves and z0 + cfg.shelf_setback < z1 - t:
            n_shelves = max(0, int(round(inner_h / cfg.shelf_spacing)) - 1)
            for k in range(1, n_shelves + 1):
                bk = b0 + t + k * inner_h / (n_shelves + 1)
                boxes.append((f"shelf_{k}", (a0 + t, bk - t / 2, z0 + cfg.shelf_setback), (a1 - t, bk + t / 2, z1 - t)))
        free = local_box(o, R, (a0 + t, b0 + t, z0), (a1 - t, b1 - t, z1 - t))
        body = "static"
    occupied = occupied_box(part, template, z0, float(depth), fp, cfg)
    outer = local_box(o, R, (a0, b0, z0), (a1, b1, z1))
    walls = [local_box(o, R, lo, hi) for _, lo, hi in boxes]
    for nm, bx in zip([b[0] for b in boxes], walls):
        if not (np.all(np.isfinite(bx.center)) and np.all(bx.half > 0)):
            raise NonFiniteError(f"part {part.id}: wall {nm} is not a valid box ({bx.center}, {bx.half})")
    return Interior(part.id, template, body, [Shape("box", box=w) for w in walls], [b[0] for b in boxes], free, outer,
                    occupied, z0, float(depth), float(t), cfg.front_thickness, n_shelves)
