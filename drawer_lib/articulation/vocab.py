"""The articulation vocabulary: the type hypotheses, the features the score rule weighs, the
hand-set prior weights, and the small records that pass between the steps (a front's
:class:`Handle`, a :class:`Decision`). A leaf of the package: the config, the handles, the
decision rules and the benchmark's fit of the weights all import it, and it imports nothing of
theirs.

A front is typed by the hypothesis of highest score (:mod:`drawer_lib.articulation.decide`);
a door is scored once per hinge side, so ``door_left`` and ``door_right`` share the weight set
``door``. Features: :mod:`drawer_lib.articulation.scoring` (their table).
"""

import math
from dataclasses import dataclass

from drawer_lib.errors import ConfigError

HYPOTHESES = ("drawer", "door_left", "door_right", "flap_top", "flap_bottom", "sliding", "fixed")
WEIGHT_SETS = ("drawer", "door", "flap_top", "flap_bottom", "sliding", "fixed")
COMMON = ("bias", "handle", "h_top", "h_bottom", "h_side", "h_corner", "h_center_u", "h_vertical", "h_horizontal",
          "h_round", "aspect", "width", "height", "z_mid", "stacked", "beside", "partner", "rail", "carcass",
          "lab_drawer", "lab_door", "support", "tall", "bare_stack", "bare_lone", "bare_tall")
DOOR_ONLY = ("h_free", "h_hinge", "beside_free", "beside_hinge")
LABEL_FEATURES = ("lab_drawer", "lab_door")  # set by hand: generic detections carry no label to fit them on


def weight_set(hypothesis: str) -> str:
    """The weight set that scores ``hypothesis`` (``door_left`` -> ``door``)."""
    if hypothesis not in HYPOTHESES:
        raise ValueError(f"unknown hypothesis {hypothesis!r} (known: {HYPOTHESES})")
    return "door" if hypothesis.startswith("door_") else hypothesis


def set_features(weight_set_name: str) -> tuple[str, ...]:
    """The features a weight set weighs (``door``: the common ones and the door-only ones)."""
    return COMMON + (DOOR_ONLY if weight_set_name == "door" else ())


def prior_weights() -> dict[str, dict[str, float]]:
    """Hand-set weights that reproduce the handle rule on clear cases: the ``prior`` of
    ``articulate.types``, the fixed label weights of the fit, and the weights of a hypothesis
    the train split has too few examples of."""
    return {
        "drawer": {"handle": 1.0, "h_top": 1.0, "h_center_u": 1.0, "h_horizontal": 0.5, "lab_drawer": 2.0,
                   "tall": -3.0, "bare_stack": 2.0},
        "door": {"handle": 1.0, "h_free": 2.5, "h_vertical": 0.5, "lab_door": 1.0, "bare_lone": 1.0,
                 "bare_tall": 1.0},
        "flap_top": {"handle": 1.0, "h_bottom": 2.0, "h_center_u": 0.5},
        "flap_bottom": {"handle": 1.0, "h_top": 1.0, "lab_door": 1.5},
        "sliding": {"partner": 5.0, "rail": 3.0},
        "fixed": {"bias": 0.5},
    }


def check_weights(weights: dict[str, dict[str, float]], where: str = "articulate.types.prior") -> None:
    """Every weight set named, every feature known, every weight a finite number; ``where``
    names the config key or file in the error."""
    if not isinstance(weights, dict):
        raise ConfigError(f"{where}: must be a mapping {{hypothesis: {{feature: weight}}}}")
    for k, ws in weights.items():
        if k not in WEIGHT_SETS:
            raise ConfigError(f"{where}: unknown hypothesis {k!r} (known: {WEIGHT_SETS})")
        if not isinstance(ws, dict):
            raise ConfigError(f"{where}.{k}: must be a mapping {{feature: weight}}")
        known = set_features(k)
        for f, v in ws.items():
            if f not in known:
                raise ConfigError(f"{where}.{k}: unknown feature {f!r} (known: {known})")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"{where}.{k}.{f} = {v!r} is not a finite number")
    missing = [k for k in WEIGHT_SETS if k not in weights]
    if missing:
        raise ConfigError(f"{where}: missing hypotheses {missing}")


@dataclass(frozen=True)
class Handle:
    """A front's handle: its centroid in the front's unit square (``a_u`` left -> right,
    ``a_v`` bottom -> top), ``orientation`` (horizontal | vertical | round), the ``n_points``
    of evidence, its ``source`` (images | masks | colour | geometry) and ``size``: its extents
    along the front's u and v (m; the 5-95 percentile ranges of its evidence)."""

    a_u: float
    a_v: float
    orientation: str
    n_points: int
    source: str
    size: tuple[float, float] | None = None


@dataclass(frozen=True)
class Decision:
    """A front's type: ``family`` (drawer | door | flap | sliding | fixed), the ``hinge`` edge of
    a revolute one (left | right | top | bottom), the ``reason`` for ``decisions.json`` and, from
    the score rule, the ``margin`` over the runner-up (log-odds) and the ``confidence`` (the
    chosen hypothesis' probability); None from a rule without scores."""

    family: str
    hinge: str | None = None
    reason: str = ""
    margin: float | None = None
    confidence: float | None = None
