"""Config of the fitted interior templates (:mod:`drawer_lib.complete.interiors`),
``conf/complete/interiors`` keys. Lengths in metres.

Distances along a front's inward direction (-normal) are measured from the front's *outer* face
(its ``center``); a template occupies [start, start + depth] there, where start = the front's
thickness (plus the depth of a sliding partner's track in front of it) and depth includes the
template's back wall.
"""

from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ConfigError(msg)


@dataclass(frozen=True)
class TemplateConfig:
    """The boxes of a template. ``wall``: wall thickness (DRAWER: 2 cm); ``front_thickness``:
    assumed thickness of a front panel (the mesh shows only its outer face).

    Drawer: an open-top box behind the front, inset by ``drawer_side`` (each side),
    ``drawer_bottom`` and ``drawer_top`` from the front's edges (the carcass sides, runners and
    the gap above the box), ending ``drawer_back_clearance`` before the carcass back (runners
    come shorter than the carcass). Cabinet: a cavity (back, sides, top, bottom) within the
    front's rectangle inset by ``cavity_inset``, with one shelf per ``shelf_spacing`` of inner
    height (n = round(h / spacing) - 1, at least 0), set back ``shelf_setback`` from the front;
    its sides, top and bottom start ``cavity_clearance`` behind the front panel (a panel that
    moves in its plane, a sliding door, must not rub on them: flush, MuJoCo's box contact holds
    it by friction at 2 mm of travel).
    Appliance (a bottom-hinged flap whose lower edge is at most ``appliance_max_bottom`` above
    the floor: an oven, a dishwasher): a cavity without shelves. Walls never take more than
    ``max_wall_frac`` of an extent and insets never more than ``max_inset_frac`` of it, so tiny
    fronts still give valid boxes."""

    wall: float = 0.02
    front_thickness: float = 0.02
    drawer_side: float = 0.03
    drawer_bottom: float = 0.02
    drawer_top: float = 0.03
    drawer_back_clearance: float = 0.04
    cavity_inset: float = 0.0
    cavity_clearance: float = 0.003
    shelf_spacing: float = 0.35
    shelf_setback: float = 0.02
    appliance_max_bottom: float = 0.35
    drawer_normal_cos: float = 0.8
    max_wall_frac: float = 0.2
    max_inset_frac: float = 0.15

    def __post_init__(self):
        _check(0 < self.wall <= 0.1, f"complete.interiors.template.wall = {self.wall} must be in (0, 0.1] m")
        _check(0 < self.front_thickness <= 0.1, "complete.interiors.template.front_thickness must be in (0, 0.1] m")
        for k in ("drawer_side", "drawer_bottom", "drawer_top", "drawer_back_clearance", "cavity_inset", "cavity_clearance",
                  "shelf_setback", "appliance_max_bottom"):
            _check(getattr(self, k) >= 0, f"complete.interiors.template.{k} = {getattr(self, k)} must be >= 0")
        _check(self.shelf_spacing > 0, "complete.interiors.template.shelf_spacing must be > 0")
        _check(0 < self.drawer_normal_cos <= 1, "complete.interiors.template.drawer_normal_cos must be in (0, 1]")
        _check(0 < self.max_wall_frac < 0.5 and 0 <= self.max_inset_frac < 0.5,
               "complete.interiors.template: need 0 < max_wall_frac < 0.5 and 0 <= max_inset_frac < 0.5")


@dataclass(frozen=True)
class EvidenceConfig:
    """What the mesh says about the depth behind a front (points sampled on the mesh, with
    normals).

    Wall behind: points facing like the front (cosine >= ``normal_cos``), within the front's
    u-range (shrunk to ``u_frac`` of it) and ``v_band`` above / below it, between ``min_behind``
    and ``max_behind`` behind its outer face; histogram in ``bin`` bins; the farthest bin with
    at least max(``min_points``, ``min_frac`` x the fullest bin) points is the wall; a plane
    (centroid, mean normal) through its points gives the distance, perpendicular to the wall.
    Caps: surfaces continuing a front's edge backwards (a counter top above, a wall cabinet's
    underside below, an end panel at the side): points whose normal points away from the edge
    (cosine >= ``normal_cos``) within ``cap_band`` beyond it and within the front's extent along
    it; their ``cap_percentile`` depth is the carcass extent when at least ``cap_min_points``
    start at the front (5th percentile < ``cap_reach``) and reach beyond ``cap_min_extent``.
    A cap more than ``cap_short`` shorter than the wall means the cabinet stops before it; one
    more than ``cap_short`` longer means the "wall" is a surface in front of the carcass (a
    plinth), not the wall: it is dropped.
    ``support``: a measurement on n points gets the data weight n / (n + support).
    Fronts of other parts: one whose plane lies less than ``track_gap`` behind a front and
    overlaps it (projected) is the other track of the same cabinet (the interior starts behind
    it); one farther behind that covers more than ``blocking_overlap`` of the front bounds the
    depth."""

    normal_cos: float = 0.9
    u_frac: float = 0.9
    v_band: float = 0.6
    min_behind: float = 0.1
    max_behind: float = 2.0
    bin: float = 0.02
    min_points: int = 20
    min_frac: float = 0.2
    cap_band: float = 0.12
    cap_percentile: float = 98.0
    cap_min_points: int = 15
    cap_reach: float = 0.1
    cap_min_extent: float = 0.08
    cap_short: float = 0.05
    support: float = 200.0
    track_gap: float = 0.06
    blocking_overlap: float = 0.3

    def __post_init__(self):
        _check(-1 < self.normal_cos < 1, "complete.interiors.evidence.normal_cos must be in (-1, 1)")
        _check(0 < self.u_frac <= 1, "complete.interiors.evidence.u_frac must be in (0, 1]")
        _check(self.v_band >= 0 and self.cap_band > 0, "complete.interiors.evidence: need v_band >= 0, cap_band > 0")
        _check(0 <= self.min_behind < self.max_behind, "complete.interiors.evidence: need 0 <= min_behind < max_behind")
        _check(self.bin > 0, "complete.interiors.evidence.bin must be > 0")
        _check(self.min_points >= 1 and self.cap_min_points >= 1,
               "complete.interiors.evidence: min_points and cap_min_points must be >= 1")
        _check(0 <= self.min_frac <= 1, "complete.interiors.evidence.min_frac must be in [0, 1]")
        _check(50 <= self.cap_percentile <= 100, "complete.interiors.evidence.cap_percentile must be in [50, 100]")
        _check(self.support > 0, "complete.interiors.evidence.support must be > 0")
        _check(self.track_gap >= 0 and 0 < self.blocking_overlap <= 1,
               "complete.interiors.evidence: need track_gap >= 0 and blocking_overlap in (0, 1]")


