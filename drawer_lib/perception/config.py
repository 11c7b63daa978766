"""Configs of the ``decompose`` and ``articulate`` stages (conf/decompose/, conf/articulate/).
Lengths in metres, angles in degrees."""

import math
from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError


@dataclass(frozen=True)
class GeometricConfig:
    """The fallback without detections: vertical planar regions of the mesh (normals within
    ``vertical_deg`` of horizontal, grown over dihedral angles below ``smooth_deg``) of at least
    ``min_area`` m^2 are the candidate front planes; each is rasterised at ``cell`` and split
    into fronts along the gaps and steps between them, which the train images show as lines
    (multi-view colour gradient on the plane) and the mesh as depth steps."""

    vertical_deg: float = 20.0
    smooth_deg: float = 15.0
    min_area: float = 0.02
    cell: float = 0.01
    edge_quantile: float = 0.9
    min_front: float = 0.12


@dataclass(frozen=True)
class DecomposeConfig:
    """Detections -> 3D segments (DRAWER percept_stage1-6, reference §3.2-3.7).

    ``max_faces``: the mesh is decimated to this many faces first (DRAWER: 80k at full
    resolution), cut to what the train views see, then split until no edge exceeds ``max_edge``.
    ``erode_px``: masks are eroded before their faces are collected, unless that would remove
    half of a mask (DRAWER: 4 at 1080p). ``absorb_handles``: a handle mask (and the gap around
    it) joins the front mask around it first
    (:func:`~drawer_lib.perception.decompose.absorb_handles`). Graph: mesh-adjacent faces are joined with weight = the rate at which masks hold
    both (over the frames that see both); edges held by fewer than ``min_cooccur`` masks or in
    fewer than ``min_rate`` of those frames are dropped (this removes one-off false masks and the
    borders between fronts that merged masks bridge now and then), and so are edges whose
    dihedral angle exceeds ``max_dihedral``. ``separation``: the rate at which the two faces lie
    in different masks of one frame is subtracted first (cuts the border of a thin front that
    the neighbour's ragged masks overlap). Louvain (networkx, seeded)
    runs at every resolution in ``resolutions`` (a run over ``louvain_timeout_s`` seconds, a
    networkx round-off cycle, is retried with the next seed; <= 0: unbounded); communities of
    at least ``min_faces`` faces are candidates, and so are the connected components of the graph
    cut to the edges of weight >= each of ``component_rates`` (a large front that modularity
    splits at every resolution). Back-projection: a candidate's silhouette is compared in every frame that sees at
    least ``min_px_frac`` of the image area of it with the frame's masks, not counting the pixels
    within ``band_px`` of the silhouette's border; ``score`` = median best IoU, kept when
    >= ``min_score`` over >= ``min_frames`` frames. Greedy by score: a candidate more than
    ``dup_overlap`` of which better segments already hold is a duplicate.
    ``grow``: each segment is then completed from the whole (un-eroded) masks it matched, by a
    per-face majority over frames (:func:`~drawer_lib.perception.decompose.grow_segments`).
    Normal consistency: a segment is ``planar`` when >= ``planar_frac`` of its area is within
    ``planar_deg`` of its mean normal.
    ``source``: ``auto`` uses detections when the capture has them, else the geometric fallback;
    ``detections`` / ``geometric`` force one path."""

    source: str = "auto"
    max_faces: int = 40000
    max_edge: float = 0.06
    erode_px: int = 1
    absorb_handles: bool = True
    min_cooccur: int = 3
    min_rate: float = 0.3
    max_dihedral: float = 50.0
    separation: bool = True
    resolutions: list[float] = field(default_factory=lambda: [0.1, 0.5, 1.0, 2.0, 5.0, 10.0])
    component_rates: list[float] = field(default_factory=lambda: [0.5, 0.6, 0.7, 0.8])
    min_faces: int = 15
    min_px_frac: float = 0.0015
    band_px: int = 2
    min_score: float = 0.55
    min_frames: int = 2
    dup_overlap: float = 0.3
    grow: bool = True
    planar_deg: float = 30.0
    planar_frac: float = 0.6
    seed: int = 42
    louvain_timeout_s: float = 60.0
    geometric: GeometricConfig = field(default_factory=GeometricConfig)

    def __post_init__(self):
        if self.source not in ("auto", "detections", "geometric"):
            raise ConfigError(f"decompose.source = {self.source!r} must be auto, detections or geometric")
        if not self.resolutions or any(r <= 0 for r in self.resolutions):
            raise ConfigError(f"decompose.resolutions = {self.resolutions} must be positive numbers")
        if any(not 0 < r <= 1 for r in self.component_rates):
            raise ConfigError(f"decompose.component_rates = {self.component_rates} must lie in (0, 1]")
        if not math.isfinite(self.louvain_timeout_s):
            raise ConfigError(f"decompose.louvain_timeout_s = {self.louvain_timeout_s} must be finite (<= 0: no bound)")
        if not 0 < self.min_score <= 1 or not 0 < self.dup_overlap <= 1:
            raise ConfigError("decompose: min_score and dup_overlap must be in (0, 1]")
        if self.band_px < 0:
            raise ConfigError(f"decompose.band_px = {self.band_px} must be >= 0")
        if self.max_faces < 100 or self.min_faces < 1:
            raise ConfigError("decompose: max_faces >= 100 and min_faces >= 1")


