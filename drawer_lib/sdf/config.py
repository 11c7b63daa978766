"""Configs of the ``sdf`` stage (conf/sdf/*.yaml): the neural SDF or the TSDF baseline.

Lengths are metres; loss weights multiply the named loss terms (0 turns a term off).
"""

from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError
from drawer_lib.io.working import check_max_side
from drawer_lib.sdf.monocal import MonoCalConfig


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ConfigError(msg)


@dataclass(frozen=True)
class EncodingConfig:
    """Multi-resolution grid: ``levels`` isotropic cell sizes from ``cell_coarse`` to
    ``cell_fine``, ``features`` per level, levels larger than 2**log2_table vertices hashed."""

    levels: int = 7
    features: int = 2
    cell_coarse: float = 0.24
    cell_fine: float = 0.015
    log2_table: int = 19
    backend: str = "numba"

    def __post_init__(self):
        _check(1 <= self.levels <= 16, f"encoding.levels = {self.levels} must be in [1, 16]")
        _check(0 < self.cell_fine <= self.cell_coarse, "encoding: need 0 < cell_fine <= cell_coarse")
        _check(10 <= self.log2_table <= 24, f"encoding.log2_table = {self.log2_table} must be in [10, 24]")
        _check(self.backend in ("numba", "torch"), f"encoding.backend = {self.backend!r} must be numba or torch")


@dataclass(frozen=True)
class NetworkConfig:
    """``init``: the geometric initialisation, an inside-out shape of radius the typical viewing
    depth around the train cameras: ``sphere`` (around their mean centre) or ``capsule``
    (around the segment their centres span along their principal axis, so every camera of a
    long path along a kitchen run starts in free space)."""

    hidden: int = 64
    geo_features: int = 15
    color_hidden: int = 64
    view_dependent: bool = True
    init: str = "capsule"

    def __post_init__(self):
        _check(self.init in ("sphere", "capsule"), f"network.init = {self.init!r} must be sphere or capsule")


@dataclass(frozen=True)
class SamplingConfig:
    """Rays: ``groups`` images x ``rays_per_group`` pixels per step (a group shares an image, as
    the scale-and-shift invariant depth loss needs). Samples: a cached coarse SDF grid (cell
    ``cache_cell``, refreshed every ``cache_every`` steps) finds each ray's first surface; ``fine``
    samples are placed around it within +- ``band`` (at least 4 beta) plus ``uniform`` stratified
    samples over the whole ray, which keep unseen surfaces discoverable.

    Depth points (metric depth only, loss ``depth_points``): each step also draws
    ``depth_points`` pixels with a valid depth from all train frames and queries the SDF, with
    no colour and no volume rendering, at each back-projected depth point (s = 0), at
    ``depth_band`` samples within [-band, +``depth_behind``] metres of it along the ray (a
    truncated projective SDF) and at ``depth_free`` samples in the free space in front of it
    (0 <= s <= distance to it). 0 turns them off."""

    groups: int = 8
    rays_per_group: int = 128
    fine: int = 16
    uniform: int = 8
    band: float = 0.06
    cache_cell: float = 0.04
    cache_every: int = 25
    near: float = 0.05
    depth_points: int = 2048
    depth_band: int = 2
    depth_free: int = 1
    depth_behind: float = 0.02

    def __post_init__(self):
        _check(self.groups >= 1 and self.rays_per_group >= 8, "sampling: need groups >= 1 and rays_per_group >= 8")
        _check(self.depth_points >= 0 and self.depth_band >= 0 and self.depth_free >= 0,
               "sampling: depth_points, depth_band and depth_free must be >= 0")
        _check(0 <= self.depth_behind <= self.band, "sampling: need 0 <= depth_behind <= band")
        _check(self.fine >= 2 and self.uniform >= 0, "sampling: need fine >= 2 and uniform >= 0")
        _check(self.cache_cell > 0 and self.cache_every >= 1 and self.band > 0, "sampling: cache_cell, band > 0")


