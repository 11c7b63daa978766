"""A part's handle as a collision primitive, and where a gripper takes hold of the part.

The handle evidence of ``articulate`` (``Part.extra["handle"]``: its place ``a_u``, ``a_v`` in
the front's unit square, ``orientation`` and ``size`` along the front's u and v, m) becomes a
box standing proud of the front: a bar along its long side, a knob as a square block. The
images give the handle's place and extent but not how far it stands out, so its depth is the
config's (``proud``: 25-40 mm is the common standoff of bar handles and knobs), or, with
``standoff: depth``, the standoff the capture's metric depth shows
(:mod:`drawer_lib.complete.standoff`; a handle found flush gets no box). A part without
handle evidence is grasped at its free edge: a door's edge opposite its hinge, a flap's edge
opposite its hinge line, a drawer's top edge, a sliding panel's trailing edge.

The grasp frame (world frame, at q = 0) is what a parallel gripper needs: ``position`` (the
point between the fingertips when closed on the handle), ``approach`` (the unit direction the
gripper moves in to reach it: into the front), ``closing_axis`` (the unit direction the fingers
close along: across the bar), ``width`` (m, the handle's extent along the closing axis, what
the fingers close on) and ``kind`` (``handle`` or ``free_edge``). A free-edge grasp has
nothing to close on: its ``width`` is 0 and its ``closing_axis`` runs along the edge (the
fingers lie along it, to hook or press). Lengths m.
"""

import math
from dataclasses import dataclass

import numpy as np

from drawer_lib.bodies import Shape, box_shape
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.geometry.boxes import front_frame
from drawer_lib.io.parts import Part


@dataclass(frozen=True)
class HandleConfig:
    """Handle primitives (``complete.handle``). ``proud`` (m): how far the handle's face stands
    in front of the front's outer face; ``thickness`` (m): a bar's extent across its length
    (and its depth: the grip); ``min_length`` / ``max_length`` (m): a bar's length is the
    evidence's extent clipped to these; ``knob`` (m): a round handle's side; ``edge_inset``
    (m): a free-edge grasp lies this far inside the edge. ``standoff``: where the handle's
    collision box stands, ``config`` (its face at ``proud``) or ``depth`` (its face at the
    standoff measured in the capture's metric depth where one was measured,
    :mod:`drawer_lib.complete.standoff`; no box where the handle is flush); the grasp frame
    stays at ``proud`` either way (where a gripper's pads close, fingertips short of the
    front). ``min_points``: depth points a measurement needs (module
    :mod:`~drawer_lib.complete.standoff`); ``max_views``: the train views it reads, evenly
    spaced (a phone's 300 frames at 1280 x 960 are 370 M points)."""

    enabled: bool = True
    proud: float = 0.035
    thickness: float = 0.014
    min_length: float = 0.04
    max_length: float = 0.6
    knob: float = 0.03
    edge_inset: float = 0.03
    standoff: str = "config"
    min_points: int = 20
    max_views: int = 60

    def __post_init__(self):
        if self.standoff not in ("config", "depth"):
            raise ConfigError(f"complete.handle.standoff = {self.standoff!r} must be config or depth")
        for k in ("min_points", "max_views"):
            v = getattr(self, k)
            if not (isinstance(v, int) and v >= 1):
                raise ConfigError(f"complete.handle.{k} = {v!r} must be an integer >= 1")
        for k in ("proud", "thickness", "min_length", "max_length", "knob", "edge_inset"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"complete.handle.{k} = {v} must be finite and > 0 (m)")
        if self.thickness >= self.proud:
            raise ConfigError(f"complete.handle: thickness {self.thickness} must be below proud {self.proud} (m)")
        if self.min_length > self.max_length:
            raise ConfigError("complete.handle: min_length must be <= max_length")


def _handle(part: Part) -> dict | None:
    h = part.extra.get("handle")
    if h is None:
        return None
    try:
        a_u, a_v = float(h["a_u"]), float(h["a_v"])
        orient = str(h["orientation"])
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(f"part {part.id!r}: handle {h!r} lacks a_u, a_v or orientation ({e})") from e
    if not (0 <= a_u <= 1 and 0 <= a_v <= 1) or orient not in ("horizontal", "vertical", "round"):
        raise InputError(f"part {part.id!r}: handle {h!r}: a_u, a_v must be in [0, 1] and orientation "
                         "horizontal, vertical or round")
    return h


