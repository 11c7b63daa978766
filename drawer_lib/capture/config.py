"""Configs of the ``capture`` stage: the scene (conf/scene/<name>.yaml) and the capture group
(conf/capture/: split, rendering, simulated sensors, video processing)."""

from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError
from drawer_lib.sfm.config import VideoConfig
from drawer_lib.synth.config import DepthSensorConfig, DetectionsConfig, MonoConfig, RenderConfig, SynthConfig

SOURCES = ("synth", "video", "dir")


@dataclass(frozen=True)
class VideoSource:
    """A video file or a folder of images (paths relative to the project root). ``reference``
    optionally names a capture folder with true cameras to score the recovered poses against;
    ``counter_height_m`` is the worktop's height above the floor when the user measured it
    (it fixes the metric scale to about 1 %; without it a typical 0.91 m is assumed)."""

    path: str = ""
    reference: str | None = None
    counter_height_m: float | None = None

    def __post_init__(self):
        if self.counter_height_m is not None and not 0.3 < self.counter_height_m < 1.5:
            raise ConfigError(f"video.counter_height_m = {self.counter_height_m} m: a worktop's height above the "
                              "floor lies between 0.3 and 1.5 m")


@dataclass(frozen=True)
class DirSource:
    """An existing capture folder (docs/formats.md#capture), e.g. from nerfstudio's ns-process-data.
    ``metric_scale`` / ``gravity`` state whether its world frame is in metres / +z up (a
    Polycam, ARKit or Record3D capture as ``ns-process-data`` writes it is both). A depth map
    smaller than its image (a phone's LiDAR) is brought to the image's size on import by
    ``depth_upsample`` (``edge_aware``: guided by the RGB, with ``upsample_sigma_color`` on
    0-255 colours, interpolating among samples within ``upsample_same_surface`` (relative) of
    each other; ``nearest``: nerfstudio's), after its pixels of confidence below
    ``min_confidence`` (0 low, 1 medium, 2 high; 0 keeps all) are made invalid
    (:mod:`drawer_lib.io.rgbd`)."""

    path: str = ""
    metric_scale: bool = False
    gravity: bool = False
    depth_upsample: str = "edge_aware"
    min_confidence: int = 1
    upsample_sigma_color: float = 25.0
    upsample_same_surface: float = 0.03

    def __post_init__(self):
        from drawer_lib.io.rgbd import UPSAMPLE_METHODS

        if self.depth_upsample not in UPSAMPLE_METHODS:
            raise ConfigError(f"dir.depth_upsample = {self.depth_upsample!r} is not one of {UPSAMPLE_METHODS}")
        if self.min_confidence not in (0, 1, 2):
            raise ConfigError(f"dir.min_confidence = {self.min_confidence} must be 0, 1 or 2")
        if not self.upsample_sigma_color > 0:
            raise ConfigError(f"dir.upsample_sigma_color = {self.upsample_sigma_color} must be > 0")
        if not 0 <= self.upsample_same_surface < 1:
            raise ConfigError(f"dir.upsample_same_surface = {self.upsample_same_surface} must be in [0, 1)")


@dataclass(frozen=True)
class SceneConfig:
    """A scene file ``conf/scene/<name>.yaml``: the ``source`` and its block; a file writes only
    what differs from these defaults (a misspelt key is an error naming it). A ``synth`` scene
    without a ``synth`` block is the default procedural kitchen (:class:`SynthConfig`); ``video``
    and ``dir`` scenes need at least their ``path``::

        source: dir
        dir: {path: data/my_capture}          # metric_scale / gravity default to false
    """

    source: str = "synth"
    synth: SynthConfig | None = None
    video: VideoSource | None = None
    dir: DirSource | None = None

    def __post_init__(self):
        if self.source not in SOURCES:
            raise ConfigError(f"source = {self.source!r} is not one of {SOURCES}")
        if self.source == "synth" and self.synth is None:
            object.__setattr__(self, "synth", SynthConfig())
        if getattr(self, self.source) is None:
            raise ConfigError(f"source is {self.source!r} but there is no {self.source!r} block "
                              f"(e.g. {self.source}: {{path: data/...}})")


@dataclass(frozen=True)
class SplitConfig:
    test_every: int = 8  # every 8th frame is a test view (the first at index 4)

    def __post_init__(self):
        if self.test_every < 2:
            raise ConfigError(f"split.test_every = {self.test_every} must be >= 2")


@dataclass(frozen=True)
class CaptureConfig:
    split: SplitConfig = field(default_factory=SplitConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    depth: DepthSensorConfig = field(default_factory=DepthSensorConfig)
    mono: MonoConfig = field(default_factory=MonoConfig)
    detections: DetectionsConfig = field(default_factory=DetectionsConfig)
    video: VideoConfig = field(default_factory=VideoConfig)
