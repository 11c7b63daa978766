"""Config of the twin's simulation (conf/sim/default.yaml, the ``sim`` group): the MuJoCo option,
the joints and their drives, the densities, the contacts and the physical checks. The ``twin``
stage builds its exports with it, ``complete`` gives its bodies the densities, ``stability``
starts from its integrator and timestep. SI units."""

import math
from dataclasses import dataclass, field

from drawer_lib.errors import ConfigError


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ConfigError(msg)


@dataclass(frozen=True)
class JointConfig:
    """Joint and drive of one joint kind (SI units; "force" is N·m for revolute, N for
    prismatic; speeds rad/s or m/s).

    ``damping`` (force per unit speed), ``armature`` (reflected inertia, kg·m^2 or kg),
    ``frictionloss`` (dry friction force), ``speed`` (the drive's target speed and control
    limit). The drive is MuJoCo's velocity servo, force = kv (target - speed), with
    ``kv = (inertia about the joint + armature) / drive_tau``: every part, whatever its mass,
    reaches the target speed with the same time constant ``drive_tau`` (s) and the same
    acceleration, and the servo is never stiffer than the implicit integrator resolves
    (drive_tau >> timestep). The servo feeds the joint's ``damping`` forward (its gain on the
    target is kv + damping), so only the dry friction leaves the steady speed short of the
    target, by friction / ((kv + damping) speed). ``effort``: the drive's force limit (MJCF ``forcerange``, URDF ``<limit effort>``).
    ``friction_mu``: runner friction as a fraction of the part's weight (:meth:`friction`), so a
    heavy drawer whose reconstructed axis tilts down by less than atan(mu) stays shut."""

    damping: float
    armature: float
    frictionloss: float
    speed: float
    drive_tau: float = 0.02
    effort: float = 50.0
    friction_mu: float = 0.0

    def friction(self, mass: float, gravity: float) -> float:
        """The joint's dry friction force (N or N·m) for a part of ``mass`` kg: ``frictionloss``,
        or ``friction_mu`` x its weight when that is more (drawer runners carry the drawer)."""
        return max(self.frictionloss, self.friction_mu * mass * gravity)

    def __post_init__(self):
        for k in ("damping", "armature", "frictionloss", "friction_mu"):
            v = getattr(self, k)
            _check(math.isfinite(v) and v >= 0, f"joint.{k} = {v} must be finite and >= 0")
        _check(math.isfinite(self.speed) and self.speed > 0, f"joint.speed = {self.speed} must be > 0")
        _check(math.isfinite(self.drive_tau) and self.drive_tau > 0, f"joint.drive_tau = {self.drive_tau} must be > 0")
        _check(math.isfinite(self.effort) and self.effort > 0, f"joint.effort = {self.effort} must be > 0")


# Hinges: a cabinet hinge is lightly damped; 1 N·m·s/rad lets a 10 N·m pull swing a 0.5 m
# door open in well under a second (terminal speed 10 rad/s) yet stops a released door within
# a fraction of a turn; dry friction 0.05 N·m holds a door at rest against small disturbances
# (a real hinge has ~0.02-0.2 N·m). Drawer slides: ball-bearing runners roll with ~1 N dry
# friction (μ ~ 0.02-0.05 of a loaded drawer's weight: friction_mu 0.05, at least 1 N, which holds a
# drawer shut whose inferred axis tilts down by up to 2.9°) and ~10 N·s/m of viscous loss (a 20 N pull
# gives 2 m/s terminal speed, and a drawer pushed at 0.5 m/s coasts ~ m/c = 0.3 s).
# DRAWER's Isaac drives use damping 1e10 as an ideal velocity source; here the ideal velocity
# source is the servo (drive_tau) and the joint keeps realistic passive damping, so a person's
# pull (checks) and a robot see a plausible cabinet. Armature (a small reflected inertia) keeps
# light parts well conditioned; the revolute speed is DRAWER's 50 deg/s, prismatic 0.5 m/s.
def _revolute_default() -> "JointConfig":
    return JointConfig(damping=1.0, armature=0.005, frictionloss=0.05, speed=math.radians(50.0), drive_tau=0.02,
                       effort=20.0)


