"""Config of the twin's shareable recording (``twin.recording`` in conf/twin/default.yaml;
written by the ``twin`` stage as ``twin/open_parts.html`` and ``twin/open_parts.viser``)."""

import math
from dataclasses import dataclass

from drawer_lib.errors import ConfigError


@dataclass(frozen=True)
class RecordConfig:
    """``enabled``: write the recording; each part opens in ``seconds`` (and closes in as many),
    stays open ``hold`` seconds; ``fps`` frames per recorded second; ``min_scale`` (m) the
    smallest Gaussian scale sent to the browser (its covariances are float16)."""

    enabled: bool = True
    seconds: float = 1.0
    hold: float = 0.4
    fps: float = 30.0
    min_scale: float = 1e-3

    def __post_init__(self):
        for k in ("seconds", "fps", "min_scale"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"twin.recording.{k} = {v}: must be > 0")
        if not (math.isfinite(self.hold) and self.hold >= 0):
            raise ConfigError(f"twin.recording.hold = {self.hold}: must be >= 0")
