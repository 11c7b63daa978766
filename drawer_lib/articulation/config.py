"""Config of the ``articulate`` stage (conf/articulate/default.yaml): every threshold that
changes a result, grouped by the step that uses it. Lengths in metres, angles in degrees."""

import math
from dataclasses import dataclass, field
from typing import Any

from drawer_lib.articulation.vocab import check_weights, prior_weights
from drawer_lib.errors import ConfigError
from drawer_lib.hub import HubModel
from drawer_lib.io.working import check_max_side


@dataclass(frozen=True)
class FrontsConfig:
    """Front rectangles (:mod:`drawer_lib.articulation.fronts`). A planar segment whose normal
    lies within ``vertical_deg`` of horizontal is a front candidate; the plane is re-fitted on
    the points within ``inlier_m`` of it; the rectangle spans the ``extent_percentile`` ..
    100 - ``extent_percentile`` percentiles of the points (corrected for a uniform spread), its
    centre on the panel's outer face: the ``outer_percentile`` of the inliers' offsets.
    With detections, each side is instead the median over the matched masks (cast onto the
    plane; ``mask_percentile`` extents) whose pixels on that side stay ``mask_border_px`` away
    from the image border, when at least ``mask_min_frames`` masks say so. Coplanar fronts
    (within 0.75 x the smallest sliding step) whose facing edges lie within ``shared_edge_gap``
    (0 = off), overlap over ``shared_edge_overlap`` of the shorter side and whose axes agree
    within ``shared_edge_angle_deg`` share one edge; so do two whose rectangles run into each
    other by up to ``shared_edge_cross`` x the shorter side across that edge (0: only within
    ``shared_edge_gap``), each cut back to where the two segments' surfaces part. Before that, a
    front with at least ``repeat_inside`` of its area inside a larger coplanar front is that front
    found twice and is dropped (0: off; :func:`~drawer_lib.articulation.infer.drop_fronts_inside`). Fronts smaller
    than ``min_size`` or larger than ``max_size`` (either side) are not parts. The gravity prior: a front whose fitted plane
    tilts less than ``plumb_deg`` from vertical is made plumb (its normal levelled; kitchen
    fronts hang plumb in a gravity-aligned world frame, and a plane fitted to a noisy mesh
    tilts by a degree or more, which would roll a drawer open on its own or swing a door on
    its leaning hinge); 0 turns it off; at most ``vertical_deg``. The prior sets the part's
    front and joint only: the evidence for its type is read off the fitted plane."""

    vertical_deg: float = 25.0
    plumb_deg: float = 15.0
    min_size: float = 0.08
    max_size: float = 2.6
    inlier_m: float = 0.01
    extent_percentile: float = 2.0
    outer_percentile: float = 90.0
    mask_percentile: float = 1.0
    mask_min_frames: int = 2
    mask_border_px: int = 2
    mask_min_pixels: int = 20
    shared_edge_gap: float = 0.025
    shared_edge_overlap: float = 0.5
    shared_edge_angle_deg: float = 10.0
    shared_edge_cross: float = 0.3
    repeat_inside: float = 0.8
    sample_per_m2: float = 40000.0  # points sampled on a segment's faces for the plane fit
    sampling: str = "random"  # the mesh points articulate reads: random (one draw over the faces) or local (per face)

    def __post_init__(self):
        if self.sampling not in ("random", "local"):
            raise ConfigError(f"articulate.fronts.sampling = {self.sampling!r}: choose random or local")
        if not 0 < self.extent_percentile < 50 or not 0 < self.mask_percentile < 50:
            raise ConfigError("articulate.fronts: extent_percentile and mask_percentile must be in (0, 50)")
        if self.shared_edge_gap < 0:
            raise ConfigError(f"articulate.fronts.shared_edge_gap = {self.shared_edge_gap} must be >= 0 (0 turns it off)")
        if not 0 <= self.shared_edge_cross < 0.5:
            raise ConfigError(f"articulate.fronts.shared_edge_cross = {self.shared_edge_cross} must be in [0, 0.5) "
                              "(a fraction of the shorter side; half or more is one front repeated, not two)")
        if not (self.repeat_inside == 0 or 0.5 < self.repeat_inside <= 1):
            raise ConfigError(f"articulate.fronts.repeat_inside = {self.repeat_inside} must be 0 (off) or in (0.5, 1] "
                              "(a share of the smaller front's area; less is two fronts running into each other)")
        if not 0 < self.min_size < self.max_size:
            raise ConfigError("articulate.fronts: need 0 < min_size < max_size")
        if not 0 <= self.plumb_deg <= self.vertical_deg:
            raise ConfigError(f"articulate.fronts.plumb_deg = {self.plumb_deg} must be in [0, vertical_deg = "
                              f"{self.vertical_deg}]")


