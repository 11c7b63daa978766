"""DRAWER's interiors, for comparison (its ``isaac_sim/compose_usd.py``): every door gets a box
1.5 x its extent across its hinge deep and every drawer one 1.25 x its width deep, 2 cm walls,
whatever the cabinet."""

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from drawer_lib.complete.interiors.config import InteriorsConfig
from drawer_lib.complete.interiors.templates import Interior, build_template, check_part, template_kind
from drawer_lib.io.parts import Part

DRAWER_DOOR_FACTOR = 1.5  # DRAWER compose_usd.py: D = 1.5 s_y for revolute parts
DRAWER_DRAWER_FACTOR = 1.25  # and 1.25 s_y for prismatic ones
DRAWER_WALL = 0.02  # their wall thickness (m)


def drawer_rule_depth(part: Part) -> float:
    """DRAWER's fixed depth (``compose_usd.py``): 1.5 x the door's extent across its hinge (its
    width for a side-hinged door, its height for a flap) for revolute parts, 1.25 x the front's
    width for prismatic ones.

    >>> from drawer_lib.io.parts import Axis, Front
    >>> f = Front((0.0, 0.0, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.4, 0.7))
    >>> round(drawer_rule_depth(Part("d", "revolute", Axis((-0.2, 0.0, 0.5), (0.0, 0.0, -1.0)), (0.0, 1.5), f)), 6)
    0.6
    """
    check_part(part)
    f = part.front
    if part.kind == "prismatic":
        return DRAWER_DRAWER_FACTOR * f.size[0]
    across_u = abs(np.asarray(part.axis.direction) @ f.v) >= abs(np.asarray(part.axis.direction) @ np.asarray(f.u))
    return DRAWER_DOOR_FACTOR * (f.size[0] if across_u else f.size[1])


def drawer_rule_interiors(parts: Sequence[Part], cfg: InteriorsConfig, floor_z: float | None = None) -> list[Interior]:
    """DRAWER's interiors for comparison: the same templates at the fixed depth of
    :func:`drawer_rule_depth`, 2 cm walls, no shelves, right behind the front."""
    out = []
    for p in (p for p in parts if p.articulated):
        check_part(p)
        tmpl, _ = template_kind(p, floor_z, cfg.template)
        d = drawer_rule_depth(p)
        it = build_template(p, tmpl, cfg.template.front_thickness, d, cfg.template, wall=DRAWER_WALL, shelves=False)
        out.append(replace(it, record={"rule": "drawer", "depth": d}))
    return out
