"""The type decision on analytic fixtures of the cases our first rule got wrong on kitchens our
generator did not make (issue 17), with the shipped config (conf/articulate/default.yaml, the
weights fitted on the train split): a full-height door, an oven door hinged at the bottom with
its bar near the top edge under generic labels, a sliding door without a partner on a rail,
drawers whose small knobs the mesh does not show, and a microwave door turned on the counter."""

from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

from drawer_lib.articulation.config import ArticulateConfig
from drawer_lib.articulation.infer import infer_parts
from drawer_lib.articulation.scoring import COMMON, DOOR_ONLY, Evidence, door_features, features, rail_extent, score
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Front
from drawer_lib.perception.decompose import Segment, face_geometry

ROOT = Path(__file__).resolve().parents[2]
CFG = to_typed(ArticulateConfig, yaml.safe_load((ROOT / "conf/articulate/default.yaml").read_text()), "articulate")
GENERIC = {"front": 30}


def box(lo, hi, subdivide: int = 0) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))
    for _ in range(subdivide):
        m = m.subdivide()
    return m


def handle_box(x, z, y, kind: str, length: float = 0.16) -> trimesh.Trimesh:
    """A bar (h | v, 2 cm thick) or a knob standing 2.3-3.5 cm proud of a front whose outer face
    is at y."""
    half = {"h": (length / 2, 0.01), "v": (0.01, length / 2), "knob": (0.012, 0.012)}[kind]
    return box([x - half[0], y - 0.035, z - half[1]], [x + half[0], y - 0.023, z + half[1]], 2)


class Scene:
    """Fronts (panels 19 mm thick, outer face at y, facing -y) in front of a floor and a wall,
    plus static boxes; the whole turned by ``yaw_deg`` about the vertical through the origin."""

    def __init__(self):
        self.meshes = [box([-1.5, -3.0, -0.02], [2.5, 0.02, 0.0]), box([-1.5, 0.0, 0.0], [2.5, 0.02, 2.5])]
        self.fronts: list[tuple[int, int]] = []  # (mesh index, not used)

    def front(self, x0, x1, z0, z1, y, handle=None) -> None:
        self.fronts.append(len(self.meshes))
        self.meshes.append(box([x0, y, z0], [x1, y + 0.019, z1], 3))
        if handle is not None:
            self.meshes.append(handle_box(*handle[:2], y, *handle[2:]))

    def static(self, lo, hi) -> None:
        self.meshes.append(box(lo, hi, 2))

    def run(self, labels=GENERIC, support=40, yaw_deg=0.0, cfg=CFG):
        R = trimesh.transformations.rotation_matrix(np.deg2rad(yaw_deg), [0, 0, 1])
        offs = np.cumsum([0] + [len(m.faces) for m in self.meshes])
        mesh = trimesh.util.concatenate(self.meshes)
        mesh.apply_transform(R)
        n, c = np.asarray(mesh.face_normals), np.asarray(mesh.triangles_center)
        out = R[:3, :3] @ np.array([0.0, -1.0, 0.0])
        segs = []
        for k, mi in enumerate(self.fronts):
            f = np.arange(offs[mi], offs[mi + 1])
            f = f[n[f] @ out > 0.99]  # the panel's outer face
            nrm, area, cen, frac = face_geometry(mesh, f, 30.0)
            segs.append(Segment(k, f, 1.0, support, dict(labels), frac > 0.6, nrm, area, cen))
        cams = (R[:3, :3] @ np.array([[0.3, -2.5, 1.2], [-0.6, -2.2, 1.5], [1.2, -2.4, 0.9]]).T).T
        parts, rep = infer_parts(mesh, segs, cams, cfg)
        by_seg = {p.extra["segment"]: p for p in parts}
        return [by_seg.get(k) for k in range(len(self.fronts))], rep, R[:3, :3]


def test_a_full_height_door_is_a_door_not_dropped_for_its_size():
    s = Scene()
    s.front(0.0, 0.6, 0.1, 2.1, -0.6, (0.555, 1.1, "v", 0.6))  # a fridge / pantry door, 2.0 m
    (p,), rep, _ = s.run()
    assert p is not None, rep
    assert p.kind == "revolute" and p.extra["hinge"] == "left"
    assert p.front.size == pytest.approx((0.6, 2.0), abs=0.03)
    assert np.allclose(p.axis.direction, [0, 0, -1], atol=1e-3)


