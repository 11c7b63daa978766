"""Config of the ``twin`` stage (conf/twin/default.yaml): whether the physical checks run, the
opened-state renders and the shareable recording. The simulation model and its checks are the
``sim`` group (:class:`drawer_lib.sim.config.SimConfig`)."""

from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError
from drawer_lib.sim.repair import RepairConfig
from drawer_lib.viewer.config import RecordConfig


@dataclass(frozen=True)
class RendersConfig:
    """Opened-state renders (``twin/renders/``, docs/formats.md#renders): each part at ``open_fraction`` of its
    range in every test view (``max_views`` caps them; 0: all), SH degree ``sh_degree``, on a
    ``background`` RGB; ``lpips``: also score LPIPS (AlexNet) against the synthetic reference;
    ``sheet_width``: pixels per tile of the contact sheet (GT | twin, one row per part)."""

    open_fraction: float = 0.5
    max_views: int = 0
    sh_degree: int = 3
    background: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    lpips: bool = True
    sheet_width: int = 200

    def __post_init__(self):
        if not 0.0 < self.open_fraction <= 1.0:
            raise ConfigError(f"twin.renders.open_fraction = {self.open_fraction} must be in (0, 1]")
        if len(self.background) != 3 or not all(0.0 <= c <= 1.0 for c in self.background):
            raise ConfigError(f"twin.renders.background = {self.background} must be an RGB in [0, 1]")
        if self.max_views < 0 or not 0 <= self.sh_degree <= 3 or self.sheet_width < 16:
            raise ConfigError("twin.renders: need max_views >= 0, sh_degree in [0, 3], sheet_width >= 16")


@dataclass(frozen=True)
class TwinConfig:
    """``check``: run the physical checks; ``on_check_failure``: ``report`` writes the twin all the
    same and lists every failing part and check in ``checks.json``, ``twin.json`` (per part
    ``checks``) and the metrics (a part a few millimetres into the carcass must not cost the
    whole twin), ``error`` stops with the error naming them and writes nothing (a simulation
    that goes non-finite stops either way); ``repair``: a part a few millimetres into the static
    scene at q = 0 is freed by carving the static collision (:mod:`drawer_lib.sim.repair`);
    ``renders``: the opened-state renders;
    ``recording``: the shareable browser recording of every part opened in turn
    (``open_parts.html``)."""

    check: bool = True
    on_check_failure: str = "report"
    repair: RepairConfig = field(default_factory=RepairConfig)
    renders: RendersConfig = field(default_factory=RendersConfig)
    recording: RecordConfig = field(default_factory=RecordConfig)

    def __post_init__(self):
        if self.on_check_failure not in ("report", "error"):
            raise ConfigError(f"twin.on_check_failure = {self.on_check_failure!r} must be report or error")