@dataclass(frozen=True)
class FitConfig:
    """The joint fit of all depths (L-BFGS-B within [``min_depth``, ``max_depth``]):
    sum_i w_i (d_i - m_i)^2 (w_i from the evidence's support; ``default_weight`` for a part
    without evidence, pulled to the default) + ``penalty`` x (squared violations of: inside the
    carcass, in front of a blocking front, a drawer's box at least as deep as its travel, and
    each pair's overlap volume over the smaller front's area, the boxes shrunk by
    ``overlap_tol`` on every side first, so slivers from fronts a degree apart do not count).
    Without evidence a part's carcass depth defaults to the median of the fitted ones of the
    fronts in its plane (within ``coplanar_tol``: one run of cabinets), else of the kitchen,
    else ``default_depth`` (behind the front's inner face). A constraint is active when the data
    alone would violate it by more than ``active_tol``."""

    min_depth: float = 0.05
    max_depth: float = 1.5
    default_depth: float = 0.5
    default_weight: float = 0.1
    penalty: float = 1.0e4
    max_iter: int = 200
    active_tol: float = 0.002
    overlap_tol: float = 0.01
    coplanar_tol: float = 0.02
    fd_step: float = 1.0e-4

    def __post_init__(self):
        _check(0 < self.min_depth < self.max_depth, "complete.interiors.fit: need 0 < min_depth < max_depth")
        _check(self.min_depth <= self.default_depth <= self.max_depth,
               "complete.interiors.fit.default_depth must lie in [min_depth, max_depth]")
        _check(self.default_weight > 0 and self.penalty > 0, "complete.interiors.fit: weights must be > 0")
        _check(self.max_iter >= 1, "complete.interiors.fit.max_iter must be >= 1")
        _check(self.active_tol >= 0 and self.fd_step > 0 and self.overlap_tol >= 0,
               "complete.interiors.fit: need active_tol >= 0, overlap_tol >= 0, fd_step > 0")
        _check(self.coplanar_tol >= 0, "complete.interiors.fit.coplanar_tol must be >= 0")


TEXTURERS = ("observed", "learned")


@dataclass(frozen=True)
class TextureConfig:
    """Interior colours. ``texturer``: ``observed`` (built in: the colours seen on the front and
    the carcass, darkened with depth as ambient occlusion: factor 1 - ``ao_strength`` (1 -
    exp(-z / ``ao_length``)) at depth z, ``top_shade`` more on the ceiling, plus a
    ``patch_size``^2 procedural patch with the observed colour spread, smoothed over
    ``patch_grain`` texels) or ``learned`` (a slot for a diffusion texturer such as DRAWER's
    MatFuse; needs weights not shipped here). ``min_samples``: colour samples needed to trust
    the carcass colour (else the front's)."""

    texturer: str = "observed"
    learned_model: str = "matfuse"
    ao_strength: float = 0.45
    ao_length: float = 0.35
    top_shade: float = 0.85
    patch_size: int = 32
    patch_grain: float = 2.0
    min_samples: int = 10
    seed: int = 0

    def __post_init__(self):
        _check(self.texturer in TEXTURERS, f"complete.interiors.texture.texturer = {self.texturer!r} must be one of "
                                           f"{TEXTURERS}")
        _check(0 <= self.ao_strength < 1 and self.ao_length > 0,
               "complete.interiors.texture: need 0 <= ao_strength < 1 and ao_length > 0")
        _check(0 < self.top_shade <= 1, "complete.interiors.texture.top_shade must be in (0, 1]")
        _check(4 <= self.patch_size <= 1024, "complete.interiors.texture.patch_size must be in [4, 1024]")
        _check(self.patch_grain >= 0 and self.min_samples >= 1,
               "complete.interiors.texture: need patch_grain >= 0 and min_samples >= 1")


@dataclass(frozen=True)
class InteriorsConfig:
    """``method``: ``fitted`` (the templates fitted to the mesh's evidence) or ``drawer_rule``
    (DRAWER's fixed boxes: depth 1.5 x a door's width, 1.25 x a drawer's, 2 cm walls; the
    ablation). Both are always built and scored against GT; ``method`` picks the one the twin
    gets."""

    method: str = "fitted"
    template: TemplateConfig = field(default_factory=TemplateConfig)
    evidence: EvidenceConfig = field(default_factory=EvidenceConfig)
    fit: FitConfig = field(default_factory=FitConfig)
    texture: TextureConfig = field(default_factory=TextureConfig)

    def __post_init__(self):
        _check(self.method in ("fitted", "drawer_rule"),
               f"complete.interiors.method = {self.method!r} must be fitted or drawer_rule")