def test_an_oven_door_with_a_top_bar_is_a_bottom_hinged_flap_under_generic_labels():
    s = Scene()
    s.front(0.0, 0.6, 0.1, 0.24, -0.6, (0.3, 0.19, "h", 0.3))  # the storage drawer below
    # the oven door, 0.6 x 0.56 (a 0.3 m bar: a 0.45 m box bar on this coarse fixture mesh breaks
    # into pieces and its heaviest piece sits off-centre, a limit of the handle clustering)
    s.front(0.0, 0.6, 0.243, 0.8, -0.6, (0.3, 0.745, "h", 0.3))
    s.static([0.0, -0.6, 0.803], [0.6, -0.581, 0.9])  # the control strip above
    (drawer, oven), rep, _ = s.run()
    assert drawer is not None and drawer.extra["family"] == "drawer", rep
    assert oven is not None and oven.kind == "revolute" and oven.extra["hinge"] == "bottom", rep
    assert np.allclose(oven.axis.origin, [0.3, -0.6, 0.243], atol=0.02)


def test_a_sliding_door_without_a_partner_slides_over_the_open_shelf():
    s = Scene()
    y = -0.39  # the panel on its own track, in front of a 0.35 m deep wall cabinet (x 0 .. 0.9)
    s.static([0.0, -0.35, 1.45], [0.018, 0.0, 2.15])
    s.static([0.882, -0.35, 1.45], [0.9, 0.0, 2.15])
    s.static([0.0, -0.35, 1.45], [0.9, 0.0, 1.468])
    s.static([0.0, -0.35, 1.78], [0.9, -0.008, 1.798])  # the shelf in the open half
    s.static([0.0, -0.402, 2.12], [0.9, -0.35, 2.15])  # the rail, the cabinet's full width
    s.front(0.0015, 0.46, 1.4515, 2.117, y, (0.045, 1.78, "v", 0.13))  # pull by the left edge
    (p,), rep, _ = s.run()
    assert p is not None and p.extra["family"] == "sliding", rep
    assert np.allclose(p.axis.direction, [1, 0, 0], atol=1e-3)  # toward the open half
    assert 0.3 < p.limits[1] < 0.5


def test_drawers_whose_knobs_the_mesh_does_not_show_are_still_drawers():
    s = Scene()
    for z0, z1 in ((0.1, 0.33), (0.333, 0.56), (0.563, 0.79)):  # a stack, no handle visible
        s.front(0.0, 0.5, z0, z1, -0.6)
    parts, rep, _ = s.run()
    assert all(p is not None and p.extra["family"] == "drawer" for p in parts), rep


@pytest.mark.parametrize("yaw", [0.0, 30.0, -40.0])
def test_a_microwave_door_turned_on_the_counter_is_hinged_at_its_left_edge(yaw):
    s = Scene()
    s.static([0.0, -0.5, 0.9], [0.5, -0.14, 1.19])  # the body on the counter
    s.static([-0.3, -0.62, 0.86], [1.0, 0.0, 0.9])  # the counter
    s.front(0.008, 0.365, 0.915, 1.175, -0.52, (0.33, 1.045, "v", 0.18))
    (p,), rep, R = s.run(yaw_deg=yaw)
    assert p is not None and p.kind == "revolute" and p.extra["hinge"] == "left", rep
    assert np.allclose(p.axis.direction, [0, 0, -1], atol=1e-3)
    assert np.allclose(p.axis.origin, R @ np.array([0.008, -0.52, 1.045]), atol=0.02)
    assert np.allclose(p.front.normal, R @ np.array([0, -1.0, 0]), atol=1e-3)


def test_mirrored_wall_doors_hinge_at_their_shared_edge():
    """Two single-door wall cabinets side by side, hinged where they meet, pulls at the outer
    edges (bars near the bottom corners, as wall doors carry them)."""
    s = Scene()
    s.front(0.0, 0.448, 1.45, 2.15, -0.35, (0.045, 1.55, "v", 0.13))
    s.front(0.452, 0.9, 1.45, 2.15, -0.35, (0.855, 1.55, "v", 0.13))
    (a, b), rep, _ = s.run()
    assert a is not None and a.extra["hinge"] == "right", rep
    assert b is not None and b.extra["hinge"] == "left", rep