@dataclass(frozen=True)
class LossWeights:
    """rgb: L1; eikonal: (|grad s| - 1)^2; depth: rendered z-depth L1 against metric sensor depth;
    depth_sdf: s = 0 at observed depth points and a truncated projective SDF in front of them
    (metric depth only, on the rendered rays); depth_points: the same SDF terms on the cheap
    depth points of ``sampling.depth_points`` (metric depth only); mono_depth: scale-and-shift invariant per group against the monocular
    prior; normal: L1 + (1 - cos) of rendered normals against the normal prior; sfm_depth:
    rendered depth at the pixels of SfM points (video captures)."""

    rgb: float = 1.0
    eikonal: float = 0.05
    depth: float = 0.5
    depth_sdf: float = 1.0
    depth_points: float = 1.0
    mono_depth: float = 0.5
    normal: float = 0.05
    sfm_depth: float = 0.5


@dataclass(frozen=True)
class PriorsConfig:
    """Which priors to use. ``depth``: auto (sensor if the capture has it, else monocular, else
    none) | sensor | mono | none; ``normal``: auto | mono | none. ``estimator`` selects the
    monocular estimator: ``capture`` reads the capture's mono_depth / mono_normal files (the
    built-in path); other names are slots for learned models (none ships weights here).
    ``calibrate_mono``: turn the monocular depth into metric depth by multi-view photometric
    calibration before training, then supervise like sensor depth (losses ``depth``,
    ``depth_sdf``, scaled by ``calibrated_weight``); the scale-and-shift invariant loss stays."""

    depth: str = "auto"
    normal: str = "auto"
    estimator: str = "capture"
    calibrate_mono: bool = True  # photometric metric calibration of mono depth (sdf/monocal.py)
    calibrated_weight: float = 1.0

    def __post_init__(self):
        _check(self.depth in ("auto", "sensor", "mono", "none"), f"priors.depth = {self.depth!r}")
        _check(self.normal in ("auto", "mono", "none"), f"priors.normal = {self.normal!r}")


@dataclass(frozen=True)
class BoundsConfig:
    """The reconstruction box: from metric depth or SfM points when the capture has them (robust
    0.05-99.95 % range plus ``margin``), else the camera frusta cut at ``far_factor`` times the
    depth where the optical axes meet."""

    margin: float = 0.25
    far_factor: float = 1.6


@dataclass(frozen=True)
class NeuralConfig:
    encoding: EncodingConfig = field(default_factory=EncodingConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    sampling: SamplingConfig = field(default_factory=SamplingConfig)
    losses: LossWeights = field(default_factory=LossWeights)
    priors: PriorsConfig = field(default_factory=PriorsConfig)
    bounds: BoundsConfig = field(default_factory=BoundsConfig)
    monocal: MonoCalConfig = field(default_factory=MonoCalConfig)
    steps: int = 2000
    max_seconds: float | None = None  # optional cap on training time incl. mono calibration; None: steps only
    budget_s: float = 300.0  # the target training time, reported (within_budget) not enforced
    lr_grid: float = 0.01
    lr_mlp: float = 0.002
    lr_final_factor: float = 0.1
    beta0: float = 0.05
    beta1: float = 0.002
    eval_every: int = 250
    eval_cell: float = 0.02  # marching-cubes cell of the quick meshes on the curve

    def __post_init__(self):
        _check(self.steps >= 1, f"neural.steps = {self.steps} must be >= 1")
        _check(self.max_seconds is None or self.max_seconds > 0,
               f"neural.max_seconds = {self.max_seconds} must be > 0 or null (no cap)")
        _check(0 < self.beta1 <= self.beta0, "neural: need 0 < beta1 <= beta0")
        _check(self.eval_every >= 1, "neural.eval_every must be >= 1")


@dataclass(frozen=True)
class TsdfConfig:
    """Open3D TSDF fusion (tensor VoxelBlockGrid) of the capture's metric depth."""

    voxel: float = 0.02
    trunc_voxels: float = 4.0
    depth_max: float = 6.0
    weight_threshold: float = 0.5
    block_count: int = 40000

    def __post_init__(self):
        _check(self.voxel > 0 and self.trunc_voxels > 0 and self.depth_max > 0, "tsdf: sizes must be positive")


@dataclass(frozen=True)
class SdfConfig:
    method: str = "neural"  # neural | tsdf
    max_side: int | None = 640  # working resolution: images reduced to at most this many px on their longer side (drawer_lib/io/working.py); None: the capture's
    neural: NeuralConfig = field(default_factory=NeuralConfig)
    tsdf: TsdfConfig = field(default_factory=TsdfConfig)

    def __post_init__(self):
        _check(self.method in ("neural", "tsdf"), f"sdf.method = {self.method!r} must be neural or tsdf")
        check_max_side("sdf.max_side", self.max_side)