def _prismatic_default() -> "JointConfig":
    return JointConfig(damping=10.0, armature=0.05, frictionloss=1.0, speed=0.5, drive_tau=0.02, effort=150.0,
                       friction_mu=0.05)


@dataclass(frozen=True)
class DensityConfig:
    """Densities (kg/m^3) a stage gives the bodies it builds: ``part`` wood / MDF fronts and
    carcass interiors (MDF ~600-800, chipboard ~650), ``rigid`` household objects as solids
    (a filled cup's hull; ceramics ~2300 but hollow)."""

    part: float = 600.0
    rigid: float = 800.0

    def __post_init__(self):
        _check(self.part > 0 and self.rigid > 0, "densities: part and rigid must be > 0")


@dataclass(frozen=True)
class ContactConfig:
    """Contacts. ``part_static``: parts collide with the static scene; ``part_part``: parts collide
    with each other. Both on by default: the twin stage first trims what overlaps at q = 0
    (:mod:`drawer_lib.sim.repair`), so nothing is in contact as the file loads, and a door
    that swings into its neighbour stops there (the checks measure that stop). Off, a part's
    joint limits are its only stops and the checks measure overlaps geometrically. Rigid
    objects always collide with the static scene, parts and each other. ``friction`` sliding
    coefficient (wood on wood, ceramic on wood ~0.3-0.6), torsional and rolling as MuJoCo's
    defaults. ``limit_timeconst`` (s): the joint limits' constraint time constant (MuJoCo
    solref; >= 2 timesteps), short so a door slammed by a 10 N·m pull stops within 2° of its
    limit (MuJoCo's default 0.02 s lets it overshoot ~4°)."""

    part_static: bool = True
    part_part: bool = True
    friction: float = 0.6
    friction_torsion: float = 0.005
    friction_roll: float = 0.0001
    limit_timeconst: float = 0.004

    def __post_init__(self):
        _check(self.friction >= 0 and self.friction_torsion >= 0 and self.friction_roll >= 0,
               "contact: friction coefficients must be >= 0")
        _check(self.limit_timeconst > 0, "contact.limit_timeconst must be > 0")


@dataclass(frozen=True)
class CheckConfig:
    """Physical checks of a built twin (:func:`drawer_lib.sim.checks.check_twin`). Angles rad,
    lengths m, times s (simulated), forces N / N·m.

    Drive: with its velocity target at the drive speed every part reaches ``open_fraction`` of
    its upper limit within ``open_time`` (or 1.2 x range / speed when that is longer) and never
    passes the limit by more than ``drive_overshoot_rad`` / ``drive_overshoot_m``.
    Pull (the model as it loads): ``pull_force`` along a drawer's axis, ``pull_torque`` about a hinge
    open it to ``pull_fraction`` of its range within ``open_time``, overshoot <=
    ``pull_overshoot_rad`` / ``pull_overshoot_m``. Penetration: at q = 0 a part intersects the
    static scene or another part by <= ``penetration``; along its path (``path_samples`` poses in
    (0, hi]) the static scene by <= ``path_penetration``. Rest: rigid objects move <
    ``rest_drift`` in ``rest_time``, and parts (the model as it loads) open by less than
    ``rest_part_drift`` (m; rad x 0.5 m for a hinge). Stop: with every other part closed, a part opens until it
    first penetrates what it collides with (other parts with ``contact.part_part``, the static
    scene with ``contact.part_static``) by more than ``stop_depth``, found on ``stop_samples``
    poses in (0, hi] refined by bisection; the drive and pull tests then need their fractions of
    that stop, not of the joint range (a door that its neighbour stops opens as far as it really
    would), and a part whose stop is below ``min_travel`` of its range fails as blocked."""

    open_fraction: float = 0.95
    open_time: float = 3.0
    drive_overshoot_rad: float = math.radians(1.0)
    drive_overshoot_m: float = 0.001
    pull_force: float = 20.0
    pull_torque: float = 10.0
    pull_fraction: float = 0.9
    pull_overshoot_rad: float = math.radians(2.0)
    pull_overshoot_m: float = 0.005
    penetration: float = 0.002
    path_penetration: float = 0.002
    path_samples: int = 8
    rest_time: float = 2.0
    rest_drift: float = 0.01
    rest_part_drift: float = 0.005
    stop_depth: float = 0.0005
    stop_samples: int = 64
    min_travel: float = 0.5

    def __post_init__(self):
        _check(0 < self.open_fraction <= 1 and 0 < self.pull_fraction <= 1, "checks: fractions must be in (0, 1]")
        _check(self.open_time > 0 and self.rest_time > 0, "checks: open_time and rest_time must be > 0")
        _check(self.path_samples >= 1 and self.stop_samples >= 1, "checks.path_samples and stop_samples must be >= 1")
        _check(0.0 <= self.min_travel <= 1.0, f"checks.min_travel = {self.min_travel} must be in [0, 1]")
        for k in ("drive_overshoot_rad", "drive_overshoot_m", "pull_force", "pull_torque", "pull_overshoot_rad",
                  "pull_overshoot_m", "penetration", "path_penetration", "rest_drift", "stop_depth",
                  "rest_part_drift"):
            _check(getattr(self, k) >= 0, f"checks.{k} must be >= 0")


