"""Configs of the geometric core of the ``complete`` stage (conf/complete/*.yaml): cutting the
parts out of the scene mesh, the static collision boxes, and the rigid objects' solids.

Lengths in metres, angles in degrees, densities in kg/m^3.
"""

from dataclasses import dataclass, field

from drawer_lib.complete.grasp import HandleConfig
from drawer_lib.complete.interiors.config import InteriorsConfig
from drawer_lib.errors import ConfigError


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ConfigError(msg)


@dataclass(frozen=True)
class CutConfig:
    """Cutting the parts out of the scene mesh (:mod:`drawer_lib.complete.cut`).

    Body of an articulated part: the faces whose centroid lies in its front's slab, i.e. within
    the front rectangle grown by ``margin`` on every side, from ``back`` behind its outer face to
    ``protrusion`` in front of it (handles). A face two slabs claim goes to the part it lies
    deepest inside.

    Cavity: every remaining (static) face with its centroid or a vertex inside the part's swept
    volume is removed. The part's solid is the front rectangle times a depth behind its outer
    face: ``panel_thickness`` for a door, flap or sliding panel; for a drawer (a prismatic part
    moving within acos(``drawer_normal_cos``) of its outward normal) the depth of its box: the
    given depth, else the carcass depth (the part's ``carcass_depth`` or measured on the mesh)
    minus ``drawer_back_clearance``, else ``drawer_default_depth``; behind its front panel
    (``panel_thickness``) a drawer's box is the rectangle shrunk by ``drawer_inset`` on each
    side (it must not cut the carcass sides the front overlaps). The solid is swept over
    q in [min(0, lower), max(0, upper)] at samples close enough that each sampled box, grown by
    ``sweep_tol``, covers the motion to its neighbours (so the sampled union contains the exact
    swept volume); at most ``max_q_samples`` samples (the growth is raised to match then).
    """

    margin: float = 0.01
    back: float = 0.03
    protrusion: float = 0.08
    panel_thickness: float = 0.02
    drawer_normal_cos: float = 0.8
    drawer_default_depth: float = 0.5
    drawer_back_clearance: float = 0.01
    drawer_min_depth: float = 0.02
    drawer_inset: float = 0.05
    sweep_tol: float = 0.003
    max_q_samples: int = 2048

    def __post_init__(self):
        _check(self.margin >= 0, f"complete.cut.margin = {self.margin} must be >= 0")
        _check(self.back > 0 and self.protrusion >= 0, "complete.cut: need back > 0 and protrusion >= 0")
        _check(self.panel_thickness > 0, f"complete.cut.panel_thickness = {self.panel_thickness} must be > 0")
        _check(0 < self.drawer_normal_cos <= 1, "complete.cut.drawer_normal_cos must be in (0, 1]")
        _check(0 < self.drawer_min_depth <= self.drawer_default_depth,
               "complete.cut: need 0 < drawer_min_depth <= drawer_default_depth")
        _check(self.drawer_back_clearance >= 0 and self.drawer_inset >= 0,
               "complete.cut: drawer_back_clearance and drawer_inset must be >= 0")
        _check(self.sweep_tol > 0, f"complete.cut.sweep_tol = {self.sweep_tol} must be > 0")
        _check(self.max_q_samples >= 2, f"complete.cut.max_q_samples = {self.max_q_samples} must be >= 2")


