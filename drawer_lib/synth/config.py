"""Typed configs of the procedural kitchens and of the simulated sensors.

The YAML files under ``conf/scene/`` (``synth:``) and ``conf/capture/`` set every field; the
defaults here exist for tests and library use. Lengths in metres, angles in degrees where the
name says ``_deg``.
"""

from dataclasses import dataclass, field, fields

from drawer_lib.errors import ConfigError

BASE_TYPES = ("door", "double_door", "drawers", "drawer_door", "flap_down", "oven", "dishwasher")
WALL_TYPES = ("door", "double_door", "flap_up", "flap_down", "sliding", "sliding_single", "glass_door", "glass_double")
TALL_TYPES = ("split", "fridge1", "fridge2", "pantry")
FIXED_TYPES = ("appliance", "sink")
HANDLE_STYLES = ("bar", "knob", "edge", "small_knob", "recessed", "none")


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ConfigError(msg)


MODULE_WIDTH = (0.25, 1.2)  # m, a written module's width


def _check_modules(m: dict) -> None:
    """:attr:`LayoutConfig.modules` is well formed (its docstring), or a ConfigError naming the entry."""
    _check(set(m) <= {"base", "wall", "tall"}, f"layout.modules: unknown runs {sorted(set(m) - {'base', 'wall', 'tall'})} "
           "(base, wall, tall)")
    _check(bool(m.get("base")), "layout.modules.base: at least one base module is needed")
    runs = {}
    for run, known in (("base", BASE_TYPES + FIXED_TYPES), ("wall", WALL_TYPES)):
        total = 0.0
        for i, e in enumerate(m.get(run) or []):
            where = f"layout.modules.{run}[{i}] = {e!r}"
            _check(isinstance(e, (list, tuple)) and len(e) == 2, f"{where}: expected [type, width]")
            _check(e[0] in known, f"{where}: unknown type (known: {known})")
            _check(isinstance(e[1], (int, float)) and MODULE_WIDTH[0] <= e[1] <= MODULE_WIDTH[1],
                   f"{where}: width must be in [{MODULE_WIDTH[0]}, {MODULE_WIDTH[1]}] m")
            total += float(e[1])
        runs[run] = total
    _check(runs["wall"] <= runs["base"] + 1e-9,
           f"layout.modules: the wall run ({runs['wall']:.2f} m) is longer than the base run ({runs['base']:.2f} m)")
    sides = []
    for i, e in enumerate(m.get("tall") or []):
        where = f"layout.modules.tall[{i}] = {e!r}"
        _check(isinstance(e, (list, tuple)) and len(e) == 2 and e[0] in ("left", "right"),
               f"{where}: expected [left|right, type]")
        _check(e[1] in TALL_TYPES, f"{where}: unknown type (known: {TALL_TYPES})")
        _check(e[0] not in sides, f"{where}: a second tall unit on the {e[0]}")
        sides.append(e[0])


