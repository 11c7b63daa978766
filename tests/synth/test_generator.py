"""The procedural kitchens: ground truth agrees with the compiled MuJoCo model, rendering agrees
with the GT mesh, layouts are sane, and seeds reproduce."""

import dataclasses
import filecmp

import hashlib

import mujoco
import numpy as np
import pytest
import trimesh
from omegaconf import OmegaConf

from drawer_lib.geometry.camera import Intrinsics, invert_rigid, look_at_opencv, opencv_to_opengl
from drawer_lib.geometry.joints import apply_transform, joint_transform
from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.io.capture import load_capture
from drawer_lib.io.parts import read_parts
from drawer_lib.config.typed import to_typed
from drawer_lib.synth.config import SynthConfig
from drawer_lib.synth.meshes import torus_arc
from drawer_lib.synth.splits import split_synth
from drawer_lib.synth.gt import layout_mesh, layout_parts
from drawer_lib.synth.layout import OUT, sample_layout
from drawer_lib.synth.model import KitchenRenderer, build_model

SEEDS = [0, 1, 5]
SPLIT_KITCHENS = [("train", 3), ("test", 11), ("test", 6)]  # ovens, microwaves, fridges, yaw, recessed pulls
# a kitchen written by hand (layout.modules): narrow and wide fronts, fixed fronts, both tall kinds
HAND = {"seed": 9, "layout": {"modules": {
    "base": [["drawers", 0.3], ["drawers", 0.8], ["sink", 1.0], ["dishwasher", 0.6], ["drawer_door", 0.45]],
    "wall": [["door", 0.3], ["flap_up", 0.8], ["sliding", 1.0], ["door", 0.45]],
    "tall": [["left", "fridge2"], ["right", "split"]]},
    "handle_styles": ["knob"], "yaw_deg": [-20.0, 20.0]}}


def split_config(split: str, k: int) -> SynthConfig:
    return to_typed(SynthConfig, OmegaConf.create(split_synth(split, k)), "synth", strict=False)


def hand_config(d: dict = HAND) -> SynthConfig:
    return to_typed(SynthConfig, OmegaConf.create(d), "synth", strict=False)


@pytest.fixture(scope="module", params=SEEDS + SPLIT_KITCHENS + ["hand"], ids=str)
def kitchen(request):
    if request.param == "hand":
        cfg = hand_config()
    else:
        cfg = SynthConfig(seed=request.param) if isinstance(request.param, int) else split_config(*request.param)
    layout = sample_layout(cfg)
    cam = Intrinsics.from_fovy(np.deg2rad(60), 64, 48)
    return layout, build_model(layout, cam), layout_parts(layout)


def _joint_of(km, name):
    jid = mujoco.mj_name2id(km.model, mujoco.mjtObj.mjOBJ_JOINT, f"{name}/joint")
    assert jid >= 0, name
    return jid


def test_gt_joints_agree_with_compiled_model(kitchen):
    layout, km, parts = kitchen
    m, d = km.model, mujoco.MjData(km.model)
    mujoco.mj_forward(m, d)
    articulated = [p for p in parts.parts if p.articulated]
    assert len(articulated) >= 4
    for p in articulated:
        jid = _joint_of(km, p.id)
        want_type = mujoco.mjtJoint.mjJNT_HINGE if p.kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE
        assert m.jnt_type[jid] == want_type, p.id
        np.testing.assert_allclose(d.xaxis[jid], p.axis.direction, atol=1e-9, err_msg=p.id)
        np.testing.assert_allclose(m.jnt_range[jid], p.limits, atol=1e-9, err_msg=p.id)
        assert m.jnt_limited[jid]
        if p.kind == "revolute":  # the model's anchor lies on the GT hinge line
            r = d.xanchor[jid] - np.asarray(p.axis.origin)
            off = r - (r @ np.asarray(p.axis.direction)) * np.asarray(p.axis.direction)
            assert np.linalg.norm(off) < 1e-9, p.id
        assert p.limits[0] == 0.0 and p.limits[1] > 0.1, p.id


