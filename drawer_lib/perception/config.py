"""Config of the ``decompose`` stage (conf/decompose/). Lengths in metres, angles in degrees."""

import math
from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError
from drawer_lib.io.working import check_max_side


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
    """Detections -> 3D segments (DRAWER's official code: ``perception/percept_stage1.py`` to
    ``percept_stage6.py``).

    ``max_faces``: the mesh is decimated to this many faces first (DRAWER: 80k at full
    resolution), cut to what the train views see, then split until no edge exceeds ``max_edge``;
    ``snap`` > 0 rounds its vertices to that grid (m) before, so that a mesh another machine's
    last bits moved is simplified the same way.
    ``erode_px``: masks are eroded before their faces are collected, unless that would remove
    half of a mask (DRAWER: 4 at 1080p). ``absorb_handles``: a handle mask (and the gap around
    it) joins the front mask around it first
    (:func:`~drawer_lib.perception.decompose.absorb_handles`). Graph: mesh-adjacent faces are joined with weight = the rate at which masks hold
    both (over the frames that see both); edges held by fewer than ``min_cooccur`` masks or in
    fewer than ``min_rate`` of those frames are dropped (this removes one-off false masks and the
    borders between fronts that merged masks bridge now and then), and so are edges whose
    dihedral angle exceeds ``max_dihedral``. ``separation``: the rate at which the two faces lie
    in different masks of one frame is subtracted first (cuts the border of a thin front that
    the neighbour's ragged masks overlap). Louvain (seeded, bounded by work:
    at most ``louvain_max_sweeps`` passes over the nodes per level,
    :mod:`drawer_lib.perception.louvain`) runs at every resolution in ``resolutions``; communities of
    at least ``min_faces`` faces are candidates, and so are the connected components of the graph
    cut to the edges of weight >= each of ``component_rates`` (a large front that modularity
    splits at every resolution). Back-projection: a candidate's silhouette is compared in every frame that sees at
    least ``min_px_frac`` of the image area of it with the frame's masks, not counting the pixels
    within ``band_px`` of the silhouette's border; ``score`` = median best IoU, kept when
    >= ``min_score`` over >= ``min_frames`` frames. Greedy by score: a candidate more than
    ``dup_overlap`` of which better segments already hold is a duplicate.
    Missed views: a frame that sees both faces of an edge but none of whose masks holds either,
    or whose masks cover less than ``missing_cover`` of a candidate's silhouette, is a view
    where the detector found nothing; it counts ``missing_weight`` of a frame in the graph's
    rate and in the score's median (1: as a frame that keeps the faces apart, scoring 0;
    0: no evidence). A detector misses the same front in many views (a low score, a dark
    corner), so a front detected in a third of the views would otherwise never become a
    segment; a candidate still needs masks in ``min_detected`` of the frames that see it.
    ``grow``: each segment is then completed from the whole (un-eroded) masks it matched, by a
    per-face majority over frames (:func:`~drawer_lib.perception.decompose.grow_segments`).
    Normal consistency: a segment is ``planar`` when >= ``planar_frac`` of its area is within
    ``planar_deg`` of its mean normal.
    ``source``: ``auto`` uses detections when the capture has them, else the geometric fallback;
    ``detections`` / ``geometric`` force one path."""

    source: str = "auto"
    max_side: int | None = 640  # working resolution of the views and masks (drawer_lib/io/working.py); None: the capture's
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
    missing_weight: float = 0.0
    missing_cover: float = 0.1
    min_detected: float = 0.1
    dup_overlap: float = 0.3
    grow: bool = True
    planar_deg: float = 30.0
    planar_frac: float = 0.6
    seed: int = 42
    louvain_max_sweeps: int = 64
    snap: float = 0.0  # m: the mesh's vertices rounded to this grid before the simplification (0: off)
    mesh_jitter: float = 0.0  # stability studies only: Gaussian noise of this sigma (m) on the mesh's vertices first
    geometric: GeometricConfig = field(default_factory=GeometricConfig)

    def __post_init__(self):
        if self.source not in ("auto", "detections", "geometric"):
            raise ConfigError(f"decompose.source = {self.source!r} must be auto, detections or geometric")
        if not self.resolutions or any(r <= 0 for r in self.resolutions):
            raise ConfigError(f"decompose.resolutions = {self.resolutions} must be positive numbers")
        if any(not 0 < r <= 1 for r in self.component_rates):
            raise ConfigError(f"decompose.component_rates = {self.component_rates} must lie in (0, 1]")
        if not (self.snap >= 0 and math.isfinite(self.snap)):
            raise ConfigError(f"decompose.snap = {self.snap}: must be a finite value >= 0")
        if not (self.mesh_jitter >= 0 and math.isfinite(self.mesh_jitter)):
            raise ConfigError(f"decompose.mesh_jitter = {self.mesh_jitter}: must be a finite value >= 0")
        if self.louvain_max_sweeps < 1:
            raise ConfigError(f"decompose.louvain_max_sweeps = {self.louvain_max_sweeps} must be >= 1")
        if not 0 < self.min_score <= 1 or not 0 < self.dup_overlap <= 1:
            raise ConfigError("decompose: min_score and dup_overlap must be in (0, 1]")
        if not 0 <= self.missing_weight <= 1 or not 0 <= self.missing_cover <= 1 or not 0 <= self.min_detected <= 1:
            raise ConfigError(f"decompose: missing_weight = {self.missing_weight}, missing_cover = {self.missing_cover} "
                              f"and min_detected = {self.min_detected} must lie in [0, 1]")
        if self.band_px < 0:
            raise ConfigError(f"decompose.band_px = {self.band_px} must be >= 0")
        check_max_side("decompose.max_side", self.max_side)
        if self.max_faces < 100 or self.min_faces < 1:
            raise ConfigError("decompose: max_faces >= 100 and min_faces >= 1")
