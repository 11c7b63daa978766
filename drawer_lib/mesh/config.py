"""Config of the ``mesh`` stage (conf/mesh/*.yaml). Lengths in metres."""

from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError
from drawer_lib.mesh.clean import CleanConfig


@dataclass(frozen=True)
class MeshConfig:
    """``cell``: marching-cubes cell for neural fields (grid fields such as the TSDF are meshed
    on their own voxel grid); ``level``: the iso-level extracted; ``coarse_factor``: the SDF is
    evaluated on a grid this much coarser first and finely only near the surface;
    ``near``: the frustum near plane of the "seen by a train camera" mask;
    ``eval_points``: surface samples per mesh for the metrics (docs/formats.md#geometry)."""

    cell: float = 0.01
    level: float = 0.0
    coarse_factor: int = 4
    near: float = 0.05
    clean: CleanConfig = field(default_factory=CleanConfig)
    eval_points: int = 500_000

    def __post_init__(self):
        if not self.cell > 0:
            raise ConfigError(f"mesh.cell = {self.cell} must be > 0")
        if self.coarse_factor < 1 or self.eval_points < 1000:
            raise ConfigError("mesh: need coarse_factor >= 1 and eval_points >= 1000")