@dataclass(frozen=True)
class HandlesConfig:
    """Handles (:mod:`drawer_lib.articulation.handles`). Geometry: mesh points (sampled at
    ``sample_per_m2``) ``min``..``max`` in front of a front's plane within its rectangle, except
    on surfaces within ``flat_deg`` of facing up or down and in rows / columns (``row_bin`` m)
    spanning more than ``full_span`` of the front (a counter edge, a plinth); clusters of
    ``geo_min_points`` at single linkage ``geo_radius``. Masks: faces covered by "handle" masks
    in at least ``min_hits`` views, clustered at max(``geo_radius``, ``mask_radius_spacing`` x
    the mesh's edge length) with ``mask_min_points``; ``evidence`` weighs them by ``count`` or
    by ``view_rate`` (hits / views seeing the face). Every point goes to the front it lies
    deepest in, at most ``max_gap`` outside its rectangle and from ``below_plane`` behind to
    ``max`` in front of it; a cluster spanning ``max_span`` of a front is not a handle. A handle's
    extents are its ``extent_percentile`` .. 100 - ``extent_percentile`` ranges; it is round
    when the longer is below ``round_aspect`` x the shorter + ``round_slack``.
    ``stacked_pulls``: a horizontal pull in the gap between two stacked fronts (coplanar within
    ``stacked_plane_tol``, overlapping over ``stacked_min_overlap``) that both take goes to the
    lower one (:func:`~drawer_lib.articulation.handles.resolve_stacked_pulls`).
    ``split_pulls``: one pull whose points two fronts took (candidates within ``max_gap`` of
    each other) goes whole to the front it reaches deeper into, when deeper by at least
    ``split_margin`` m (:func:`~drawer_lib.articulation.handles.resolve_split_pulls`)."""

    min: float = 0.008
    max: float = 0.08
    evidence: str = "view_rate"
    min_hits: int = 2
    geo_radius: float = 0.015
    geo_min_points: int = 10
    mask_radius_spacing: float = 1.5
    mask_min_points: int = 3
    max_gap: float = 0.03
    max_span: float = 0.85
    below_plane: float = 0.01
    flat_deg: float = 30.0
    full_span: float = 0.8
    row_bin: float = 0.01
    extent_percentile: float = 5.0
    round_aspect: float = 1.8
    round_slack: float = 0.01
    stacked_pulls: bool = True
    stacked_plane_tol: float = 0.02
    stacked_min_overlap: float = 0.5
    split_pulls: bool = True
    split_margin: float = 0.01
    sample_per_m2: float = 20000.0

    def __post_init__(self):
        if not 0 < self.min < self.max:
            raise ConfigError("articulate.handles: need 0 < min < max")
        if self.evidence not in ("count", "view_rate"):
            raise ConfigError(f"articulate.handles.evidence = {self.evidence!r} must be count or view_rate")
        if self.min_hits < 1 or self.geo_min_points < 1 or self.mask_min_points < 1:
            raise ConfigError("articulate.handles: min_hits, geo_min_points and mask_min_points must be >= 1")
        if not self.split_margin >= 0:
            raise ConfigError(f"articulate.handles.split_margin = {self.split_margin} must be >= 0 (m)")


