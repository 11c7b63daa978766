"""The type decision as a score over hypotheses, from all the evidence a front has.

Every front gets a feature vector (its handle's place and shape, its size and aspect, its
height above the floor, its neighbours, a sliding partner, the carcass behind it, label votes
and detection support; :func:`features`), and each hypothesis a linear score

    score(H) = sum_f weights[H][f] * phi_f

with ``door`` scored once per hinge side on features expressed relative to that side (the
handle's closeness to the free and to the hinge edge, a neighbour at either edge), so left and
right doors share one weight vector and mirror exactly. The front takes the hypothesis of
highest score (a multinomial logistic model: the ``fit_decisions`` stage fits the weights on
the benchmark's train split, :mod:`drawer_lib.bench.fit`; ``decisions.json`` records every
feature and score; the names: :mod:`drawer_lib.articulation.vocab`). Nothing here encodes a size of our generator: sizes enter
only as features whose weights are fitted.

| feature | meaning (all 0 without a handle for the handle terms) |
|---|---|
| bias | 1 |
| handle | a handle was found |
| h_top, h_bottom | closeness of the handle to the top / bottom edge: max(0, 1 - d / ramp), d in units of the front's height |
| h_side | closeness to the nearer side edge (same ramp, units of the width) |
| h_corner | min(h_side, max(h_top, h_bottom)): the handle sits by a corner (a door's pull at its free side, high or low) |
| h_center_u | 1 - 2 abs(a_u - 0.5): 1 when the handle is centred left-right |
| h_vertical, h_horizontal, h_round | the handle's shape |
| aspect | log(height / width), clipped to +-2 |
| width, height | the front's sides (m) |
| z_mid | the front's centre above the floor (m; the floor is a low percentile of the mesh's heights) |
| stacked | coplanar fronts sharing its top or bottom edge (0, 0.5, 1 for 0, 1, 2+) |
| beside | a coplanar front shares its left or right edge |
| partner | a neighbouring front of the same height on another track (a sliding pair) |
| rail | a track along the top or bottom edge: the unbroken length, in units of the front's width (at most 2; 0 under 0.9), of an outward-facing strip from ``joints.rail_inside`` inside that edge (where a mask that spilt onto the track puts the edge) to 6 cm beyond it, standing 0.4 .. 4 cm proud of the plane, when no deep horizontal surface (a counter) spans half of it beyond the edge (:func:`~drawer_lib.articulation.probes.rail_extent`) |
| carcass | depth of the cabinet the mesh shows behind it (m, 0 when none) |
| lab_drawer, lab_door | the fraction of the segment's label votes in drawer_labels / door_labels |
| support | log(1 + views whose detections matched the segment) / log(50) |
| tall | how far the front's height exceeds ``drawer_max_height``, in 10 cm, clipped to [0, 2]: a front taller than the deepest drawers (pan drawers stop near 0.4 m) with a pull at its top is a door or a flap (an oven, a dishwasher, a base door with a top pull) |
| bare_stack | ``stacked`` when the front has no handle, else 0: a handle-less front in a column of coplanar fronts sharing its top or bottom edge has the gap pattern of a drawer bank (push-to-open) |
| bare_lone | 1 when the front has no handle, no coplanar front shares its top or bottom edge and it is not *flanked* (the surface running on flush at both sides with gap lines along fewer than two of its sides: a patch of wall; :func:`~drawer_lib.articulation.infer.flanked`): a lone push-to-open door or flap, or a panel that does not move (the interaction test rules out what cannot swing) |
| bare_tall | min(1, ``tall``) when the front has no handle and a coplanar front shares its top or bottom edge, else 0: a push-to-open door under (or over) a drawer, which ``bare_stack`` would call a drawer were it not taller than drawers are, and ``bare_lone`` does not cover since it has a stacked neighbour (a front sharing an edge with another front is no patch of wall, so ``flanked`` does not turn it off) |
| h_free, h_hinge | (door only) the handle's closeness to the free / the hinge edge |
| beside_free, beside_hinge | (door only) a coplanar front shares the free / the hinge edge |
"""

from dataclasses import dataclass

import numpy as np

from drawer_lib.articulation.vocab import COMMON, DOOR_ONLY, HYPOTHESES, Handle

RAMP = 0.35  # handle closeness falls from 1 at an edge to 0 at this fraction of the front away