def test_gt_joint_moves_front_as_parts_json_says(kitchen):
    layout, km, parts = kitchen
    m, d = km.model, mujoco.MjData(km.model)
    for p in (p for p in parts.parts if p.articulated):
        jid = _joint_of(km, p.id)
        bid = m.jnt_bodyid[jid]
        d.qpos[:] = 0
        mujoco.mj_kinematics(m, d)
        T0 = np.eye(4)
        T0[:3, :3], T0[:3, 3] = d.xmat[bid].reshape(3, 3), d.xpos[bid]
        corners = p.front.corners()
        local = apply_transform(invert_rigid(T0), corners)
        for frac in (0.3, 1.0):
            q = frac * p.limits[1]
            d.qpos[m.jnt_qposadr[jid]] = q
            mujoco.mj_kinematics(m, d)
            Tq = np.eye(4)
            Tq[:3, :3], Tq[:3, 3] = d.xmat[bid].reshape(3, 3), d.xpos[bid]
            moved_model = apply_transform(Tq, local)
            moved_gt = apply_transform(joint_transform(p.kind, np.asarray(p.axis.origin), np.asarray(p.axis.direction), q), corners)
            np.testing.assert_allclose(moved_model, moved_gt, atol=1e-7, err_msg=f"{p.id} at q={q}")
            # positive q opens: nothing goes behind the closed front's plane into the cabinet
            n, c = np.asarray(p.front.normal), np.asarray(p.front.center)
            assert ((moved_gt - c) @ n).min() > -1e-9, p.id
            if p.extra["family"] in ("drawer",):
                np.testing.assert_allclose(moved_gt - corners, np.tile(q * n, (4, 1)), atol=1e-9)
            if p.extra["family"] == "sliding":  # slides within its own plane
                assert np.abs((moved_gt - corners) @ n).max() < 1e-9
            if p.kind == "revolute":  # the free edge swings out by about width * sin(q)
                assert ((moved_gt - c) @ n).max() > 0.5 * min(p.front.size) * np.sin(min(q, np.pi / 2))


def test_layout_fronts_are_sane(kitchen):
    layout, _, parts = kitchen
    fronts = [p.front for p in parts.parts if p.articulated] + [b.front for b in parts.ignore_boxes]
    out = layout.pose[:3, :3] @ OUT  # the fronts' outward normal (the kitchen may be turned)
    for f in fronts:
        assert abs(f.normal[2]) < 1e-9 and abs(np.linalg.norm(f.normal) - 1) < 1e-9
        assert np.dot(f.normal, out) > np.cos(np.deg2rad(46))  # a microwave turns by at most 45 deg
        assert min(f.size) > 0.05
    # fronts in one plane never overlap (they are separated by the front gap)
    for i, a in enumerate(fronts):
        n, u = np.asarray(a.normal), np.asarray(a.u)
        for b in fronts[i + 1:]:
            d = np.asarray(b.center) - np.asarray(a.center)
            if abs(d @ n) > 1e-6 or np.dot(a.normal, b.normal) < 1 - 1e-9:
                continue
            ox = (a.size[0] + b.size[0]) / 2 - abs(d @ u)
            oz = (a.size[1] + b.size[1]) / 2 - abs(d[2])
            assert min(ox, oz) < 1e-9
    # each ignore box contains its fixed front
    for b in parts.ignore_boxes:
        assert all(b.contains(c) for c in b.front.corners())
    ids = [p.instance_id for p in parts.parts] + [b.instance_id for b in parts.ignore_boxes]
    assert len(ids) == len(set(ids)) and 0 not in ids
    # handles stand proud of their front, inside its rectangle's extent
    for e in layout.parts():
        handles = [p.mesh.verts for p in e.pieces if p.role == "handle"]
        if e.front is None or not handles:  # a push-to-open front has none
            continue
        hv = np.concatenate(handles)
        proud = (hv - np.asarray(e.front.center)) @ np.asarray(e.front.normal)
        if proud.max() < 0.001:  # a recessed pull: a pocket 12 mm into the front
            assert -0.02 < proud.max() < -0.005, e.name  # the pocket's visible back
        else:
            assert proud.max() > 0.008, e.name
        _assert_handle_on_front(e, hv)