@dataclass(frozen=True)
class StaticCollisionConfig:
    """Static collision boxes (:mod:`drawer_lib.complete.static_collision`).

    Frame: the grid is turned about +z by the mesh's dominant horizontal direction (the
    area-weighted histogram of the vertical faces' normal angles mod 90 degrees, faces within
    ``vertical_deg`` of vertical, ``yaw_bin_deg`` bins; ``align: false`` keeps the world axes).
    Grid: cells of ``cell`` over the visual mesh's extent plus ``margin_cells``, clipped to the
    field's box; a cell is occupied when the SDF at its centre is below ``iso`` (0: the surface).
    ``source: field`` (needs ``sdf/field.pt``) or ``mesh``: surface cells of the mesh, filled
    downward below up-facing surfaces (mean normal z > ``up_cos``) to the next surface below, a
    heuristic for captures without a field. Only occupied cells within ``shell_depth`` of the
    visual mesh are kept (0: all): an SDF is negative in space no camera saw, which has no
    visible surface to collide with; solid behind a visible surface stays that thick (its hidden
    back costs Chamfer: keep it to a few cells). Carving: cells whose centre lies within
    ``carve_inflate`` x ``cell`` of a swept volume or cavity are emptied. Connected islands of
    fewer than ``min_island_voxels`` cells are dropped (floaters). Merge: greedy along x, then
    y, then z into boxes; ``overlap: true`` lets a box grow over cells an earlier box covers
    (fewer, larger boxes; the union is the same); ``fill_tol``: a box may grow over a layer
    with up to this fraction of free cells (0: exact cover; more: fewer boxes over ragged
    surfaces). ``skins``: thin boxes (``skin_thickness``) under the visual mesh's up-facing
    surfaces (normal z >= ``skin_up_cos``) outside every carver, in ``skin_cell`` squares
    (:func:`~drawer_lib.complete.static_collision.surface_skins`): carving takes a one-cell
    counter with the cavity below it.
    """

    source: str = "field"
    cell: float = 0.04
    iso: float = 0.0
    margin_cells: int = 1
    align: bool = True
    vertical_deg: float = 30.0
    yaw_bin_deg: float = 0.5
    up_cos: float = 0.5
    shell_depth: float = 0.08
    carve_inflate: float = 1.0
    min_island_voxels: int = 4
    overlap: bool = True
    fill_tol: float = 0.0
    chunk: int = 200_000
    fidelity_points: int = 20_000
    skins: bool = True
    skin_cell: float = 0.02
    skin_thickness: float = 0.01
    skin_up_cos: float = 0.95

    def __post_init__(self):
        _check(self.source in ("field", "mesh"), f"complete.static.source = {self.source!r} must be field or mesh")
        _check(0.005 <= self.cell <= 0.5, f"complete.static.cell = {self.cell} must be in [0.005, 0.5] m")
        _check(self.margin_cells >= 0, "complete.static.margin_cells must be >= 0")
        _check(0 < self.vertical_deg < 90, "complete.static.vertical_deg must be in (0, 90)")
        _check(0 < self.yaw_bin_deg <= 5, "complete.static.yaw_bin_deg must be in (0, 5]")
        _check(-1 < self.up_cos < 1, "complete.static.up_cos must be in (-1, 1)")
        _check(0.005 <= self.skin_cell <= 0.5 and 0 < self.skin_thickness <= 0.1 and 0 < self.skin_up_cos < 1,
               "complete.static: need skin_cell in [0.005, 0.5] m, skin_thickness in (0, 0.1] m, skin_up_cos in (0, 1)")
        _check(self.shell_depth >= 0, "complete.static.shell_depth must be >= 0 (0: off)")
        _check(self.carve_inflate >= 0, "complete.static.carve_inflate must be >= 0")
        _check(0 <= self.fill_tol < 0.5, f"complete.static.fill_tol = {self.fill_tol} must be in [0, 0.5)")
        _check(self.min_island_voxels >= 0, "complete.static.min_island_voxels must be >= 0")
        _check(self.chunk >= 1000 and self.fidelity_points >= 100,
               "complete.static: need chunk >= 1000 and fidelity_points >= 100")


def _default_density() -> dict[str, float]:
    """Rough bulk densities (kg/m^3) of the closed solids of common kitchen objects (hollow
    objects count their enclosed air, hence the low values)."""
    return {"kettle": 300.0, "box": 200.0, "cup": 400.0, "mug": 400.0, "bowl": 400.0, "bottle": 500.0,
            "pot": 400.0, "pan": 600.0, "plate": 1200.0, "book": 700.0, "fruit": 950.0, "apple": 850.0,
            "can": 600.0, "jar": 600.0, "plant": 400.0, "vase": 500.0}