@pytest.mark.xfail(strict=True, reason="known gap: a horizontal bar a quarter of the way along the bottom edge of "
                   "a tall wall door still scores as a top-hinged flap (the train split has no such door)")
def test_a_wall_door_with_a_horizontal_bar_by_its_bottom_corner_is_a_door_not_a_flap():
    s = Scene()
    s.front(0.0, 0.45, 1.45, 2.15, -0.35, (0.11, 1.5, "h", 0.13))  # a_u ~ 0.24, near the bottom
    (p,), rep, _ = s.run()
    assert p is not None and p.kind == "revolute" and p.extra["hinge"] == "right", rep


def test_decisions_record_every_feature_and_score():
    s = Scene()
    s.front(0.0, 0.5, 0.1, 0.8, -0.6, (0.455, 0.7, "v"))
    (p,), rep, _ = s.run()
    row = next(r for r in rep if r.get("part") == p.id)
    assert set(row["features"]) == set(COMMON)
    assert set(row["door_features"]["left"]) == set(DOOR_ONLY)
    assert max(row["scores"], key=row["scores"].get) == "door_left"


def test_door_hypotheses_mirror_exactly():
    """Left and right doors share one weight vector on side-relative features: a mirrored front
    scores the mirrored hypothesis the same."""
    from drawer_lib.articulation.handles import Handle

    def ev(a_u, left, right):
        return Evidence(Handle(a_u, 0.6, "vertical", 30, "masks"), (0.45, 0.7), 0.9, 0, left, right, False, 0.0,
                        0.5, {}, 30)

    w = CFG.types.weights
    for a_u, left, right in ((0.1, False, True), (0.85, True, False), (0.5, True, True)):
        e, m = ev(a_u, left, right), ev(1 - a_u, right, left)
        se = score(features(e, [], [], True), {s: door_features(e, s) for s in ("left", "right")}, w)
        sm = score(features(m, [], [], True), {s: door_features(m, s) for s in ("left", "right")}, w)
        assert se["door_left"] == pytest.approx(sm["door_right"]) and se["door_right"] == pytest.approx(sm["door_left"])


def test_rail_extent_finds_a_track_and_not_a_counter():
    f = Front((0.25, -0.6, 0.5), (0, -1.0, 0), (1.0, 0, 0), (0.5, 0.6))
    g = np.random.default_rng(0)
    # a rail strip 1 m long just above the front, facing outward, 1 cm proud
    rail = np.stack([g.uniform(-0.25, 0.75, 400), np.full(400, -0.61), g.uniform(0.81, 0.84, 400)], -1)
    out = np.tile([0, -1.0, 0], (400, 1))
    assert rail_extent(f, rail, out) == pytest.approx(2.0, abs=0.1)  # twice the front's width
    # the same strip with a counter top behind it: no track
    top = np.stack([g.uniform(-0.25, 0.75, 400), g.uniform(-0.6, 0.0, 400), np.full(400, 0.84)], -1)
    up = np.tile([0, 0, 1.0], (400, 1))
    assert rail_extent(f, np.concatenate([rail, top]), np.concatenate([out, up])) == 0.0
    assert rail_extent(f, np.zeros((0, 3)), np.zeros((0, 3))) == 0.0
    # the pulls of the fronts above and beside it, with gaps between them: no track
    pulls = rail[(np.abs(rail[:, 0] - 0.25) > 0.06) & (np.abs(rail[:, 0] - 0.25) < 0.2)]
    assert rail_extent(f, pulls, out[: len(pulls)]) == 0.0


def test_weights_are_checked():
    from drawer_lib.articulation.config import TypesConfig

    w = {k: dict(v) for k, v in CFG.types.weights.items()}
    w["door"]["h_sideways"] = 1.0
    with pytest.raises(ConfigError, match="unknown feature 'h_sideways'"):
        TypesConfig(weights=w)
    with pytest.raises(ConfigError, match="missing hypotheses"):
        TypesConfig(weights={"drawer": {}})
    with pytest.raises(ConfigError, match="not finite"):
        TypesConfig(weights={**CFG.types.weights, "fixed": {"bias": float("nan")}})