@dataclass(frozen=True)
class LayoutConfig:
    """What the kitchen is made of. Module types are drawn with the given weights.

    Base modules: door, double_door, drawers, drawer_door, flap_down, oven (a bottom-hinged
    appliance door over a drawer, under a control strip), dishwasher (a full-height
    bottom-hinged door); wall modules: door, double_door, flap_up, flap_down, sliding (two panels
    on two tracks), sliding_single (one panel on a rail in front of an open shelf: no partner
    to see); tall units: split (upper door over a drawer or door), fridge1 (one full-height
    door), fridge2 (fridge over freezer door), pantry (one full-height door with the kitchen's
    handle style). Handle styles (one per kitchen): bar, knob, edge, small_knob, recessed (a
    slot in the front), none; ``no_handle_p``: each front independently has no handle
    (push-to-open). ``microwaves``: microwave ovens on the counter (a side-hinged door), each
    turned by a yaw drawn from ``microwave_yaw_deg``; ``yaw_deg``: the whole kitchen turns by a
    yaw drawn from this range about the vertical (cabinets not aligned with the world axes);
    ``repeat_p``: each drawn base or wall module takes its left neighbour's type and width with
    this probability, so runs of equal modules appear as a planner lays them out (two singles
    where a double would do, a bank of drawers; fixed fronts, appliances and the only module of
    a required type are neither copied nor replaced).
    The defaults of the keys added after the first release (tall_types, tall_width,
    microwaves, microwave_yaw_deg, yaw_deg, no_handle_p, repeat_p, modules) leave earlier kitchens unchanged.

    ``modules`` writes the kitchen by hand instead of drawing it: ``base`` and ``wall`` are the
    runs from left to right as ``[type, width m]`` (base types and ``appliance`` / ``sink``, the
    fixed fronts; widths 0.25 to 1.2 m), ``tall`` the tall units as ``[side, type]`` (left /
    right, at most one each). The wall run is centred over the base run and must not be longer.
    The counts, type weights and widths above are then not read; materials, hinge sides,
    handles (one of ``handle_styles``, ``no_handle_p``), appliances' doors, microwaves, objects
    and the yaw are still drawn from the seed.
    """

    base_modules: int = 4
    wall_modules: int = 3
    tall_units: int = 1
    fixed_fronts: int = 1  # appliance fronts / sink units with a false drawer (GT ignore_boxes)
    n_objects: int = 3  # rigid objects on the counter
    module_widths: list[float] = field(default_factory=lambda: [0.4, 0.45, 0.5, 0.6])
    double_widths: list[float] = field(default_factory=lambda: [0.8, 0.9])
    base_types: dict[str, float] = field(default_factory=lambda: {
        "door": 2.0, "double_door": 1.0, "drawers": 2.0, "drawer_door": 1.5, "flap_down": 0.3})
    wall_types: dict[str, float] = field(default_factory=lambda: {
        "door": 2.0, "double_door": 1.0, "flap_up": 1.5, "flap_down": 0.3, "sliding": 1.0})
    require_types: list[str] = field(default_factory=lambda: ["drawers", "door", "flap_up", "sliding"])
    handle_styles: list[str] = field(default_factory=lambda: ["bar", "knob", "edge"])
    revolute_limits_deg: list[float] = field(default_factory=lambda: [90.0, 110.0])
    base_depth: float = 0.58
    carcass_height: float = 0.72
    plinth_height: float = 0.10
    counter_thickness: float = 0.04
    wall_bottom: float = 1.45
    wall_height: float = 0.70
    wall_depth: float = 0.33
    tall_height: float = 2.05  # tall units' carcass height above the plinth
    front_gap: float = 0.003
    front_thickness: float = 0.019
    tall_types: dict[str, float] = field(default_factory=lambda: {"split": 1.0})
    tall_width: float = 0.6
    microwaves: int = 0
    microwave_yaw_deg: list[float] = field(default_factory=lambda: [-35.0, 35.0])
    yaw_deg: list[float] = field(default_factory=lambda: [0.0, 0.0])
    no_handle_p: float = 0.0
    repeat_p: float = 0.0
    modules: dict[str, list[list[str | float]]] | None = None

    def __post_init__(self):
        if self.modules is not None:
            _check_modules(self.modules)
        _check(self.base_modules >= 1, f"layout.base_modules = {self.base_modules} must be >= 1")
        _check(self.wall_modules >= 0, f"layout.wall_modules = {self.wall_modules} must be >= 0")
        _check(0 <= self.tall_units <= 2, f"layout.tall_units = {self.tall_units} must be 0, 1 or 2")
        _check(0 <= self.fixed_fronts <= self.base_modules,
               f"layout.fixed_fronts = {self.fixed_fronts} must be in [0, base_modules]")
        _check(self.n_objects >= 0, f"layout.n_objects = {self.n_objects} must be >= 0")
        for k in self.base_types:
            _check(k in BASE_TYPES, f"layout.base_types: unknown type {k!r} (known: {BASE_TYPES})")
        for k in self.wall_types:
            _check(k in WALL_TYPES, f"layout.wall_types: unknown type {k!r} (known: {WALL_TYPES})")
        for k in self.require_types:
            _check(k in BASE_TYPES or k in WALL_TYPES, f"layout.require_types: unknown type {k!r}")
        for s in self.handle_styles:
            _check(s in HANDLE_STYLES, f"layout.handle_styles: unknown style {s!r} (known: {HANDLE_STYLES})")
        _check(bool(self.handle_styles), "layout.handle_styles is empty")
        for k in self.tall_types:
            _check(k in TALL_TYPES, f"layout.tall_types: unknown type {k!r} (known: {TALL_TYPES})")
        _check(any(w > 0 for w in self.tall_types.values()), "layout.tall_types: no type has a positive weight")
        _check(0.4 <= self.tall_width <= 1.0, f"layout.tall_width = {self.tall_width} must be in [0.4, 1.0] m")
        _check(0 <= self.microwaves <= 3, f"layout.microwaves = {self.microwaves} must be in [0, 3]")
        for name in ("microwave_yaw_deg", "yaw_deg"):
            r = getattr(self, name)
            _check(len(r) == 2 and -90.0 <= r[0] <= r[1] <= 90.0, f"layout.{name} = {r} must be [lo, hi] within [-90, 90]")
        _check(0.0 <= self.no_handle_p < 1.0, f"layout.no_handle_p = {self.no_handle_p} must be in [0, 1)")
        _check(0.0 <= self.repeat_p <= 1.0, f"layout.repeat_p = {self.repeat_p} must be in [0, 1]")
        _check(bool(self.module_widths) and all(0.25 <= w <= 1.0 for w in self.module_widths),
               f"layout.module_widths {self.module_widths} must be in [0.25, 1.0] m")
        _check(0 < self.front_gap < 0.02, f"layout.front_gap = {self.front_gap} must be in (0, 0.02) m")
        _check(self.wall_bottom > self.plinth_height + self.carcass_height + self.counter_thickness + 0.3,
               "layout.wall_bottom leaves no room above the counter")
        _check(self.carcass_height + 0.5 < self.tall_height < 2.5 - self.plinth_height,
               f"layout.tall_height = {self.tall_height} must exceed the base cabinets and fit under the ceiling")


