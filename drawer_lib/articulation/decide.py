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

import dataclasses

import numpy as np

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


def decide_by_score(ev: Evidence, cfg: TypesConfig, weights: dict[str, dict[str, float]],
                    blocked: dict[str, str] | None = None) -> tuple[Decision, dict]:
    """The hypothesis of highest score (:mod:`drawer_lib.articulation.scoring`) and the terms
    for ``decisions.json`` (features, door features per hinge side, scores, the runner-up, the
    margin and the confidence over the hypotheses its evidence allows: :func:`margin_confidence`,
    :func:`missing_evidence`, :func:`glazed`; ``excluded``: the others and why; ``glazed_near``:
    :func:`glazed_near`). ``blocked``: hypotheses the
    interaction test rules out ({hypothesis: why};
    :func:`~drawer_lib.articulation.interaction.blocked_hypotheses`); ``fixed`` stays whenever
    everything else is excluded."""
    common = features(ev, cfg.drawer_labels, cfg.door_labels, cfg.use_labels, cfg.drawer_max_height)
    door = {side: door_features(ev, side) for side in ("left", "right")}
    all_scores = score(common, door, weights)
    unseen = (missing_evidence(common, cfg) | glazed(ev, cfg, common["z_mid"])
              | {k: v for k, v in (blocked or {}).items() if k != "fixed"})
    if set(all_scores) <= set(unseen):  # nothing left: a glazed front that cannot swing is a fixed panel
        unseen.pop("fixed", None)
    scores = {k: v for k, v in all_scores.items() if k not in unseen}
    best = max(scores, key=lambda k: (scores[k], -HYPOTHESES.index(k)))
    runner_up, margin, conf = margin_confidence(scores, best)
    fam, _, hinge = best.partition("_")
    if runner_up == best:  # the evidence allows nothing else: no margin to speak of
        dec = Decision(fam, hinge or None, f"score {scores[best]:.2f} (every other hypothesis excluded)",
                       confidence=conf)
        runner_up, margin_json = None, None
    else:
        dec = Decision(fam, hinge or None, f"score {scores[best]:.2f} (next best {runner_up} {scores[runner_up]:.2f})",
                       margin=margin, confidence=conf)
        margin_json = round(margin, 4)
    r4 = lambda d: {k: round(float(v), 4) for k, v in d.items()}  # noqa: E731
    return dec, {"features": r4(common), "door_features": {k: r4(v) for k, v in door.items()},
                 "scores": r4(all_scores), "excluded": unseen, "runner_up": runner_up, "margin": margin_json,
                 "confidence": round(conf, 4), "glazed_near": glazed_near(ev, cfg, common["z_mid"])}


def missing_evidence(common: dict[str, float], cfg: TypesConfig) -> dict[str, str]:
    """The hypotheses whose defining evidence the front lacks, with why: with
    ``cfg.sliding_needs_track``, a sliding door needs a partner panel on another track or a
    track along its top or bottom edge (a high front with side neighbours is not one); a front
    shorter than ``cfg.hinged_min_height`` is neither a side-hinged door nor a top-hinged flap
    (no room for hinges: a shallow drawer whose pull was found beside its centre is no door)."""
    out = {}
    if cfg.sliding_needs_track and common["partner"] <= 0 and common["rail"] <= 0:
        out["sliding"] = "no partner on another track and no track along an edge"
    if cfg.hinged_min_height is not None and common["height"] < cfg.hinged_min_height:
        why = f"{common['height']:.2f} m tall < hinged_min_height {cfg.hinged_min_height} m: no room for hinges"
        out.update(dict.fromkeys(("door_left", "door_right", "flap_top"), why))
    return out


WINDOW_BAND = 0.03  # grey level: a window contrast this close to window_contrast is a decision near its threshold
GLAZED_BAND = 0.05  # m: a glazed front's centre this close to glazed_low is one too


def glazed_near(ev: Evidence, cfg: TypesConfig, z_mid: float) -> bool:
    """Whether the glazed rules' outcome for this front rests on a value within its band of a
    threshold (:data:`WINDOW_BAND` of ``cfg.window_contrast``; for a glazed front, :data:`GLAZED_BAND`
    of ``cfg.glazed_low``): another machine's last bits could flip it, so the decision is marked
    ``low_margin``. False with the rules off or no image."""
    if cfg.window_contrast is None or ev.window is None:
        return False
    if abs(ev.window - cfg.window_contrast) < WINDOW_BAND:
        return True
    return (ev.window >= cfg.window_contrast and cfg.glazed_low is not None
            and abs(z_mid - cfg.glazed_low) < GLAZED_BAND)