@dataclass(frozen=True)
class RectifyConfig:
    """Rectified fronts (:mod:`drawer_lib.articulation.rectify`): ``enabled`` (false: the
    handle evidence of the masks is the faces of the mesh they cover), the grid's ``res`` (m per
    cell) and ``margin`` (m beyond the rectangle); a view counts where the front faces it within
    ``max_angle_deg`` and the ray-cast surface is not nearer than the cell by more than
    ``occlusion_tol`` (m, + 2 % of the depth); the handle map samples ``handle_offset`` (m) in
    front of the plane. A handle cell is seen in at least ``min_views`` views and covered in at
    least ``min_rate`` of them; a handle is at least ``min_cells`` such cells linked at
    ``handle_link`` cells (single linkage; 1.5 links neighbours and diagonals only, 2.5 bridges
    one missing cell). ``grid_anchor``: how the grid sits on the front
    (:func:`~drawer_lib.articulation.rectify.front_grid`): ``size``, the cells that cover it,
    centred (a size crossing a multiple of ``res`` moves them all by half a cell), or
    ``centre``, cells at whole multiples of ``res`` from its centre (a size change adds or drops
    border cells only).
    ``colour_handles``: a front whose masks show no handle takes one read off its rectified
    colours (:func:`~drawer_lib.articulation.handles.colour_handle`: cells ``colour_edge_band``
    m inside the rectangle farther from the front's median colour than max(``colour_contrast``,
    ``colour_texture_k`` x the median distance), a bar or knob ``colour_min_len`` ..
    ``colour_max_len`` m long and at most ``colour_max_width`` m wide)."""

    enabled: bool = True
    res: float = 0.004
    margin: float = 0.03
    max_angle_deg: float = 75.0
    occlusion_tol: float = 0.05
    handle_offset: float = 0.02
    min_views: int = 3
    min_rate: float = 0.3
    min_cells: int = 8
    handle_link: float = 1.5
    grid_anchor: str = "size"
    colour_handles: bool = True
    colour_edge_band: float = 0.015
    colour_contrast: float = 0.12
    colour_texture_k: float = 4.0
    colour_min_len: float = 0.015
    colour_max_len: float = 0.45
    colour_max_width: float = 0.05

    def __post_init__(self):
        if not 0 < self.res <= 0.05:
            raise ConfigError(f"articulate.rectify.res = {self.res} must be in (0, 0.05] m")
        if self.margin < 0 or self.occlusion_tol < 0 or self.handle_offset < 0:
            raise ConfigError("articulate.rectify: margin, occlusion_tol and handle_offset must be >= 0")
        if not 0 < self.max_angle_deg < 90:
            raise ConfigError(f"articulate.rectify.max_angle_deg = {self.max_angle_deg} must be in (0, 90)")
        if not 0 < self.min_rate <= 1 or self.min_views < 1 or self.min_cells < 1:
            raise ConfigError("articulate.rectify: need 0 < min_rate <= 1, min_views >= 1, min_cells >= 1")
        if not 1.0 <= self.handle_link <= 5.0:
            raise ConfigError(f"articulate.rectify.handle_link = {self.handle_link} must be in [1, 5] cells")
        if self.grid_anchor not in ("size", "centre"):
            raise ConfigError(f"articulate.rectify.grid_anchor = {self.grid_anchor!r} must be size or centre")


@dataclass(frozen=True)
class SplitConfig:
    """Fronts cut at their gap lines (:mod:`drawer_lib.articulation.gaps`; needs ``rectify`` and
    the images): ``enabled``; a strong boundary cell lies between two instance masks in at least
    ``boundary_rate`` of the views that saw it (a weak one in ``boundary_rate_handles``), give
    or take ``slack`` cells; an image line cell
    differs from the mean of the cells ``step`` away on either side by more than max(``contrast``,
    ``texture_k`` x the front's median such difference); a cut's strong boundary cells cover
    ``coverage`` of each third of the piece's span (with handles on both sides, its weak
    boundary or image line cells ``coverage_handles``), at least ``min_piece`` (m) from its edges, crossing no handle; at
    most ``max_depth`` cuts deep. ``depth_steps``: a front (or piece) is also cut where the
    mesh under it steps by a sliding door's track offset (``joints.sliding_step``) along u,
    profiled in bins of ``depth_bin`` m (:func:`~drawer_lib.articulation.gaps.depth_step_cuts`;
    the mesh alone, no images needed). ``extent_steps``: also where the segment's outline steps
    by ``extent_min_step`` m or more (an L-shaped segment is two fronts;
    :func:`~drawer_lib.articulation.gaps.extent_step_cuts`). ``max_width`` (m; 0: off): a piece
    wider than this holds several fronts (catalogue doors stop near 0.6 m, drawers and flaps
    near 1.2 m): its vertical cuts need no handle on either side, and with no such cut it is cut
    at its best-covered column all the same, at least ``wide_min_piece`` (m) from its ends.
    ``wide_even`` (m; 0: off; nothing with ``max_width`` off): a piece still too wide with no line
    at all is cut into max(2, round(width / ``wide_even``)) pieces of equal width (a run of
    modules of one width)."""

    enabled: bool = True
    boundary_rate: float = 0.1
    boundary_rate_handles: float = 0.05
    slack: int = 2
    step: int = 2
    contrast: float = 0.02
    texture_k: float = 4.0
    coverage: float = 0.6
    coverage_handles: float = 0.35
    min_piece: float = 0.1
    max_depth: int = 6
    duplicate_iou: float = 0.5
    depth_steps: bool = True
    depth_bin: float = 0.02
    extent_steps: bool = True
    extent_min_step: float = 0.05
    max_width: float = 1.3
    wide_min_piece: float = 0.2
    wide_even: float = 0.6

    def __post_init__(self):
        if not 0 < self.duplicate_iou <= 1:
            raise ConfigError(f"articulate.split.duplicate_iou = {self.duplicate_iou} must be in (0, 1]")
        if not self.extent_min_step > 0:
            raise ConfigError(f"articulate.split.extent_min_step = {self.extent_min_step} must be > 0 m")
        if self.max_width < 0 or not self.wide_min_piece > 0 or (self.max_width and self.max_width < 2 * self.wide_min_piece):
            raise ConfigError(f"articulate.split: need max_width >= 0 (0: off) and wide_min_piece > 0, at most half of it; "
                              f"got {self.max_width}, {self.wide_min_piece}")
        if not (self.wide_even == 0 or (self.wide_even >= self.wide_min_piece
                                         and (self.max_width == 0 or self.wide_even <= self.max_width))):
            raise ConfigError(f"articulate.split.wide_even = {self.wide_even}: 0 (off), or between wide_min_piece "
                              f"({self.wide_min_piece}) and max_width ({self.max_width})")
        if not 0 < self.depth_bin <= 0.1:
            raise ConfigError(f"articulate.split.depth_bin = {self.depth_bin} must be in (0, 0.1] m")
        if self.step < 1 or self.max_depth < 0 or self.slack < 0:
            raise ConfigError("articulate.split: need step >= 1, slack >= 0 and max_depth >= 0")
        if not 0 < self.boundary_rate_handles <= self.boundary_rate <= 1:
            raise ConfigError("articulate.split: need 0 < boundary_rate_handles <= boundary_rate <= 1")
        if not 0 < self.coverage_handles <= self.coverage <= 1 or self.contrast < 0 or self.texture_k < 0 or not self.min_piece > 0:
            raise ConfigError("articulate.split: need 0 < coverage_handles <= coverage <= 1, contrast >= 0, "
                              "texture_k >= 0, min_piece > 0")