def _assert_handle_on_front(e, hv: np.ndarray, tol: float = 0.02) -> None:
    """No handle reaches more than ``tol`` (m) beyond its front's rectangle (a bar's end cap may
    pass an edge by a little, an edge pull's plate sits in the gap; a bar standing on the next
    front is a layout error)."""
    f = e.front
    rel = hv - np.asarray(f.center)
    eu = np.abs(rel @ np.asarray(f.u)) - f.size[0] / 2
    ev = np.abs(rel @ np.asarray(f.v)) - f.size[1] / 2
    assert max(eu.max(), ev.max()) <= tol, f"{e.name}: handle reaches {max(eu.max(), ev.max()):.3f} m past its front"


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_tall_unit_handles_stay_on_their_fronts(seed):
    cfg = SynthConfig(seed=seed)
    cfg = dataclasses.replace(cfg, layout=dataclasses.replace(cfg.layout, tall_units=2))
    layout = sample_layout(cfg)
    for e in layout.parts():
        if e.front is not None:
            _assert_handle_on_front(e, np.concatenate([p.mesh.verts for p in e.pieces if p.role == "handle"]))


def test_required_types_and_kinds_present():
    layout = sample_layout(SynthConfig(seed=0))
    fams = {e.family for e in layout.parts()}
    assert {"drawer", "door", "flap", "sliding"} <= fams
    hinges = {e.hinge for e in layout.parts() if e.joint == "hinge"}
    assert {"left", "right", "top"} <= hinges


def test_pieces_are_closed_outward_shells():
    layout = sample_layout(SynthConfig(seed=3))
    for e in layout.entities:
        for p in e.pieces:
            tm = trimesh.Trimesh(p.mesh.verts, p.mesh.faces, process=True)
            assert tm.is_watertight, (e.name, p.material)
            assert p.mesh.volume() > 0, (e.name, p.material)
            assert np.all(np.isfinite(p.mesh.uv))