LAYOUT_KEYS = frozenset(f.name for f in fields(LayoutConfig))  # the keys a layout block (or an override of one) may set


@dataclass(frozen=True)
class CameraPathConfig:
    """A hand-held walk in front of the kitchen: ``passes`` smooth sweeps along the run."""

    n_frames: int = 48
    width: int = 200
    height: int = 150
    fovy_deg: float = 62.0
    distance: list[float] = field(default_factory=lambda: [1.25, 1.9])  # from the fronts
    eye_height: list[float] = field(default_factory=lambda: [1.2, 1.65])
    passes: int = 2
    margin: float = -0.2  # how far past the run's ends the sweep reaches (< 0: stays inside)
    jitter_pos_m: float = 0.012
    jitter_rot_deg: float = 0.8

    def __post_init__(self):
        _check(self.n_frames >= 4, f"camera.n_frames = {self.n_frames} must be >= 4")
        _check(16 <= self.width <= 4096 and 16 <= self.height <= 4096,
               f"camera size {self.width}x{self.height} out of range")
        _check(10.0 < self.fovy_deg < 150.0, f"camera.fovy_deg = {self.fovy_deg} out of (10, 150)")
        _check(len(self.distance) == 2 and 0.3 < self.distance[0] <= self.distance[1],
               f"camera.distance {self.distance} must be [min, max] with min > 0.3 m")
        _check(len(self.eye_height) == 2 and 0.2 < self.eye_height[0] <= self.eye_height[1] < 2.4,
               f"camera.eye_height {self.eye_height} must be [min, max] within the room")
        _check(self.passes >= 1, "camera.passes must be >= 1")


