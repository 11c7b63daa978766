"""Config of the video source: frames from a video, structure-from-motion, world frame."""

from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError
from drawer_lib.sfm.scale import ScaleConfig


@dataclass(frozen=True)
class VideoConfig:
    """How a video (or an image folder) becomes posed frames.

    Frames: every ``frame_step``-th frame, at most ``max_frames`` (evenly subsampled), resized
    so the longer side is at most ``max_image_size``; then in every window of
    round(1 / ``drop_blurriest``) consecutive frames the blurriest one (lowest variance of the
    Laplacian) is dropped. SfM: pycolmap SIFT features (``sift_peak_threshold`` below COLMAP's
    0.0067 keeps the low-contrast features of painted fronts and small frames: on kitchen_small
    0.002 gives ~4x the points and ~4x lower rotation error), ``matcher`` sequential (with
    ``overlap`` neighbours) or exhaustive, incremental mapping with one shared camera of model
    ``camera_model``, then undistortion to PINHOLE. Fails when fewer than
    ``min_registered_fraction`` of the kept frames register. ``num_threads`` = 1 keeps runs
    bit-reproducible (DVC caches them); -1 uses every core.

    World frame (RGB alone fixes neither gravity nor metric scale): +z is the direction most
    orthogonal to every camera's x axis (people hold cameras without roll), +y the mean
    horizontal viewing direction, the origin the median of the SfM points. The scale first puts
    the median point depth at ``assumed_median_depth_m``, then ``scale``
    (:class:`~drawer_lib.sfm.scale.ScaleConfig`) estimates it from what the reconstruction shows
    (the floor, the worktop, the cameras' height); the manifest records the estimate, its
    uncertainty and its cues, and calls the frame metric when the uncertainty (log) is at most
    ``scale.metric_sigma``.
    """

    frame_step: int = 1
    max_frames: int = 150
    max_image_size: int = 640
    drop_blurriest: float = 0.1
    camera_model: str = "SIMPLE_RADIAL"
    matcher: str = "sequential"
    overlap: int = 10
    max_num_features: int = 4096
    sift_peak_threshold: float = 0.002
    min_registered_fraction: float = 0.8
    assumed_median_depth_m: float = 1.8
    num_threads: int = 1
    scale: ScaleConfig = field(default_factory=ScaleConfig)

    def __post_init__(self):
        if self.frame_step < 1 or self.max_frames < 3:
            raise ConfigError("video.frame_step must be >= 1 and video.max_frames >= 3")
        if not 0 <= self.drop_blurriest < 0.5:
            raise ConfigError(f"video.drop_blurriest = {self.drop_blurriest} must be in [0, 0.5)")
        if self.camera_model not in ("SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV"):
            raise ConfigError(f"video.camera_model = {self.camera_model!r} is not supported")
        if self.matcher not in ("sequential", "exhaustive"):
            raise ConfigError(f"video.matcher = {self.matcher!r} must be sequential or exhaustive")
        if not 0 < self.min_registered_fraction <= 1:
            raise ConfigError("video.min_registered_fraction must be in (0, 1]")
        if self.assumed_median_depth_m <= 0:
            raise ConfigError("video.assumed_median_depth_m must be positive")