@dataclass(frozen=True)
class SimConfig:
    """Simulation of the twin (MuJoCo option and the joints, drives, densities, contacts and
    checks). ``timestep`` (s), ``integrator`` one of MuJoCo's (implicitfast integrates the
    velocity servos and joint damping implicitly, stable for any gain), ``gravity`` (m/s^2, along
    -z). ``flap_gravcomp``: the fraction of a flap's weight (a part hinged about an axis more
    than 45° from vertical) its mechanism carries (MuJoCo body ``gravcomp``): up-opening flaps
    ride on gas struts or lift fittings and down-opening ones on balancing springs, so a hand
    moves them as it moves a door; 0 leaves the bare panel (a tall lift-up flap then needs more
    than the 10 N·m pull to open). ``drives_on_load``: the parts' velocity servos act as the
    file loads (MJCF ``actuatorgroupdisable``; USD drives with their damping). Default off: the
    twin loads as a passive kitchen, and whoever drives its parts turns them on
    (:func:`drawer_lib.sim.mjcf.set_drives`; the simulate stage, the viewer and the drive check do)."""

    timestep: float = 0.002
    integrator: str = "implicitfast"
    gravity: float = 9.81
    flap_gravcomp: float = 1.0
    drives_on_load: bool = False
    revolute: JointConfig = field(default_factory=_revolute_default)
    prismatic: JointConfig = field(default_factory=_prismatic_default)
    densities: DensityConfig = field(default_factory=DensityConfig)
    contact: ContactConfig = field(default_factory=ContactConfig)
    checks: CheckConfig = field(default_factory=CheckConfig)

    def __post_init__(self):
        _check(0 < self.timestep <= 0.01, f"sim.timestep = {self.timestep} must be in (0, 0.01] s")
        _check(self.integrator in ("euler", "implicit", "implicitfast", "rk4"),
               f"sim.integrator = {self.integrator!r} must be euler, implicit, implicitfast or rk4")
        _check(math.isfinite(self.gravity) and self.gravity >= 0, "sim.gravity must be finite and >= 0")
        _check(0.0 <= self.flap_gravcomp <= 1.0, f"sim.flap_gravcomp = {self.flap_gravcomp} must be in [0, 1]")
        _check(self.contact.limit_timeconst >= 2 * self.timestep,
               f"sim.contact.limit_timeconst = {self.contact.limit_timeconst} must be >= 2 x timestep "
               f"({2 * self.timestep}) to stay stable")

    def joint(self, kind: str) -> JointConfig:
        return self.revolute if kind == "revolute" else self.prismatic