@dataclass(frozen=True)
class TypesConfig:
    """The type decision (:mod:`drawer_lib.articulation.decide`). ``rule: score`` (default): a
    linear score per hypothesis over the front's evidence (:mod:`drawer_lib.articulation.scoring`)
    with the ``weights``: ``fitted`` (what the ``fit_decisions`` stage fitted on the benchmark's
    train split, a file of the pipeline) or ``prior`` (the hand-set {hypothesis: {feature:
    weight}} below, which the fit also starts from). ``rule: handle``: the handle rule alone
    (:func:`~drawer_lib.articulation.decide.decide_by_handle`): a handle within ``edge_frac`` of
    a side edge makes a door hinged on the far side (a horizontal one only within ``edge_frac`` /
    2), near the bottom a flap hinged at the top, near the top a drawer (or, when ``use_labels``
    and the majority of label votes is in ``door_labels`` rather than ``drawer_labels``, a flap
    hinged at the bottom), central a drawer; a sliding partner makes a sliding door, no handle a
    fixed panel. ``edge_frac`` also bounds the stacked-pull check of the handles. ``use_labels``:
    label votes are evidence (false: ignored). Either rule: a front without a handle that
    detections matched in fewer than ``min_support`` views is a fixed panel (a front seen in many
    views, in a carcass, is rarely fixed even when its handle is too small to find); a front with
    a handle or enough support is typed. Either rule: a front without a handle narrower than
    ``filler_width`` (m) is a fixed panel too: a filler strip, or the sliver a cut leaves where a
    mask spilt onto a neighbour (real narrow pull-outs carry a handle); null turns this off. A score decision whose margin over the runner-up is
    below ``low_margin`` (log-odds) is marked ``low_margin`` in ``decisions.json`` and
    ``parts.json``, listed by the report and marked in the viewer; ``near_segment``: so is every
    front of a segment decompose selected by a margin another machine's mesh could cross (its
    ``near`` rows in ``segments.json``; off by default: on the tuning kitchens those rows marked
    none of the parts that a mesh moved by its last bits moved, docs/perception.md). ``sliding_needs_track``: the
    score rule types a front sliding only when it has a partner on another track or a track
    along an edge (:func:`~drawer_lib.articulation.decide.missing_evidence`).
    ``hinged_min_height`` (m): the score rule types a front shorter than this neither a
    side-hinged door nor a top-hinged flap (a hinged front needs room for its hinges; kitchen
    makers' doors and flaps start near 0.3 m, drawers at 0.1 m; a bottom-hinged tilt-out stays
    possible); null turns this off.
    ``window_contrast`` (grey level in [0, 1]): the score rule types a front whose panel stands
    this far or more off its frame's grey on its rectified image (a window:
    :func:`~drawer_lib.articulation.rectify.window_contrast`) no drawer (an oven, a microwave, a
    glass door; a drawer front is opaque); null turns this off.
    ``glazed_low`` (m; read only with ``window_contrast``): such a glazed front whose centre lies
    below this height above the floor is an oven door, hinged at its bottom (every other
    hypothesis excluded); one above it is a hinged door, never a fixed panel (a microwave's or a
    glass cabinet's door; the hinge side from the handle as for any door); null turns this off.
    ``drawer_max_height`` (m): where the score rule's ``tall`` feature starts (a front taller
    than the deepest drawers, which stop near 0.4 m in real kitchens, is a door or a flap).
    ``front_labels``: the labels, besides ``door_labels`` and ``drawer_labels``, a detector
    gives a front (the built-in detector's and generic detections' ``front``); with
    ``use_labels``, a planar segment more than half of whose label votes are other labels
    (``box``, ``object``, ``kettle``: what a detector called an object) is a rigid object, not a
    front (DRAWER takes its articulated parts from the masks of its front prompts alone).
    ``pair_pull`` (fraction of the width; 0: off; score rule only): a front whose pull is a
    vertical bar within this of its middle, at least 2 x ``pair_min_width`` (m) wide, for which
    the evidence excludes neither side-hinged door and that is not a sliding panel with a
    partner, is two doors meeting at its middle, each hinged on its outer edge (a pair a
    detector joined: a single front never carries its pull there;
    :func:`~drawer_lib.articulation.decide.pair_of_doors`)."""

    rule: str = "score"
    weights: str = "fitted"
    prior: dict[str, dict[str, float]] = field(default_factory=prior_weights)
    min_support: int = 5
    filler_width: float | None = 0.25
    low_margin: float = 1.0
    near_segment: bool = False
    sliding_needs_track: bool = True
    hinged_min_height: float | None = 0.2
    window_contrast: float | None = 0.15
    glazed_low: float | None = 0.75
    drawer_max_height: float = 0.45
    pair_pull: float = 0.1
    pair_min_width: float = 0.25
    edge_frac: float = 0.3
    use_labels: bool = True
    door_labels: list[str] = field(default_factory=lambda: ["door", "flap", "cabinet door"])
    drawer_labels: list[str] = field(default_factory=lambda: ["drawer"])
    front_labels: list[str] = field(default_factory=lambda: ["front"])

    def object_share(self, labels: dict[str, int]) -> float:
        """The share of a segment's label votes ``labels`` that no front label holds (0 without votes)."""
        total = sum(labels.values())
        fronts = {x.strip().lower() for x in [*self.door_labels, *self.drawer_labels, *self.front_labels]}
        return sum(v for k, v in labels.items() if k.strip().lower() not in fronts) / total if total else 0.0

    def __post_init__(self):
        if self.rule not in ("score", "handle"):
            raise ConfigError(f"articulate.types.rule = {self.rule!r} must be score or handle")
        if self.weights not in ("fitted", "prior"):
            raise ConfigError(f"articulate.types.weights = {self.weights!r} must be fitted or prior")
        if self.window_contrast is not None and not 0 < self.window_contrast < 1:
            raise ConfigError(f"articulate.types.window_contrast = {self.window_contrast} must be in (0, 1) "
                              "(a grey level) or null")
        if self.glazed_low is not None and not 0 <= self.glazed_low < 10:
            raise ConfigError(f"articulate.types.glazed_low = {self.glazed_low} must be in [0, 10) m or null")
        if not 0 < self.edge_frac < 0.5:
            raise ConfigError(f"articulate.types.edge_frac = {self.edge_frac} must be in (0, 0.5)")
        if self.min_support < 0:
            raise ConfigError(f"articulate.types.min_support = {self.min_support} must be >= 0")
        if not self.low_margin >= 0:
            raise ConfigError(f"articulate.types.low_margin = {self.low_margin} must be >= 0")
        if self.filler_width is not None and not 0 <= self.filler_width < 10:
            raise ConfigError(f"articulate.types.filler_width = {self.filler_width} must be in [0, 10) m or null")
        if self.hinged_min_height is not None and not 0 <= self.hinged_min_height < 10:
            raise ConfigError(f"articulate.types.hinged_min_height = {self.hinged_min_height} must be in [0, 10) m or null")
        if not 0 <= self.pair_pull < 0.5:
            raise ConfigError(f"articulate.types.pair_pull = {self.pair_pull} must be in [0, 0.5) "
                              "(a fraction of the width; 0: off)")
        if not 0 < self.pair_min_width < 5:
            raise ConfigError(f"articulate.types.pair_min_width = {self.pair_min_width} must be in (0, 5) m")
        if not 0 < self.drawer_max_height < 10:
            raise ConfigError(f"articulate.types.drawer_max_height = {self.drawer_max_height} must be in (0, 10) m")
        check_weights(self.prior, "articulate.types.prior")


