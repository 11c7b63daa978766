"""The twin as the viewer draws it (drawer_lib/viewer/scene.py), without a browser: covariances
against a per-Gaussian loop, float16-safe clamping, every pose from MuJoCo against the joints'
analytic motion, and bad folders named."""

import json
import math
import shutil
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from viewer_fixtures import write_tiny_twin  # noqa: E402
from helpers import quat_to_rot  # noqa: E402

from drawer_lib.errors import InputError  # noqa: E402
from drawer_lib.geometry.joints import joint_transform  # noqa: E402
from drawer_lib.splat.render import Gaussians  # noqa: E402
from drawer_lib.viewer.scene import body_hulls, covariances, load_twin_scene, relative_poses, splats_of  # noqa: E402


@pytest.fixture(scope="module")
def twin(tmp_path_factory) -> Path:
    return write_tiny_twin(tmp_path_factory.mktemp("viewer") / "twin")


def test_covariances_match_a_per_gaussian_loop():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(50, 4)) * rng.uniform(0.1, 10, size=(50, 1))  # any norm
    s = np.exp(rng.uniform(-8, 1, size=(50, 3)))
    ref = np.stack([quat_to_rot(qi) @ np.diag(si**2) @ quat_to_rot(qi).T for qi, si in zip(q, s)])
    np.testing.assert_allclose(covariances(q, s), ref, rtol=1e-10, atol=1e-18)
    with pytest.raises(ValueError, match="zero quaternions"):
        covariances(np.zeros((1, 4)), np.ones((1, 3)))


def _gaussians(scales, n=None, **kw):
    scales = torch.as_tensor(scales, dtype=torch.float32)
    n = len(scales)
    g = dict(means=torch.zeros(n, 3), quats=torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1), scales=scales,
             opacities=torch.full((n,), 0.5), sh=torch.zeros(n, 1, 3))
    g.update(kw)
    return Gaussians(**g)


def test_tiny_and_huge_scales_are_clamped_so_float16_covariances_stay_finite_and_non_zero():
    scales = [[1e-5, 1e-4, 2e-3], [1e-3, 1e-3, 1e-3], [5e3, 1.0, 1.0], [0.01, 0.02, 0.03]]
    sp = splats_of(_gaussians(scales), min_scale=1e-3, max_scale=10.0)
    assert sp.n_clamped == 2
    diag = np.diagonal(sp.covariances, axis1=1, axis2=2)
    h = diag.astype(np.float16)  # what the web client stores
    assert np.all(np.isfinite(h)) and np.all(h > 0)
    np.testing.assert_allclose(h.astype(np.float64), diag, rtol=0.02)  # >= 1 mm: within float16's 2 %
    np.testing.assert_allclose(diag[3], np.array([0.01, 0.02, 0.03]) ** 2, rtol=1e-6)  # in range: untouched
    assert sp.opacities.shape == (4, 1) and sp.rgbs.shape == (4, 3)
    np.testing.assert_allclose(sp.rgbs, 0.5)  # zero DC -> mid grey


def test_a_non_finite_gaussian_is_named():
    g = _gaussians([[0.01, 0.01, 0.01]] * 3, means=torch.tensor([[0.0, 0, 0], [float("nan"), 0, 0], [0, 0, 0]]))
    with pytest.raises(InputError, match=r"static.ply: 1 Gaussians with non-finite means \(first at index 1\)"):
        splats_of(g, what="static.ply")


def test_the_scene_lists_bodies_joints_and_hulls_as_the_mjcf_has_them(twin):
    sc = load_twin_scene(twin)
    assert [b.id for b in sc.bodies] == ["drawer_0", "door_0", "flap_0", "cup_0", "cup_1"]
    d = sc.body("drawer_0")
    assert d.kind == "prismatic" and d.joint.range == (0.0, 0.4)
    np.testing.assert_allclose(d.joint.axis, [0, -1, 0], atol=1e-12)
    door = sc.body("door_0")
    np.testing.assert_allclose(door.joint.anchor, [0.95, -0.002, 0.35], atol=1e-9)  # fixture: hinge on x0, back face
    np.testing.assert_allclose(door.joint.axis, [0, 0, -1], atol=1e-12)
    assert sc.body("cup_0").joint is None and sc.body("cup_0").kind == "rigid"
    assert len(d.hulls) == 5 and len(sc.static.hulls) == 17  # the drawer's 5 boxes; floor, 3 carcasses, counter
    # a box hull's vertices are the box's corners: the drawer's front panel spans its 8 corners
    v = np.concatenate([h[0] for h in d.hulls])
    assert v[:, 1].min() == pytest.approx(0.0, abs=1e-9) and v[:, 1].max() == pytest.approx(0.45, abs=1e-9)
    assert sc.n_gaussians == sum(len(b.splats) for b in [sc.static, *sc.bodies])