@dataclass(frozen=True)
class ArticulateConfig:
    """Segments -> ``parts.json`` (DESIGN §5).

    ``estimator``: ``geometric`` (built in: plane, rectangle, handle and layout cues) or a learned
    one (``3doi``, ``vlm``: named slots that need unavailable weights/services; register one with
    :func:`drawer_lib.perception.articulate.register_estimator`). ``use_labels``: the detector's
    labels (majority over frames) may break the one tie geometry cannot (a top handle: drawer
    or bottom-hinged flap); they never decide a type on their own. Handles are mesh points
    ``handle_min``..``handle_max`` in front of the front plane within its rectangle (or faces
    that "handle" masks hit). A front smaller than ``min_size`` (either side) is not a part.
    Revolute limits default to ``revolute_limit_deg``; drawer travel is ``drawer_travel`` x the
    carcass depth the mesh shows behind the front (``default_depth`` when it shows none).
    Coplanar fronts whose facing edges lie within ``shared_edge_gap`` (m; 0 = off) of each
    other share one boundary: the mean of the two estimates. ``handle_evidence``: how a front
    picks its handle among the clusters of handle-mask faces on it: ``count`` (the most faces) or
    ``view_rate`` (default: the largest sum over its faces of the fraction of the views seeing a
    face in which a mask covers it; the fringe that ragged masks smear onto a neighbour weighs
    less than the pull). ``stacked_pulls``: a horizontal pull in the
    gap between a front and the one below it, which both take for their own, goes to the lower
    one (a lip pull); the upper one takes its next candidate
    (:func:`~drawer_lib.perception.articulate.resolve_stacked_pulls`)."""

    estimator: str = "geometric"
    use_labels: bool = True
    handle_min: float = 0.008
    handle_max: float = 0.08
    edge_frac: float = 0.3
    min_size: float = 0.08
    max_size: float = 1.6
    vertical_deg: float = 25.0
    revolute_limit_deg: float = 90.0
    drawer_travel: float = 0.8
    default_depth: float = 0.5
    sliding_step: list[float] = field(default_factory=lambda: [0.008, 0.06])
    shared_edge_gap: float = 0.025
    handle_evidence: str = "view_rate"
    stacked_pulls: bool = True

    def __post_init__(self):
        if len(self.sliding_step) != 2 or not 0 <= self.sliding_step[0] < self.sliding_step[1]:
            raise ConfigError(f"articulate.sliding_step = {self.sliding_step} must be [min, max] with 0 <= min < max")
        if not 0 < self.edge_frac < 0.5:
            raise ConfigError(f"articulate.edge_frac = {self.edge_frac} must be in (0, 0.5)")
        if not 0 < self.handle_min < self.handle_max:
            raise ConfigError("articulate: need 0 < handle_min < handle_max")
        if self.handle_evidence not in ("count", "view_rate"):
            raise ConfigError(f"articulate.handle_evidence = {self.handle_evidence!r} must be count or view_rate")
        if self.shared_edge_gap < 0:
            raise ConfigError(f"articulate.shared_edge_gap = {self.shared_edge_gap} must be >= 0 (0 turns it off)")
        if self.revolute_limit_deg <= 0 or self.drawer_travel <= 0:
            raise ConfigError("articulate: revolute_limit_deg and drawer_travel must be positive")