@dataclass(frozen=True)
class JointsConfig:
    """Axes and limits (:mod:`drawer_lib.articulation.joints`). Revolute parts open to
    ``revolute_limit_deg``. A drawer travels ``drawer_travel`` x the carcass depth: the
    ``carcass_percentile`` of the distances, between ``carcass_min_depth`` and
    ``carcass_max_depth`` behind the front, of the mesh points facing the same way (cosine >=
    ``carcass_normal_cos``), when there are ``carcass_min_points`` of them (else
    ``default_depth``). Sliding doors: an adjacent front (overlap > -``sliding_adjacent_gap``)
    with a near-parallel normal (cosine >= ``sliding_normal_cos``) a ``sliding_step`` [min,
    max] behind (measured on the points within ``sliding_band`` of their shared edge), of the
    same height (within ``sliding_same_height`` of it, centres within ``sliding_aligned`` of
    it), neither pulled more than ``sliding_pull_meets`` of its width off centre toward the
    other (a double door; null: not checked); each travels the partner's width minus the
    overlap and ``sliding_clearance``, at least
    ``sliding_min_travel``. A sliding door without a partner travels ``sliding_single_travel``
    x its width toward the side where the mesh lies deeper behind its plane (an open shelf or
    a panel it slides over, probed over ``sliding_probe`` x its width beyond each side edge),
    away from its handle when both sides look alike. Its track is looked for from
    ``rail_inside`` inside its top or bottom edge to 6 cm beyond it
    (:func:`~drawer_lib.articulation.probes.rail_run`): a mask that spills onto the track puts
    the front's edge on it."""

    revolute_limit_deg: float = 90.0
    drawer_travel: float = 0.8
    default_depth: float = 0.5
    carcass_min_depth: float = 0.1
    carcass_max_depth: float = 1.0
    carcass_normal_cos: float = 0.9
    carcass_percentile: float = 10.0
    carcass_min_points: int = 10
    sliding_step: list[float] = field(default_factory=lambda: [0.008, 0.06])
    sliding_adjacent_gap: float = 0.04
    sliding_normal_cos: float = 0.95
    sliding_band: float = 0.08
    sliding_same_height: float = 0.15
    sliding_aligned: float = 0.1
    sliding_clearance: float = 0.02
    sliding_min_travel: float = 0.05
    sliding_single_travel: float = 0.9
    sliding_probe: float = 0.5
    sliding_pull_meets: float | None = 0.15
    rail_inside: float = 0.03

    def __post_init__(self):
        if len(self.sliding_step) != 2 or not 0 <= self.sliding_step[0] < self.sliding_step[1]:
            raise ConfigError(f"articulate.joints.sliding_step = {self.sliding_step} must be [min, max] with 0 <= min < max")
        if self.revolute_limit_deg <= 0 or self.drawer_travel <= 0:
            raise ConfigError("articulate.joints: revolute_limit_deg and drawer_travel must be positive")
        if not 0 <= self.carcass_min_depth < self.carcass_max_depth:
            raise ConfigError("articulate.joints: need 0 <= carcass_min_depth < carcass_max_depth")
        if not 0 <= self.rail_inside < 0.06:
            raise ConfigError(f"articulate.joints.rail_inside = {self.rail_inside} must be in [0, 0.06) m")