@dataclass(frozen=True, kw_only=True)
class Evidence:
    """What is known about one front besides its rectangle (built by keyword)."""

    handle: Handle | None
    size: tuple[float, float]  # (width, height) m
    z_mid: float  # centre above the floor (m)
    stacked: int  # coplanar fronts sharing its top or bottom edge
    beside_left: bool  # a coplanar front shares its left edge
    beside_right: bool
    partner: bool  # a sliding partner on another track
    rail: float  # rail_extent
    carcass: float | None  # cabinet depth behind it (m)
    labels: dict  # label votes
    support: int  # views whose detections matched the segment
    flanked: bool = False  # the surface runs on flush at both sides, hardly a gap round it (infer.flanked)
    window: float | None = None  # rectify.window_contrast: a glazed panel stands out from its frame (None: no image)


def _ramp(d: float) -> float:
    return float(np.clip(1.0 - d / RAMP, 0.0, 1.0))


TALL_STEP = 0.1  # m: the ``tall`` feature counts the height above ``drawer_max_height`` in these


def features(ev: Evidence, drawer_labels: list[str], door_labels: list[str], use_labels: bool,
             drawer_max_height: float = 0.45) -> dict[str, float]:
    """The common features (:data:`COMMON`) of a front; ``drawer_max_height`` (m) starts the
    ``tall`` feature."""
    w, h = ev.size
    f = dict.fromkeys(COMMON, 0.0)
    f["bias"] = 1.0
    hd = ev.handle
    if hd is not None:
        f["handle"] = 1.0
        f["h_top"], f["h_bottom"] = _ramp(1.0 - hd.a_v), _ramp(hd.a_v)
        f["h_side"] = max(_ramp(hd.a_u), _ramp(1.0 - hd.a_u))
        f["h_corner"] = min(f["h_side"], max(f["h_top"], f["h_bottom"]))
        f["h_center_u"] = 1.0 - 2.0 * abs(hd.a_u - 0.5)
        f[f"h_{hd.orientation}"] = 1.0
    f["aspect"] = float(np.clip(np.log(max(h, 1e-3) / max(w, 1e-3)), -2.0, 2.0))
    f["width"], f["height"] = float(w), float(h)
    f["z_mid"] = float(np.clip(ev.z_mid, 0.0, 3.0))
    f["stacked"] = min(ev.stacked, 2) / 2.0
    f["beside"] = float(ev.beside_left or ev.beside_right)
    f["partner"] = float(ev.partner)
    f["rail"] = float(np.clip(ev.rail, 0.0, 2.0))
    f["carcass"] = float(ev.carcass or 0.0)
    votes = sum(ev.labels.values()) if ev.labels else 0
    if use_labels and votes > 0:
        f["lab_drawer"] = sum(v for k, v in ev.labels.items() if k in drawer_labels) / votes
        f["lab_door"] = sum(v for k, v in ev.labels.items() if k in door_labels) / votes
    f["support"] = float(np.clip(np.log1p(ev.support) / np.log(50.0), 0.0, 1.5))
    f["tall"] = float(np.clip((h - drawer_max_height) / TALL_STEP, 0.0, 2.0))
    f["bare_stack"] = f["stacked"] if hd is None else 0.0
    f["bare_lone"] = 1.0 if hd is None and ev.stacked == 0 and not ev.flanked else 0.0
    f["bare_tall"] = min(1.0, f["tall"]) if hd is None and ev.stacked > 0 else 0.0
    return f


def door_features(ev: Evidence, hinge: str) -> dict[str, float]:
    """The features of the door hypothesis hinged at ``hinge`` (left | right)."""
    hd = ev.handle
    f = dict.fromkeys(DOOR_ONLY, 0.0)
    if hd is not None:
        to_left, to_right = hd.a_u, 1.0 - hd.a_u
        f["h_free"] = _ramp(to_right if hinge == "left" else to_left)
        f["h_hinge"] = _ramp(to_left if hinge == "left" else to_right)
    f["beside_hinge"] = float(ev.beside_left if hinge == "left" else ev.beside_right)
    f["beside_free"] = float(ev.beside_right if hinge == "left" else ev.beside_left)
    return f


def score(common: dict[str, float], door: dict[str, dict[str, float]], weights: dict[str, dict[str, float]]
          ) -> dict[str, float]:
    """The score of every hypothesis (:data:`HYPOTHESES`). ``door``: {left|right: door features}."""

    def dot(ws: dict[str, float], *fs: dict[str, float]) -> float:
        return float(sum(ws.get(k, 0.0) * v for f in fs for k, v in f.items()))

    out = {}
    for hyp in HYPOTHESES:
        if hyp.startswith("door_"):
            out[hyp] = dot(weights["door"], common, door[hyp[5:]])
        else:
            out[hyp] = dot(weights[hyp], common)
    return out