@dataclass(frozen=True)
class RigidConfig:
    """Rigid objects as closed solids (:mod:`drawer_lib.complete.rigid`).

    Faces: the perception-mesh faces of the part's segment; without labels, the faces whose
    centroid lies in its ``bounds`` grown by ``bounds_margin`` in x, y and more than
    ``above_support`` above their bottom. Support: the median height of the up-facing scene
    faces (normal within ``support_deg`` of +z) outside the shell, within ``support_xy`` of its
    footprint, from ``support_below`` under to ``support_above`` over the shell's lowest point
    (at least ``support_min_faces``; else the lowest point). Closing: boundary loops near the
    support (lowest point within ``bottom_band`` of it) or facing down (cap normal within
    ``bottom_deg`` of -z) are projected onto the support plane, extruded and capped; other holes
    are capped in place. The shell is "too broken" when over ``max_boundary_frac`` of its edges
    are boundary edges, it has more than ``max_loops`` loops or non-manifold edges: then, as
    when the closed result is not watertight, the solid is the convex hull of the shell and its
    footprint on the support. Mass: ``density`` by the part's top label, else
    ``default_density``. Collision: V-HACD (vhacdx) with at most ``max_hulls`` hulls of at most
    ``max_hull_vertices`` vertices at voxel ``resolution``.
    """

    bounds_margin: float = 0.01
    above_support: float = 0.005
    support_deg: float = 25.0
    support_xy: float = 0.03
    support_below: float = 0.1
    support_above: float = 0.02
    support_min_faces: int = 3
    bottom_band: float = 0.02
    bottom_deg: float = 60.0
    max_boundary_frac: float = 0.25
    max_loops: int = 20
    default_density: float = 800.0
    density: dict[str, float] = field(default_factory=_default_density)
    max_hulls: int = 8
    max_hull_vertices: int = 32
    resolution: int = 50_000
    fidelity_points: int = 5000

    def __post_init__(self):
        _check(self.bounds_margin >= 0 and self.above_support >= 0,
               "complete.rigid: bounds_margin and above_support must be >= 0")
        _check(0 < self.support_deg < 90 and 0 < self.bottom_deg < 90,
               "complete.rigid: support_deg and bottom_deg must be in (0, 90)")
        _check(self.support_below >= 0 and self.support_above >= 0 and self.support_xy >= 0,
               "complete.rigid: support_below, support_above, support_xy must be >= 0")
        _check(self.support_min_faces >= 1, "complete.rigid.support_min_faces must be >= 1")
        _check(self.bottom_band >= 0, "complete.rigid.bottom_band must be >= 0")
        _check(0 < self.max_boundary_frac <= 1, "complete.rigid.max_boundary_frac must be in (0, 1]")
        _check(self.max_loops >= 1, "complete.rigid.max_loops must be >= 1")
        _check(self.default_density > 0 and all(v > 0 for v in self.density.values()),
               "complete.rigid: densities must be > 0 kg/m^3")
        _check(1 <= self.max_hulls <= 256, f"complete.rigid.max_hulls = {self.max_hulls} must be in [1, 256]")
        _check(4 <= self.max_hull_vertices <= 1024, "complete.rigid.max_hull_vertices must be in [4, 1024]")
        _check(10_000 <= self.resolution <= 10_000_000, "complete.rigid.resolution must be in [1e4, 1e7]")
        _check(self.fidelity_points >= 100, "complete.rigid.fidelity_points must be >= 100")


@dataclass(frozen=True)
class GaussiansConfig:
    """The bodies' Gaussians: the appearance variant whose model they come from
    (``out/<scene>/appearance/<variant>/model``), and the flat Gaussians that cover the
    interiors (``spacing`` m between them, ``opacity``). ``cull_visible``: an interior Gaussian
    whose blend weight with every part closed exceeds this many pixels in any training view is
    dropped: the capture saw the closed scene, so a visible interior contradicts it (a wall
    poking out of the carcass, one drawn over a surface at a grazing angle); null keeps all."""

    variant: str = "movable_gs_ste"
    spacing: float = 0.02
    opacity: float = 0.95
    cull_visible: float | None = 0.02

    def __post_init__(self):
        _check(self.spacing > 0 and 0 < self.opacity <= 1, "complete.gaussians: need spacing > 0, opacity in (0, 1]")
        _check(self.cull_visible is None or self.cull_visible >= 0,
               f"complete.gaussians.cull_visible = {self.cull_visible} must be >= 0 pixels or null")


@dataclass(frozen=True)
class CompleteConfig:
    """The ``complete`` stage (conf/complete/default.yaml): cut, static collision, rigid solids,
    interiors, the bodies' Gaussians and the handles (:mod:`drawer_lib.complete.grasp`). ``sample_per_m2``: mesh points per m^2 the interiors
    measure their depths on; ``collision_clearance`` (m): a part's collision panel is inset by
    this on every side (reconstructed fronts abut and must not touch at q = 0)."""

    cut: CutConfig = field(default_factory=CutConfig)
    static: StaticCollisionConfig = field(default_factory=StaticCollisionConfig)
    rigid: RigidConfig = field(default_factory=RigidConfig)
    interiors: InteriorsConfig = field(default_factory=InteriorsConfig)
    gaussians: GaussiansConfig = field(default_factory=GaussiansConfig)
    handle: HandleConfig = field(default_factory=HandleConfig)
    sample_per_m2: float = 20000.0
    collision_clearance: float = 0.005

    def __post_init__(self):
        _check(self.sample_per_m2 > 0, "complete.sample_per_m2 must be > 0")
        _check(0 <= self.collision_clearance < 0.05, "complete.collision_clearance must be in [0, 0.05) m")