@pytest.mark.parametrize("pid,q", [("drawer_0", 0.3), ("door_0", 1.2), ("flap_0", 0.7), ("door_0", 1e-6)])
def test_relative_poses_move_rest_points_as_the_joint_does(twin, pid, q):
    sc = load_twin_scene(twin)
    m, d = sc.model, mujoco.MjData(sc.model)
    j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, pid)
    d.qpos[m.jnt_qposadr[j]] = q
    mujoco.mj_kinematics(m, d)
    b = sc.body(pid)
    pos, wxyz = relative_poses(d.xpos[[b.mj_body]], d.xquat[[b.mj_body]], sc.rest_xpos[[b.mj_body]], sc.rest_xquat[[b.mj_body]])
    rest = b.splats.centers.astype(np.float64)
    moved = rest @ quat_to_rot(wxyz[0]).T + pos[0]
    T = joint_transform(b.kind, b.joint.anchor, b.joint.axis, q)  # the analytic joint motion
    np.testing.assert_allclose(moved, rest @ T[:3, :3].T + T[:3, 3], atol=1e-9)
    # and MuJoCo's own geoms went to the same place
    now = np.concatenate([h[0] for h in body_hulls(m, d, b.mj_body)])
    then = np.concatenate([h[0] for h in b.hulls])
    np.testing.assert_allclose(then @ quat_to_rot(wxyz[0]).T + pos[0], now, atol=1e-9)


def test_relative_poses_of_a_free_body_compose():
    rng = np.random.default_rng(1)
    q0, q1 = rng.normal(size=(2, 4))
    q0, q1 = q0 / np.linalg.norm(q0), q1 / np.linalg.norm(q1)
    x0, x1 = rng.normal(size=(2, 3))
    pos, wxyz = relative_poses(x1[None], q1[None], x0[None], q0[None])
    p = rng.normal(size=(10, 3))  # points given at rest, in the world
    local = (p - x0) @ quat_to_rot(q0)  # the same points in the body frame
    np.testing.assert_allclose(p @ quat_to_rot(wxyz[0]).T + pos[0], local @ quat_to_rot(q1).T + x1, atol=1e-12)


def _copy(twin, tmp_path):
    t = tmp_path / "t"
    shutil.copytree(twin, t)
    return t


def test_bad_folders_are_named(twin, tmp_path):
    with pytest.raises(InputError, match="nowhere: no such folder"):
        load_twin_scene(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match=r"empty/twin.json: missing \(a twin folder is what the twin stage writes"):
        load_twin_scene(tmp_path / "empty")
    t = _copy(twin, tmp_path)
    tj = json.loads((t / "twin.json").read_text())
    (t / "twin.json").write_text(json.dumps({**tj, "schema": "drawer.twin/0"}))
    with pytest.raises(InputError, match="schema 'drawer.twin/0'"):
        load_twin_scene(t)
    tj["parts"][0]["id"] = tj["parts"][0]["body"] = "drawer_9"
    (t / "twin.json").write_text(json.dumps(tj))
    with pytest.raises(InputError, match="scene.xml: no body named 'drawer_9'"):
        load_twin_scene(t)


def test_a_missing_ply_or_a_wrong_joint_is_named(twin, tmp_path):
    t = _copy(twin, tmp_path)
    (t / "gaussians" / "door_0.ply").unlink()
    with pytest.raises(InputError, match=r"door_0.ply: missing \(listed for part 'door_0'"):
        load_twin_scene(t)
    t2 = tmp_path / "t2"
    shutil.copytree(twin, t2)
    tj = json.loads((t2 / "twin.json").read_text())
    tj["parts"][0]["kind"] = "revolute"  # the drawer's joint is a slide
    (t2 / "twin.json").write_text(json.dumps(tj))
    with pytest.raises(InputError, match="part 'drawer_0' \\(revolute\\) has no hinge joint"):
        load_twin_scene(t2)
    (t2 / "scene.xml").write_text("<mujoco><worldbody><geom type='nothing'/></worldbody></mujoco>")
    with pytest.raises(InputError, match="scene.xml: MuJoCo cannot load it"):
        load_twin_scene(t2)


def test_bounds_ignore_a_far_floater(twin):
    sc = load_twin_scene(twin)
    lo, hi = sc.bounds()
    sc.static.splats.centers[0] = [1e4, 1e4, 1e4]
    lo2, hi2 = sc.bounds()
    assert np.all(np.abs(hi2 - hi) < 0.2) and math.isfinite(float(lo2.sum()))