@dataclass(frozen=True)
class SynthConfig:
    seed: int = 0
    layout: LayoutConfig = field(default_factory=LayoutConfig)
    camera: CameraPathConfig = field(default_factory=CameraPathConfig)


# ---------------------------------------------------------------------------------------------
# simulated sensors (conf/capture/{depth,mono,detections}/*.yaml)


@dataclass(frozen=True)
class DepthSensorConfig:
    """Metric depth like a structured-light / ToF sensor. With ``exact`` the depth is the
    rendered z-depth quantised to ``unit_scale`` and nothing else.

    Axial noise sigma(z) = sigma_base + sigma_quad (z - z_ref)^2 (Nguyen et al. 2012 for a
    Kinect: 0.0012 + 0.0019 (z - 0.4)^2); holes beyond the range, at grazing angles (a soft band
    starting ``grazing_band_deg`` below ``grazing_deg``), within ``edge_px`` of depth
    discontinuities larger than ``edge_jump`` (relative), and random dropout.
    """

    enabled: bool = True
    exact: bool = False
    unit_scale: float = 0.001
    sigma_base: float = 0.0012
    sigma_quad: float = 0.0019
    z_ref: float = 0.4
    min_range: float = 0.3
    max_range: float = 6.0
    grazing_deg: float = 80.0
    grazing_band_deg: float = 8.0
    edge_jump: float = 0.04
    edge_px: int = 1
    dropout: float = 0.005

    def __post_init__(self):
        _check(0 < self.unit_scale <= 0.01, f"depth.unit_scale = {self.unit_scale} must be in (0, 0.01]")
        _check(self.sigma_base >= 0 and self.sigma_quad >= 0, "depth noise must be >= 0")
        _check(0 <= self.dropout < 1, f"depth.dropout = {self.dropout} must be in [0, 1)")
        _check(0 < self.min_range < self.max_range, "depth range must satisfy 0 < min < max")
        _check(0 < self.grazing_deg <= 90, f"depth.grazing_deg = {self.grazing_deg} must be in (0, 90]")


@dataclass(frozen=True)
class MonoConfig:
    """Monocular priors as an estimator (Marigold-like) gives them.

    Relative depth: the z-depth blurred by ``depth_blur_px``, multiplied by a smooth field
    1 + ``depth_warp`` * w(u, v) (low-frequency), with relative noise ``depth_noise``, then
    normalised per frame to [0, 1] (an unknown per-frame scale and shift). Normals: the true
    camera-frame normals rotated by a smooth random field of ``normal_noise_deg`` and blurred
    by ``normal_blur_px`` (which also smears them across depth edges), with the structured
    errors of real estimators: every normal of a frame rotated together by ``normal_bias_deg``
    about a random axis (a per-frame tilt), and pulled toward facing the camera by
    ``normal_frontal_pull`` of the way (estimators flatten slanted surfaces). ``exact`` turns
    off blur, warp, bias and noise (the per-frame normalisation stays).
    """

    depth_enabled: bool = True
    normal_enabled: bool = True
    exact: bool = False
    depth_blur_px: float = 1.0
    depth_warp: float = 0.04
    depth_noise: float = 0.005
    normal_noise_deg: float = 4.0
    normal_blur_px: float = 1.0
    normal_bias_deg: float = 0.0
    normal_frontal_pull: float = 0.0

    def __post_init__(self):
        _check(0 <= self.depth_warp < 0.5, f"mono.depth_warp = {self.depth_warp} must be in [0, 0.5)")
        _check(self.depth_noise >= 0 and self.normal_noise_deg >= 0, "mono noise must be >= 0")
        _check(0 <= self.normal_bias_deg < 90, f"mono.normal_bias_deg = {self.normal_bias_deg} must be in [0, 90)")
        _check(0 <= self.normal_frontal_pull < 1,
               f"mono.normal_frontal_pull = {self.normal_frontal_pull} must be in [0, 1)")


