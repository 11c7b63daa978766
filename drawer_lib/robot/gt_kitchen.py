"""The ground-truth kitchen as a physical model, for replaying the robot's demonstrations in it."""

import numpy as np

from drawer_lib.bodies import PartBody, RigidBody, TwinModel, mesh_shape
from drawer_lib.synth.layout import KitchenLayout


def layout_twin_model(layout: KitchenLayout, density_part: float = 600.0, density_rigid: float = 800.0
                      ) -> TwinModel:
    """The kitchen's own physical model (:class:`drawer_lib.bodies.TwinModel`), what a twin of
    it should have been: every piece of the static scene and of the fixed fronts and appliances
    a static collision solid, every articulated entity a part with its true joint and limits and
    its pieces (front panel, handle, box walls) as collision solids, every object a rigid body.
    Each piece is a closed convex primitive (a box, a cylinder, a handle bar) except the
    objects' (a cup's hollow), which collide as their hull. The robot stage's transfer runs the
    demonstrations planned in the twin here. Densities kg/m^3."""
    def shapes(e) -> list:
        return [mesh_shape(p.mesh.verts, p.mesh.faces) for p in e.pieces if len(p.mesh.faces)]

    static, parts, rigid = [], [], []
    for e in layout.entities:
        if e.articulated:
            parts.append(PartBody(e.name, "revolute" if e.joint == "hinge" else "prismatic",
                                  np.asarray(e.axis_origin, np.float64), np.asarray(e.axis_dir, np.float64),
                                  (float(e.limits[0]), float(e.limits[1])), [], shapes(e), density_part))
        elif e.joint == "free":
            rigid.append(RigidBody(e.name, [], shapes(e), density_rigid))
        else:
            static += shapes(e)
    return TwinModel([], static, parts, rigid).validate()