def test_rendered_depth_agrees_with_gt_mesh_raycast():
    layout = sample_layout(SynthConfig(seed=0))
    intr = Intrinsics.from_fovy(np.deg2rad(62), 160, 120)
    km = build_model(layout, intr)
    mesh, _ = layout_mesh(layout)
    rc = Raycaster(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    r = KitchenRenderer(km, intr)
    errs = []
    try:
        for eye, tgt in [([1.0, -2.4, 1.4], [1.2, 0, 0.9]), ([0.2, -1.6, 1.1], [1.5, 0, 0.5]), ([2.2, -1.8, 1.7], [1.0, 0, 1.6])]:
            c2w = look_at_opencv(np.array(eye), np.array(tgt), np.array([0, 0, 1.0]))
            r.set_camera(opencv_to_opengl(c2w))
            _, z, ent, _ = r.render()
            z_rc, _, fid = rc.depth_normals(intr, invert_rigid(c2w))
            ok = (fid >= 0) & (z > 0)
            assert ok.mean() > 0.99  # the room is closed: every ray hits something
            errs.append(np.abs(z[ok] - z_rc[ok]))
            assert np.all(ent >= 0)
    finally:
        r.close()
    e = np.concatenate(errs)
    assert np.median(e) <= 1e-3, np.median(e)
    assert np.mean(e < 5e-3) > 0.97  # only silhouette pixels may disagree by more


def test_capture_depth_png_agrees_with_gt_mesh(exact_capture):
    out, _, _ = exact_capture
    cap = load_capture(out)
    mesh = trimesh.load(out / "gt" / "mesh.ply", process=False)
    rc = Raycaster(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    errs = []
    for i in range(0, len(cap.frames), 3):
        z = cap.depth(i)
        z_rc, _, fid = rc.depth_normals(cap.intrinsics, cap.frames[i].w2c)
        ok = (z > 0) & (fid >= 0)
        errs.append(np.abs(z[ok] - z_rc[ok]))
    assert np.median(np.concatenate(errs)) <= 1e-3


def test_gt_instances_match_parts(exact_capture):
    out, manifest, _ = exact_capture
    parts = read_parts(out / "gt" / "parts.json")
    known = {p.instance_id for p in parts.parts} | {b.instance_id for b in parts.ignore_boxes}
    cap = load_capture(out)
    seen = set()
    for f in cap.frames:
        from drawer_lib.io.images import read_u16

        seen |= set(np.unique(read_u16(out / "gt" / "instances" / f"{f.stem}.png")).tolist())
    assert seen - {0} <= known
    assert len(seen - {0}) >= 3
    assert manifest.gt_part_kinds == parts.kinds()


def test_same_seed_same_kitchen_and_capture(tmp_path, tiny_scene, exact_capture):
    from helpers import render_capture, sensor_cfg

    a = sample_layout(tiny_scene.synth)
    b = sample_layout(tiny_scene.synth)
    assert layout_parts(a).to_json() == layout_parts(b).to_json()
    np.testing.assert_array_equal(layout_mesh(a)[0].vertices, layout_mesh(b)[0].vertices)
    other = sample_layout(dataclasses.replace(tiny_scene.synth, seed=tiny_scene.synth.seed + 1))
    assert layout_parts(other).to_json() != layout_parts(a).to_json()

    out1, _, _ = exact_capture
    out2 = tmp_path / "again"
    render_capture(tiny_scene, sensor_cfg(depth="exact", mono="exact", detections="perfect"), out2)
    cmp = filecmp.dircmp(out1, out2)
    for sub in ("images", "depth", "detections", "mono_depth"):
        names = sorted(p.name for p in (out1 / sub).iterdir())
        match, mismatch, errors = filecmp.cmpfiles(out1 / sub, out2 / sub, names, shallow=False)
        assert not mismatch and not errors, (sub, mismatch)
    assert (out1 / "transforms.json").read_text() == (out2 / "transforms.json").read_text()
    assert not cmp.left_only and not cmp.right_only


def test_opening_a_drawer_in_the_renderer_moves_its_front_by_the_joint_value():
    layout = sample_layout(SynthConfig(seed=0))
    parts = layout_parts(layout)
    drawer = next(p for p in parts.parts if p.extra["family"] == "drawer")
    intr = Intrinsics.from_fovy(np.deg2rad(40), 64, 48)
    c = np.asarray(drawer.front.center)
    c2w = look_at_opencv(c + 1.5 * np.asarray(drawer.front.normal) + [0, 0, 0.01], c, np.array([0, 0, 1.0]))
    r = KitchenRenderer(build_model(layout, intr), intr)
    try:
        r.set_camera(opencv_to_opengl(c2w))
        z0 = r.render()[1][24, 32]
        r.set_joint(drawer.id, 0.2)
        z1 = r.render()[1][24, 32]
    finally:
        r.close()
    assert z0 - z1 == pytest.approx(0.2, abs=2e-3)


def test_default_kitchen_is_the_one_earlier_releases_made():
    """The keys added for the wider generator draw from their own stream: with their defaults
    the kitchens of earlier releases come out vertex for vertex (kitchen_small's, seed 0)."""
    m, inst = layout_mesh(sample_layout(SynthConfig(seed=0)))
    h = hashlib.md5(np.asarray(m.vertices).tobytes() + inst.tobytes()).hexdigest()
    assert h == "08a0817a9d983f9d0bacc86c412301a0"  # the code of f2f54da gives the same


@pytest.mark.parametrize("arc_deg", [180.0, 200.0, 359.0])
def test_torus_arc_is_closed_with_outward_faces(arc_deg):
    m = torus_arc(0.05, 0.008, np.deg2rad(arc_deg))
    tm = trimesh.Trimesh(m.verts, m.faces, process=True)
    assert tm.is_watertight and tm.is_winding_consistent
    assert m.volume() > 0
    # closed as given (the seams' duplicated vertices coincide): the signed volume does not
    # depend on the origin
    assert abs(m.translated([1.0, 2.0, 3.0]).volume() - m.volume()) < 1e-9


def test_splits_are_fixed_and_disjoint():
    assert split_synth("train", 4) == split_synth("train", 4)
    train = {split_synth("train", k)["seed"] for k in range(20)}
    test = {split_synth("test", k)["seed"] for k in range(20)}
    assert not train & test
    for k in range(20):  # every kitchen of both splits is a valid config
        split_config("train", k), split_config("test", k)
    with pytest.raises(ValueError, match="unknown split"):
        split_synth("val", 0)
    hand = [split_config("hand", k) for k in range(8)]  # written by hand: every kitchen builds
    assert all(c.layout.modules is not None for c in hand)
    assert not {c.seed for c in hand} & (train | test)
    with pytest.raises(ValueError, match="kitchens 0 .. 7"):
        split_synth("hand", 8)
    first = split_synth("hand", 0)
    first["layout"]["modules"]["base"].clear()  # a copy: the split's table is not touched
    assert split_synth("hand", 0)["layout"]["modules"]["base"]
    for c in hand:
        parts = layout_parts(sample_layout(c))
        assert sum(p.articulated for p in parts.parts) >= 9
    tune = [split_config("hand_tune", k) for k in range(10)]  # written by hand, to be tuned on
    assert all(c.layout.modules is not None for c in tune)
    assert not {c.seed for c in tune} & ({c.seed for c in hand} | train | test)
    with pytest.raises(ValueError, match="hand_tune split has kitchens 0 .. 9"):
        split_synth("hand_tune", 10)
    assert sum(sum(p.articulated for p in layout_parts(sample_layout(c)).parts) for c in tune) == 158


def test_wide_generator_makes_each_new_case():
    fams = set()
    tall = []
    for k in range(12):
        layout = sample_layout(split_config("test", k))
        for e in layout.parts():
            if e.articulated:
                fams.add((e.family, e.hinge, e.label))
                tall.append(max(e.front.size))
        assert abs(layout.pose[2, 2] - 1) < 1e-12  # a yaw about z only
    assert ("flap", "bottom", "door") in fams  # oven / dishwasher doors
    assert max(tall) > 1.9  # full-height fridge / pantry doors


def test_a_kitchen_written_by_hand_has_its_modules_in_order():
    """layout.modules: the base and wall runs left to right at the written widths, the tall
    units of the written kinds on their sides; the same seed gives the same kitchen."""
    cfg = hand_config()
    layout = sample_layout(cfg)
    R = layout.pose[:3, :3]
    x_of = lambda e: float((R.T @ (np.asarray(e.front.center) - layout.pose[:3, 3]))[0])  # noqa: E731
    fronts = [e for e in layout.entities if e.front is not None and e.family != "object"]
    base = sorted((e for e in fronts if e.front.center[2] < 1.0 and e.front.size[1] < 1.2), key=x_of)
    g = cfg.layout.front_gap
    # base run: 3 drawers 0.3 wide, 3 drawers 0.8, the sink's false drawer 1.0 over two doors,
    # the dishwasher's door 0.6, a drawer over a door 0.45
    widths = sorted({round(e.front.size[0] + g, 3) for e in base})
    assert widths == [0.3, 0.45, 0.5, 0.6, 0.8, 1.0]  # 0.5: the sink's doors, half its width
    assert sum(e.family == "false_front" for e in fronts) == 1
    tall = [e for e in fronts if e.front.size[1] > 1.2]  # fridge2's upper door, the split unit's upper door
    assert len(tall) == 2 and {e.family for e in tall} == {"door"}
    run_end = 0.3 + 0.8 + 1.0 + 0.6 + 0.45  # the base run; tall units stand beyond its ends
    assert x_of(min(tall, key=x_of)) < 0 and x_of(max(tall, key=x_of)) > run_end
    walls = [e for e in fronts if e.front.center[2] > 1.4 and e.front.size[1] < 1.2]
    assert sorted(round(e.front.size[0] + g, 3) for e in walls if e.family != "sliding") == [0.3, 0.45, 0.8]
    assert sum(e.family == "sliding" for e in walls) == 2
    assert layout_parts(sample_layout(cfg)).to_json() == layout_parts(layout).to_json()


@pytest.mark.parametrize("modules, msg", [
    ({"wall": [["door", 0.4]]}, "at least one base module"),
    ({"base": [["door", 0.4]], "tall": []}, None),
    ({"base": [["drawer", 0.4]]}, r"base\[0\] = \['drawer', 0.4\]: unknown type"),
    ({"base": [["door", 0.1]]}, r"width must be in \[0.25, 1.2\]"),
    ({"base": [["door", 0.4]], "wall": [["door", 0.3], ["door", 0.3]]}, "wall run \\(0.60 m\\) is longer"),
    ({"base": [["door", 0.4]], "tall": [["left", "pantry"], ["left", "fridge1"]]}, "second tall unit on the left"),
    ({"base": [["door", 0.4]], "island": []}, "unknown runs"),
])
def test_a_written_kitchen_that_cannot_be_built_is_refused(modules, msg):
    from drawer_lib.errors import ConfigError

    d = {"seed": 0, "layout": {"modules": modules}}
    if msg is None:
        assert hand_config(d).layout.modules["base"] == [["door", 0.4]]
        return
    with pytest.raises(ConfigError, match=msg):
        hand_config(d)


def test_runs_of_equal_modules_copy_the_left_neighbour():
    """repeat_runs: at p = 1 every module copies its left neighbour (a whole run of one kind and
    width) except fixed fronts, appliances and the only module of a required kind; at p = 0
    nothing changes; the inputs are not modified."""
    from drawer_lib.synth.layout import repeat_runs

    kinds = ["door", "drawers", "sink", "door", "oven", "flap_down", "drawer_door"]
    widths = [0.4, 0.6, 0.9, 0.45, 0.6, 0.5, 0.5]
    rng = np.random.default_rng(0)
    k1, w1 = repeat_runs(rng, kinds, widths, 1.0, required=["drawers"])
    # drawers is required and the only one: kept; the sink and the oven neither copy nor are copied
    assert k1 == ["door", "drawers", "sink", "door", "oven", "flap_down", "flap_down"]
    assert w1 == [0.4, 0.6, 0.9, 0.45, 0.6, 0.5, 0.5]
    k2, w2 = repeat_runs(rng, kinds, widths, 1.0, required=[])
    assert k2[:2] == ["door", "door"] and w2[:2] == [0.4, 0.4]
    assert (k2, w2) != (kinds, widths) and kinds[1] == "drawers"  # inputs untouched
    assert repeat_runs(rng, kinds, widths, 0.0, required=[]) == (kinds, widths)
    # a wall run may not grow past the base run it hangs over (a required module would be dropped)
    wall = (["sliding", "double_door", "flap_up"], [0.9, 0.8, 0.4])
    assert repeat_runs(rng, *wall, 1.0, required=["flap_up"], max_total=2.15) == wall
    assert repeat_runs(rng, *wall, 1.0, required=["flap_up"], max_total=2.2)[1] == [0.9, 0.9, 0.4]
    assert repeat_runs(rng, ["door", "door"], [0.5, 0.4], 1.0, required=[], max_total=0.8)[1] == [0.5, 0.4]


def test_repeat_p_draws_runs_and_leaves_other_kitchens_alone():
    """layout.repeat_p: with it, equal neighbours are far more common than the drawn kitchens
    have them, every required kind is still there, and the same seed gives the same kitchen;
    0 (the default) gives every kitchen as before (the hash test above pins seed 0)."""
    from drawer_lib.errors import ConfigError

    def equal_pairs(cfg):
        parts = [e for e in sample_layout(cfg).parts() if e.articulated and e.front.center[2] < 1.0]
        ws = sorted((round(float(e.front.center[0]), 3), round(float(e.front.size[0]), 3), e.family) for e in parts)
        return sum(a[1:] == b[1:] for a, b in zip(ws, ws[1:]))

    base = [SynthConfig(seed=s) for s in range(20)]
    runs = [dataclasses.replace(c, layout=dataclasses.replace(c.layout, repeat_p=0.8)) for c in base]
    assert sum(map(equal_pairs, runs)) > sum(map(equal_pairs, base)) + 10
    for c in runs[:5]:
        fams = {e.family for e in sample_layout(c).parts()}
        assert {"drawer", "door", "flap", "sliding"} <= fams
        assert layout_parts(sample_layout(c)).to_json() == layout_parts(sample_layout(c)).to_json()
    same = dataclasses.replace(base[3], layout=dataclasses.replace(base[3].layout, repeat_p=0.0))
    assert layout_parts(sample_layout(same)).to_json() == layout_parts(sample_layout(base[3])).to_json()
    with pytest.raises(ConfigError, match="repeat_p = 1.5"):
        dataclasses.replace(base[0].layout, repeat_p=1.5)