@dataclass(frozen=True)
class DetectionsConfig:
    """2D instance masks as a detector + segmenter (Grounded-SAM-like) gives them.

    Per frame: each visible instance is missed with ``p_miss`` (always when smaller than
    ``min_area_px``); touching fronts are merged into one mask with ``p_merge`` per pair;
    masks are eroded or dilated by up to ``ragged_px`` and their boundary jittered by
    ``boundary_noise_px``; ``false_rate`` false masks per frame (Poisson) appear on static
    surfaces; ids are shuffled per frame. ``labels``: ``typed`` (drawer/door/handle/cup/...,
    with drawer <-> door swaps at ``label_confusion``) or ``generic`` (front/handle/object).

    Failures of a real detector that persist across views, decided once per capture and per
    part in 3D (all off by default): a part is never detected (``p_never``) or detected in only
    ``sparse_keep`` of the views that see it (``p_sparse``); two fronts that touch in 3D are one
    mask in ``merge_views`` of the views where both are seen (``p_merge_part`` per touching pair);
    a front's handle is never found (``p_no_handle``); a front's typed label is swapped drawer
    <-> door in every view (``p_label_part``); ``n_false_fronts`` rectangles fixed on static
    surfaces (a window, an appliance panel) are detected as fronts wherever they are seen.
    """

    enabled: bool = True
    labels: str = "typed"
    p_miss: float = 0.08
    p_merge: float = 0.05
    ragged_px: int = 2
    boundary_noise_px: float = 1.5
    false_rate: float = 0.3
    label_confusion: float = 0.1
    detect_handles: bool = True
    min_area_px: int = 30
    score_range: list[float] = field(default_factory=lambda: [0.45, 0.98])
    p_never: float = 0.0
    p_sparse: float = 0.0
    sparse_keep: float = 0.25
    p_merge_part: float = 0.0
    merge_views: float = 0.8
    p_no_handle: float = 0.0
    p_label_part: float = 0.0
    n_false_fronts: int = 0

    def __post_init__(self):
        _check(self.labels in ("typed", "generic"), f"detections.labels = {self.labels!r} must be typed or generic")
        _check(self.n_false_fronts >= 0, f"detections.n_false_fronts = {self.n_false_fronts} must be >= 0")
        for k in ("p_miss", "p_merge", "label_confusion", "p_never", "p_sparse", "sparse_keep", "p_merge_part",
                  "merge_views", "p_no_handle", "p_label_part"):
            v = getattr(self, k)
            _check(0 <= v <= 1, f"detections.{k} = {v} must be in [0, 1]")
        _check(self.false_rate >= 0 and self.ragged_px >= 0 and self.boundary_noise_px >= 0,
               "detections noise parameters must be >= 0")

    @property
    def persistent(self) -> bool:
        """Whether any failure persists across views."""
        return (self.p_never > 0 or self.p_sparse > 0 or self.p_merge_part > 0 or self.p_no_handle > 0
                or self.p_label_part > 0 or self.n_false_fronts > 0)

    @property
    def perfect(self) -> bool:
        return (self.p_miss == 0 and self.p_merge == 0 and self.ragged_px == 0
                and self.boundary_noise_px == 0 and self.false_rate == 0 and self.label_confusion == 0
                and not self.persistent)


@dataclass(frozen=True)
class RenderConfig:
    """MuJoCo offscreen rendering (EGL or OSMesa: the ``MUJOCO_GL`` environment variable)."""

    multisamples: int = 4
    shadow_size: int = 2048

    def __post_init__(self):
        _check(self.multisamples in (0, 1, 2, 4, 8, 16), f"render.multisamples = {self.multisamples}")