def glazed(ev: Evidence, cfg: TypesConfig, z_mid: float) -> dict[str, str]:
    """The hypotheses a glazed front is not, with why: ``{"drawer": why}`` when its window
    contrast (``ev.window``, :func:`~drawer_lib.articulation.rectify.window_contrast`) reaches
    ``cfg.window_contrast`` (an oven's or a microwave's door, a glass door is hinged, never a
    drawer); with ``cfg.glazed_low`` and the front's centre height ``z_mid`` (m above the floor)
    as well, every hypothesis but ``flap_bottom`` below it (an oven door) and ``fixed`` as well
    above it (a microwave's or a glass cabinet's door moves); else {}."""
    if cfg.window_contrast is None or ev.window is None or ev.window < cfg.window_contrast:
        return {}
    out = {"drawer": f"a window: its panel stands {ev.window:.2f} off its frame's grey (>= window_contrast "
                     f"{cfg.window_contrast}): a glazed door, not a drawer"}
    if cfg.glazed_low is None:
        return out
    if z_mid < cfg.glazed_low:
        why = f"a window with its centre {z_mid:.2f} m up (< glazed_low {cfg.glazed_low} m): an oven door, hinged at its bottom"
        out.update({k: why for k in HYPOTHESES if k not in ("flap_bottom", "drawer")})
    else:
        out["fixed"] = (f"a window with its centre {z_mid:.2f} m up (>= glazed_low {cfg.glazed_low} m): "
                        "a microwave's or a glass cabinet's door, which moves")
    return out


PAIR_BAND = 0.02  # of the width, and m: a pull or a width this close to the pair rule's bounds is a decision near them


def pair_of_doors(h: Handle | None, size: tuple[float, float], excluded: dict[str, str],
                  cfg: TypesConfig) -> tuple[str, bool] | None:
    """Whether a front of ``size`` (w, h) m whose pull is ``h`` is two doors meeting at its
    middle (``cfg.pair_pull``; 0: never): its pull is a vertical bar within ``pair_pull`` of
    the width from the middle (no single front carries it there: a door's pull sits at its free
    edge, a drawer's or a flap's lies along an edge), it is at least 2 x ``pair_min_width`` wide
    and ``excluded`` (the score rule's ruled-out hypotheses) holds neither side-hinged door.
    Returns (why, near) or None; ``near``: the pull or the width lies within
    :data:`PAIR_BAND` of a bound, so that another machine's last bits could decide otherwise."""
    if not cfg.pair_pull or h is None or h.orientation != "vertical":
        return None
    off, w, w_min = abs(h.a_u - 0.5), size[0], 2 * cfg.pair_min_width
    if off > cfg.pair_pull or w < w_min or "door_left" in excluded or "door_right" in excluded:
        return None
    near = cfg.pair_pull - off < PAIR_BAND or w - w_min < PAIR_BAND
    why = (f"a pair of doors meeting at its middle: a vertical pull {off:.3f} of the width off it "
           f"(<= pair_pull {cfg.pair_pull}) on a front {w:.2f} m wide (>= 2 x pair_min_width {cfg.pair_min_width} m)")
    return why, near


def half_handle(h: Handle, side: str) -> Handle | None:
    """The pull ``h`` of a front cut at its middle, on the ``side`` half (left | right) in that
    half's unit square; None when its centre lies on the other half."""
    if side == "left" and h.a_u <= 0.5:
        return dataclasses.replace(h, a_u=2.0 * h.a_u)
    if side == "right" and h.a_u > 0.5:
        return dataclasses.replace(h, a_u=2.0 * h.a_u - 1.0)
    return None


def margin_confidence(scores: dict[str, float], best: str) -> tuple[str, float, float]:
    """(runner-up hypothesis, margin, confidence) of the choice ``best``: the margin is its
    score minus the runner-up's (a log-odds: the scores are a multinomial logistic model's), the
    confidence its softmax probability over all hypotheses. A margin near 0 is a decision that
    a small change of the evidence flips (two hinge sides with nothing to tell them apart tie
    at 0)."""
    others = [k for k in scores if k != best]
    if not others:
        return best, float("inf"), 1.0
    runner_up = max(others, key=lambda k: (scores[k], -HYPOTHESES.index(k)))
    s = np.array([scores[k] for k in scores], np.float64)
    p = np.exp(s - s.max())
    conf = float(np.exp(scores[best] - s.max()) / p.sum())
    return runner_up, float(scores[best] - scores[runner_up]), conf
