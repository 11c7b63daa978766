"""The type decision of a front: which of the hypotheses (:data:`~drawer_lib.articulation.vocab.HYPOTHESES`)
it is.

``articulate.types.rule: score`` (default, :func:`decide_by_score`): the hypothesis of highest
linear score over all the front's evidence (:mod:`drawer_lib.articulation.scoring`), with the
fitted or the prior weights. ``rule: handle`` (:func:`decide_by_handle`): DRAWER's rule on the
3DOI affordance peak (``sdf/scripts/fit_doors.py`` in its official code), with the handle in
place of the peak:

| evidence | type |
|---|---|
| handle near the left / right edge (a_u < f or > 1 - f; a horizontal one within f / 2) | door hinged on the far side |
| handle near the bottom edge | flap hinged at the top |
| handle near the top edge | drawer, or a flap hinged at the bottom when the labels say door |
| handle central | drawer |
| a neighbouring front of the same height on another track (a depth step) | sliding door (toward it) |
| no handle | not articulated (a fixed panel) |
"""

from drawer_lib.articulation.config import TypesConfig
from drawer_lib.articulation.scoring import Evidence, door_features, features, score
from drawer_lib.articulation.vocab import HYPOTHESES, Decision, Handle


def decide_by_handle(h: Handle | None, labels: dict, cfg: TypesConfig) -> Decision:
    """The type from the handle position (and, for the one ambiguous case, the label votes)."""
    if h is None:
        return Decision("fixed", reason="no handle")
    f = cfg.edge_frac
    side = h.a_u < f or h.a_u > 1 - f
    if side and (h.orientation != "horizontal" or h.a_u < f / 2 or h.a_u > 1 - f / 2):
        # doors carry their handle at the free side (a horizontal bar only right at the edge)
        return Decision("door", "right" if h.a_u < 0.5 else "left", "handle near a side edge")
    if h.a_v < f:
        return Decision("flap", "top", "handle near the bottom edge")
    if h.a_v > 1 - f:
        if cfg.use_labels:
            door_votes = sum(v for k, v in labels.items() if k in cfg.door_labels)
            drawer_votes = sum(v for k, v in labels.items() if k in cfg.drawer_labels)
            if door_votes > drawer_votes:
                return Decision("flap", "bottom", "handle near the top edge; labels say door")
        return Decision("drawer", reason="handle near the top edge")
    if side:  # a horizontal bar near a side, halfway up: still a side-hinged door
        return Decision("door", "right" if h.a_u < 0.5 else "left", "handle near a side edge")
    return Decision("drawer", reason="central handle")


def decide_by_score(ev: Evidence, cfg: TypesConfig, weights: dict[str, dict[str, float]]) -> tuple[Decision, dict]:
    """The hypothesis of highest score (:mod:`drawer_lib.articulation.scoring`) and the terms
    for ``decisions.json`` (features, door features per hinge side, scores)."""
    common = features(ev, cfg.drawer_labels, cfg.door_labels, cfg.use_labels)
    door = {side: door_features(ev, side) for side in ("left", "right")}
    scores = score(common, door, weights)
    best = max(scores, key=lambda k: (scores[k], -HYPOTHESES.index(k)))
    runner_up = max((v for k, v in scores.items() if k != best), default=float("-inf"))
    fam, _, hinge = best.partition("_")
    dec = Decision(fam, hinge or None, f"score {scores[best]:.2f} (next best {runner_up:.2f})")
    r4 = lambda d: {k: round(float(v), 4) for k, v in d.items()}  # noqa: E731
    return dec, {"features": r4(common), "door_features": {k: r4(v) for k, v in door.items()}, "scores": r4(scores)}
