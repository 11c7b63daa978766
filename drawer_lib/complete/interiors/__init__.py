"""Fitted interior templates behind articulated fronts (DRAWER's amodal interiors).

DRAWER gives every door a box 1.5 x its width deep and every drawer one 1.25 x its width deep
(``isaac_sim/compose_usd.py``, 2 cm walls), whatever the cabinet. Here the depth is *measured*
on the scene mesh and *fitted* jointly over the kitchen, and the template follows the part:

| part | template | body |
|---|---|---|
| prismatic along its outward normal | drawer: open-top box (bottom, front, back, sides) | the part |
| revolute, bottom hinge, lower edge near the floor | appliance: cavity, no shelves (oven) | static |
| other revolute (door, flap) | cabinet: back, sides, top, bottom + shelves | static |
| prismatic along the front's plane (sliding) | cabinet behind the other track (shallow) | static |

(near the floor: within ``appliance_max_bottom``; drawer: direction . normal >=
``drawer_normal_cos``; shelves: one per ``shelf_spacing`` of height.)

Frame: a part's template lives in its front's frame, origin at the centre of the front's outer
face, coordinates (a, b, z) along (u, v, -normal): z is the distance behind the outer face. A
template occupies z in [start, start + depth]: ``start`` = the front's thickness (plus the step
to a sliding partner's track in front of it), ``depth`` includes the back wall; its *free depth*
= start - front thickness + depth - wall = from the front's inner face to the back wall's inner
face. Shapes are world-frame boxes at q = 0 (all closed) with proper rotations [u, v, normal].

The modules, by job: ``templates`` (which template, its boxes, the
:class:`~drawer_lib.complete.interiors.templates.Interior` record),
``evidence`` (what the mesh and the other fronts say about the depth behind each front),
``fit`` (the joint fit of the depths and :func:`~drawer_lib.complete.interiors.fit.build_interiors`,
the whole step), ``drawer_rule`` (DRAWER's fixed depths, for comparison), ``texture`` (the
walls' colours) and ``config``.
"""