@dataclass(frozen=True)
class InteractionConfig:
    """The interaction test (:mod:`drawer_lib.articulation.interaction`): each moving
    hypothesis' panel swept along its joint through the mesh's points (sampled every
    ``spacing`` on the front inset by ``inset``, ``step`` of motion at a time); a contact is
    ``min_hits`` panel samples within ``clearance`` of points that are not the front's own (its
    rectangle grown by ``own_margin``, from ``own_depth`` behind to ``own_proud`` in front of
    it). A hypothesis blocked before ``min_clear`` of its range is excluded by the score rule, and
    a drawer when the ``room_percentile`` of the depths of the points behind the front (probed
    to ``room_probe``) is under ``drawer_min_room``."""

    enabled: bool = True
    clearance: float = 0.015
    spacing: float = 0.03
    inset: float = 0.03
    step: float = 0.03
    min_hits: int = 3
    own_margin: float = 0.03
    own_depth: float = 0.03
    own_proud: float = 0.1
    min_clear: float = 0.5
    room_probe: float = 0.3
    room_percentile: float = 10.0
    drawer_min_room: float = 0.15

    def __post_init__(self):
        if min(self.clearance, self.spacing, self.step, self.room_probe) <= 0 or self.min_hits < 1:
            raise ConfigError("articulate.interaction: clearance, spacing, step, room_probe must be > 0 and min_hits >= 1")
        if not 0 <= self.min_clear <= 1:
            raise ConfigError(f"articulate.interaction.min_clear = {self.min_clear} must be in [0, 1]")
        if min(self.inset, self.own_margin, self.own_depth, self.own_proud, self.drawer_min_room) < 0:
            raise ConfigError("articulate.interaction: inset, own_margin, own_depth, own_proud, drawer_min_room must be >= 0")
        if not 0 <= self.room_percentile <= 100:
            raise ConfigError(f"articulate.interaction.room_percentile = {self.room_percentile} must be in [0, 100]")