def handle_box(part: Part, cfg: HandleConfig, standoff: dict | None = None) -> Shape | None:
    """The part's handle as a box (world frame, q = 0), or None without handle evidence. A bar
    along its long side (length: its evidence's extent, within ``min_length`` ..
    ``max_length`` and the front), ``thickness`` across it and deep, its face ``proud`` in
    front of the front; a knob a ``knob`` square block as deep. It lies inside the front's
    rectangle (moved in where the evidence reaches past an edge), touching nothing else. With
    ``cfg.standoff == "depth"`` and a measured ``standoff`` (a record of
    :func:`drawer_lib.complete.standoff.measure_standoffs`), its face is at the measured
    standoff above the measured front surface and it is at most that deep; None when the
    handle was found flush."""
    h = _handle(part)
    if h is None or not cfg.enabled:
        return None
    face, depth = cfg.proud, cfg.thickness
    if cfg.standoff == "depth" and standoff is not None and standoff.get("standoff_m") is not None:
        if standoff.get("flush"):
            return None
        face = float(standoff["standoff_m"]) + float(standoff.get("surface_offset_m") or 0.0)
        depth = min(cfg.thickness, float(standoff["standoff_m"]))
    f = part.front
    R = front_frame(f.normal, f.u)
    w, hgt = f.size
    size = h.get("size") or (0.0, 0.0)
    if h["orientation"] == "round":
        half_uv = np.array([cfg.knob / 2, cfg.knob / 2])
    else:
        along = 0 if h["orientation"] == "horizontal" else 1
        length = float(np.clip(float(size[along]), cfg.min_length, min(cfg.max_length, (w, hgt)[along])))
        half_uv = np.full(2, cfg.thickness / 2)
        half_uv[along] = length / 2
    half_uv = np.minimum(half_uv, np.array([w, hgt]) / 2)
    # the centre inside the rectangle: the box never reaches past the front's edges
    cu = np.clip((h["a_u"] - 0.5) * w, -w / 2 + half_uv[0], w / 2 - half_uv[0])
    cv = np.clip((h["a_v"] - 0.5) * hgt, -hgt / 2 + half_uv[1], hgt / 2 - half_uv[1])
    n_mid = face - depth / 2
    center = np.asarray(f.center) + R[:, 0] * cu + R[:, 1] * cv + R[:, 2] * n_mid
    return box_shape(center, [half_uv[0], half_uv[1], depth / 2], R)


def _free_edge(part: Part) -> tuple[float, float, int]:
    """(u, v) offsets (m, from the front's centre) of the free edge's midpoint and the in-plane
    axis (0: u, 1: v) across that edge."""
    f = part.front
    w, h = f.size
    hinge = part.extra.get("hinge")
    fam = part.extra.get("family")
    R = front_frame(f.normal, f.u)
    if part.kind == "revolute":
        # the hinge edge: the one the axis runs along (nearest the axis origin)
        o = np.asarray(part.axis.origin) - np.asarray(f.center)
        ou, ov = float(o @ R[:, 0]), float(o @ R[:, 1])
        if hinge in ("left", "right") or (hinge is None and abs(ou) / w >= abs(ov) / h):
            side = -1.0 if (hinge == "left" or (hinge is None and ou < 0)) else 1.0
            return -side * w / 2, 0.0, 0
        side = 1.0 if (hinge == "top" or (hinge is None and ov > 0)) else -1.0
        return 0.0, -side * h / 2, 1
    d = np.asarray(part.axis.direction, np.float64)
    du = float(d @ R[:, 0])
    if fam == "sliding" or abs(du) > 0.5:  # a sliding panel: its trailing edge
        return -math.copysign(w / 2, du), 0.0, 0
    return 0.0, h / 2, 1  # a drawer: its top edge


def grasp_frame(part: Part, cfg: HandleConfig) -> dict:
    """Where a parallel gripper takes hold of ``part`` (module doc): on its handle box when
    :func:`handle_box` gives one, else at its free edge, ``edge_inset`` inside it on the outer
    face. Vectors are unit, world frame, at q = 0."""
    f = part.front
    R = front_frame(f.normal, f.u)
    approach = -R[:, 2]
    box = handle_box(part, cfg)
    if box is not None:
        b = box.box
        # fingers close across the bar: along its shorter in-plane side
        across = 1 if b.half[0] >= b.half[1] else 0
        return {"kind": "handle", "position": b.center.tolist(), "approach": approach.tolist(),
                "closing_axis": R[:, across].tolist(), "width": float(2 * b.half[across])}
    eu, ev, axis = _free_edge(part)
    inset = min(cfg.edge_inset, f.size[axis] / 4)
    pos_uv = np.array([eu, ev])
    pos_uv[axis] -= math.copysign(inset, pos_uv[axis]) if pos_uv[axis] != 0 else 0.0
    pos = np.asarray(f.center) + R[:, 0] * pos_uv[0] + R[:, 1] * pos_uv[1]
    return {"kind": "free_edge", "position": pos.tolist(), "approach": approach.tolist(),
            "closing_axis": R[:, 1 - axis].tolist(), "width": 0.0}
