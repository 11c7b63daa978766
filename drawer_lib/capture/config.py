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
    optionally names a capture folder with true cameras to score the recovered poses against."""

    path: str = ""
    reference: str | None = None


@dataclass(frozen=True)
class DirSource:
    """An existing capture folder (docs/formats.md#capture), e.g. from nerfstudio's ns-process-data.
    ``metric_scale`` / ``gravity`` state whether its world frame is in metres / +z up."""

    path: str = ""
    metric_scale: bool = False
    gravity: bool = False


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
