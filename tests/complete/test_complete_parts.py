"""A part's collision handle: the hull of what stands proud of its front, inside its rectangle."""

import numpy as np
import trimesh

from drawer_lib.complete.pipeline import _handle_hull
from drawer_lib.io.parts import Axis, Front, Part


def _door() -> Part:
    f = Front((0.0, 0.0, 0.5), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.4, 0.6))
    return Part("door_0", "revolute", Axis((-0.2, 0.0, 0.5), (0.0, 0.0, 1.0)), (0.0, 1.5), f)


def test_handle_hull_keeps_the_handle_and_drops_the_margin():
    panel = trimesh.creation.box((0.4, 0.02, 0.6)).apply_translation((0.0, 0.01, 0.5))
    handle = trimesh.creation.box((0.02, 0.03, 0.15)).apply_translation((0.15, -0.025, 0.5))  # 1-4 cm proud
    lip = trimesh.creation.box((0.6, 0.04, 0.03)).apply_translation((0.0, -0.02, 0.19))  # a counter lip below the front
    far = trimesh.creation.box((0.02, 0.02, 0.02)).apply_translation((0.0, -0.15, 0.5))  # 14-16 cm out: not a handle
    body = trimesh.util.concatenate([panel, handle, lip, far])
    (hull,) = _handle_hull(body, _door(), max_proud=0.08)
    v = hull.vertices
    lo, hi = v.min(0), v.max(0)
    np.testing.assert_allclose(lo, [0.14, -0.04, 0.425], atol=1e-9)
    np.testing.assert_allclose(hi, [0.16, -0.01, 0.575], atol=1e-9)
    # nothing proud inside the rectangle: no hull
    assert _handle_hull(trimesh.util.concatenate([panel, lip]), _door(), max_proud=0.08) == []