@dataclass(frozen=True)
class FalseFrontsConfig:
    """A world-fixed false front (a detector that takes a patch of wall, a window or an
    appliance panel for a front in every view) is dropped, not typed: no gap runs round it (no
    side of its rectified image shows a line or an edge within ``line_slack`` m along
    ``line_coverage`` of its length; :func:`~drawer_lib.articulation.gaps.border_lines`), the
    surface runs on flush beyond ``min_flush_sides`` of its sides (``flush_frac`` of the mesh
    points ``ring`` = [from, to] m beyond the side within ``flush_tol`` of its plane, with at
    least ``min_points`` there; :func:`~drawer_lib.articulation.probes.flush_sides`), and no
    handle detection or protrusion says otherwise (a handle read off colours alone does not).

    A front short of that, whose surface runs on flush beyond both its left and right sides
    (``flanked_flush`` of the ring's points) while a gap line shows along fewer than
    ``flanked_min_lines`` of its sides (each along ``flanked_line`` of its length), is
    *flanked*: kept and typed, but without a handle it is not taken for a lone push-to-open
    door (:func:`~drawer_lib.articulation.infer.flanked`; the ``bare_lone`` feature of
    :mod:`~drawer_lib.articulation.scoring`). ``flanked_min_lines: 0`` turns this off."""

    enabled: bool = True
    line_slack: float = 0.012
    line_coverage: float = 0.5
    ring: list[float] = field(default_factory=lambda: [0.03, 0.1])
    flush_tol: float = 0.01
    flush_frac: float = 0.7
    min_points: int = 20
    min_flush_sides: int = 4
    flanked_flush: float = 0.4
    flanked_line: float = 0.3
    flanked_min_lines: int = 2

    def __post_init__(self):
        if len(self.ring) != 2 or not 0 <= self.ring[0] < self.ring[1]:
            raise ConfigError(f"articulate.false_fronts.ring = {self.ring} must be [from, to] with 0 <= from < to")
        if not (0 <= self.line_coverage <= 1 and 0 <= self.flush_frac <= 1 and 0 <= self.min_flush_sides <= 4):
            raise ConfigError("articulate.false_fronts: line_coverage and flush_frac in [0, 1], min_flush_sides in 0..4")
        if self.line_slack < 0 or self.flush_tol <= 0 or self.min_points < 1:
            raise ConfigError("articulate.false_fronts: line_slack >= 0, flush_tol > 0, min_points >= 1")
        if not (0 <= self.flanked_flush <= 1 and 0 <= self.flanked_line <= 1 and 0 <= self.flanked_min_lines <= 4):
            raise ConfigError(f"articulate.false_fronts: flanked_flush = {self.flanked_flush} and flanked_line = "
                              f"{self.flanked_line} must be in [0, 1], flanked_min_lines = {self.flanked_min_lines} in 0..4")


@dataclass(frozen=True)
class VlmConfig:
    """The ``vlm`` estimator (:mod:`drawer_lib.articulation.vlm`; DRAWER asks GPT-4o): a
    vision-language model run locally through ``transformers`` is shown each front in the view
    that sees it largest, outlined in red with ``margin`` of its box around it, and asked
    ``prompt``; the first word of ``answers`` its reply contains gives the front label votes of
    that key, ``share`` of the segment's votes once added (the detections' keep the rest), which
    the score rule weighs through ``lab_drawer`` / ``lab_door``. A front smaller than ``min_px``
    on its shorter side in every view, or that no view sees whole, is not asked.
    ``processor_kwargs``: keyword arguments of the processor's call, which set what the model
    sees and so its cost (SmolVLM / Idefics3: ``do_image_splitting: false`` gives one 512 px
    tile instead of up to 17, ~64 image tokens instead of ~1100; a processor that does not know
    a key ignores it with a warning). Weights: ``model`` (:class:`~drawer_lib.hub.HubModel`),
    read from a local folder or the Hugging Face cache, fetched only with ``allow_download``."""

    model: HubModel = field(default_factory=lambda: HubModel(repo="HuggingFaceTB/SmolVLM-256M-Instruct"))
    allow_download: bool = False
    device: str = "cpu"
    prompt: str = ("The part of a kitchen outlined in red: is it a drawer, a door, or a fixed panel that does not "
                   "open? Answer with one word.")
    answers: dict[str, list[str]] = field(default_factory=lambda: {
        "drawer": ["drawer"], "door": ["door", "flap", "lid"], "front": ["panel", "fixed"]})
    share: float = 0.5
    margin: float = 0.3
    min_px: int = 24
    max_new_tokens: int = 8
    processor_kwargs: dict[str, Any] = field(default_factory=lambda: {"do_image_splitting": False})

    def __post_init__(self):
        if not all(isinstance(k, str) for k in self.processor_kwargs):
            raise ConfigError(f"articulate.vlm.processor_kwargs = {self.processor_kwargs!r} must map names to values")
        reserved = {"text", "images", "return_tensors"} & set(self.processor_kwargs)
        if reserved:
            raise ConfigError(f"articulate.vlm.processor_kwargs: {sorted(reserved)} are set by the estimator")
        if not self.prompt.strip():
            raise ConfigError("articulate.vlm.prompt is empty")
        if not self.answers or any(not isinstance(w, list) or not w for w in self.answers.values()):
            raise ConfigError("articulate.vlm.answers must map each label to a non-empty list of answer words")
        if not 0 < self.share < 1:
            raise ConfigError(f"articulate.vlm.share = {self.share} must be in (0, 1)")
        if self.margin < 0 or self.min_px < 1 or self.max_new_tokens < 1:
            raise ConfigError("articulate.vlm: margin >= 0, min_px >= 1 and max_new_tokens >= 1")


@dataclass(frozen=True)
class CheckConfig:
    """The parts inferred again from the mesh moved as another machine's reconstruction could
    move it (:func:`drawer_lib.articulation.pipeline.mesh_check`): ``runs`` times (0: off),
    decompose and articulate rerun on the mesh whose every vertex moved by Gaussian noise of
    ``sigma`` metres (each run its own draw); a part that any run gives another kind or hinge
    side, or no part, is listed ``near_mesh`` and marked ``low_margin``. Its kinds are not
    changed. Costs ``runs`` x (decompose + articulate)."""

    runs: int = 0
    sigma: float = 1e-6

    def __post_init__(self):
        if self.runs < 0:
            raise ConfigError(f"articulate.check.runs = {self.runs}: must be >= 0")
        if not (self.sigma > 0 and math.isfinite(self.sigma)):
            raise ConfigError(f"articulate.check.sigma = {self.sigma}: must be a finite length > 0 (m)")


@dataclass(frozen=True)
class ArticulateConfig:
    """Segments -> ``parts.json`` (``drawer.parts/1``, docs/formats.md). ``estimator``: ``geometric`` (built in: plane,
    rectangle, handle and layout cues), ``vlm`` (the same, with a local vision-language model's
    answer for each front as label votes: ``vlm``) or ``3doi`` (a named slot that needs weights
    not available here; register an estimator with
    :func:`drawer_lib.articulation.estimators.register_estimator`)."""

    estimator: str = "geometric"
    max_side: int | None = 640  # working resolution of the views, masks and rectified fronts (drawer_lib/io/working.py); None: the capture's
    fronts: FrontsConfig = field(default_factory=FrontsConfig)
    handles: HandlesConfig = field(default_factory=HandlesConfig)
    rectify: RectifyConfig = field(default_factory=RectifyConfig)
    split: SplitConfig = field(default_factory=SplitConfig)
    types: TypesConfig = field(default_factory=TypesConfig)
    joints: JointsConfig = field(default_factory=JointsConfig)
    interaction: InteractionConfig = field(default_factory=InteractionConfig)
    false_fronts: FalseFrontsConfig = field(default_factory=FalseFrontsConfig)
    vlm: VlmConfig = field(default_factory=VlmConfig)
    check: CheckConfig = field(default_factory=CheckConfig)

    def __post_init__(self):
        check_max_side("articulate.max_side", self.max_side)
        if self.estimator == "vlm":
            if not self.types.use_labels:
                raise ConfigError("articulate.estimator = vlm gives label votes, which articulate.types.use_labels = "
                                  "false ignores")
            fronts = {x.strip().lower() for x in [*self.types.door_labels, *self.types.drawer_labels,
                                                  *self.types.front_labels]}
            bad = sorted(k for k in self.vlm.answers if k.strip().lower() not in fronts)
            if bad:
                raise ConfigError(f"articulate.vlm.answers: {bad} are not front labels (articulate.types door_labels, "
                                  "drawer_labels or front_labels): their votes would make a front an object")
