"""The robot stage's pieces on analytic fixtures: the Panda model's frames and additions, the IK
against forward kinematics, the planned path against the part's own joint, the LeRobot writer
read back the way lerobot's loader reads it, and the whole stage on a one-drawer kitchen whose
ground truth is itself (the demonstration transfers) or a hinged door (it must not)."""

import importlib.util
import json
import math
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from drawer_lib.errors import ConfigError, InputError
from drawer_lib.geometry.joints import joint_transform
from drawer_lib.io.parts import write_parts
from drawer_lib.robot import panda as P
from drawer_lib.robot.dataset import Episode, write_lerobot
from drawer_lib.geometry.rotations import rotation_angle
from drawer_lib.robot.ik import PandaIK
from drawer_lib.robot.plan import PHASES, RobotConfig, grasp_pose, task_path
from drawer_lib.runner import StageRun

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import sim_fixtures as F  # noqa: E402


def test_panda_tcp_frame_is_approach_z_and_closing_y():
    m = P.panda_spec().compile()
    d = mujoco.MjData(m)
    d.qpos[:7] = P.HOME
    mujoco.mj_forward(m, d)
    s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, P.TCP)
    R = d.site_xmat[s].reshape(3, 3)
    left = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "panda0_leftfinger")
    slide = d.xmat[left].reshape(3, 3) @ np.array([0.0, 1.0, 0.0])  # the finger joint's axis, world
    assert abs(abs(R[:, 1] @ slide) - 1) < 1e-6  # fingers close along the TCP's y
    hand = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "panda0_link7")
    z7 = d.xmat[hand].reshape(3, 3)[:, 2]
    assert abs(R[:, 2] @ z7 - 1) < 1e-6  # the TCP's z is the flange's: the approach
    np.testing.assert_allclose(d.site_xpos[s], d.xpos[hand] + P.TCP_Z * z7, atol=1e-9)
    assert all(m.body_gravcomp[1:] == 1.0)
    col = [g for g in range(m.ngeom) if m.geom_contype[g]]
    assert col and all(m.geom_contype[g] == P.BIT_ROBOT and not m.geom_conaffinity[g] & P.BIT_ROBOT for g in col)


def test_fingers_squeeze_with_the_commanded_force():
    """A command below closed is a squeeze: the servo pushes a finger stopped at the gap x with
    kp * (x - ctrl)."""
    m = P.panda_spec().compile()
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, P.FINGER_ACTUATORS[0])
    assert m.actuator_ctrlrange[i].tolist() == [P.FINGER_MIN_CTRL, P.FINGER_MAX]
    assert m.actuator_gainprm[i, 0] == P.FINGER_KP and m.actuator_biasprm[i, 1] == -P.FINGER_KP


def test_missing_package_is_one_clear_error(monkeypatch):
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    with pytest.raises(ConfigError, match="pip install gymnasium-robotics"):
        P.franka_dir()


def test_ik_recovers_poses_of_its_own_forward_kinematics():
    ik = PandaIK()
    lo, hi = ik.model.jnt_range[:7, 0], ik.model.jnt_range[:7, 1]
    rng = np.random.default_rng(0)
    for _ in range(5):  # targets near HOME: the posture keeps the solver in one branch
        q = np.clip(P.HOME + rng.uniform(-0.3, 0.3, 7), lo, hi)
        T = ik.fk(q)
        q2, ep, er = ik.solve(T, P.HOME, iters=200)
        assert ep < 1e-3 and er < 1e-2, (ep, er)
        assert ((q2 >= lo - 1e-6) & (q2 <= hi + 1e-6)).all()
    far = ik.fk(P.HOME)
    far[:3, 3] += [3.0, 0.0, 0.0]  # out of reach: a finite error, no NaN
    q3, ep, er = ik.solve(far, P.HOME)
    assert np.isfinite(q3).all() and ep > 2.0


def test_grasp_pose_is_a_rotation_and_flip_pitch_keep_the_grasp():
    g = {"kind": "handle", "position": [0.1, 0.2, 0.3], "approach": [0, 2.0, 0], "closing_axis": [0, 0.1, 1.0]}
    T = grasp_pose(g)
    R = T[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) > 0 and np.allclose(R[:, 2], [0, 1, 0]) and np.allclose(R[:, 1], [0, 0, 1])
    F_ = grasp_pose(g, flip=True)[:3, :3]
    assert np.allclose(F_[:, 2], R[:, 2]) and np.allclose(F_[:, 1], -R[:, 1])
    Pt = grasp_pose(g, pitch=0.5)[:3, :3]  # about the bar's long axis (x): x stays, z tilts by 0.5 rad
    assert np.allclose(Pt[:, 0], R[:, 0]) and math.isclose(rotation_angle(Pt, R), 0.5, abs_tol=1e-9)


@pytest.mark.parametrize("kind,axis,origin", [("prismatic", (0, -1.0, 0), (0, 0, 0.5)),
                                              ("revolute", (0, 0, -1.0), (-0.3, 0, 0.5))])
def test_the_path_rides_with_the_part_along_its_joint(kind, axis, origin):
    part = F.parts_of(F.single(F.drawer_cabinet)).parts[0]
    part = type(part)(part.id, kind, type(part.axis)(origin, axis), (0.0, 1.2), part.front)
    g = {"kind": "handle", "position": [0.0, -0.03, 0.2], "approach": [0, 1.0, 0], "closing_axis": [0, 0, 1.0]}
    cfg = RobotConfig()
    G = grasp_pose(g)
    ticks = task_path(part, G, cfg)
    seen = [PHASES.index(t.phase) for t in ticks]
    assert seen == sorted(seen) and {t.phase for t in ticks} == set(PHASES)  # phases in order, all present
    opening = [t for t in ticks if t.phase == "open"]
    q = np.array([t.q_part for t in opening])
    assert np.all(np.diff(q) >= -1e-12) and math.isclose(q[-1], cfg.open_fraction * 1.2)
    for t in opening + [t for t in ticks if t.phase == "close"]:
        np.testing.assert_allclose(t.tcp, joint_transform(kind, np.asarray(origin), np.asarray(axis), t.q_part) @ G,
                                   atol=1e-12)
    assert ticks[0].tcp[:3, 3] @ np.array([0, 1.0, 0]) == pytest.approx(-0.03 - cfg.pregrasp)
    assert ticks[-1].finger == P.FINGER_MAX and min(t.finger for t in ticks) < 0  # released; squeezed


def _read_like_lerobot(root: Path):
    """What lerobot's loader does with the files: features from info.json cast onto the data
    parquet by Hugging Face datasets, tasks by pandas (index 'task'), episodes' row ranges."""
    datasets = pytest.importorskip("datasets")
    pd = pytest.importorskip("pandas")
    info = json.loads((root / "meta" / "info.json").read_text())
    hf = {}
    for k, f in info["features"].items():
        if f["dtype"] == "image":
            hf[k] = datasets.Image()
        elif list(f["shape"]) == [1]:
            hf[k] = datasets.Value(f["dtype"])
        else:
            hf[k] = datasets.Sequence(datasets.Value(f["dtype"]), length=f["shape"][0])
    files = sorted(str(p) for p in (root / "data").glob("*/*.parquet"))
    ds = datasets.Dataset.from_parquet(files, features=datasets.Features(hf), cache_dir=str(root.parent / "cache"))
    tasks = pd.read_parquet(root / "meta" / "tasks.parquet")
    eps = pd.concat(pd.read_parquet(p) for p in sorted((root / "meta" / "episodes").glob("*/*.parquet")))
    return info, ds, tasks, eps


def test_lerobot_dataset_reads_back(tmp_path):
    rng = np.random.default_rng(0)
    feats = {"observation.state": {"dtype": "float32", "shape": [3], "names": ["a", "b", "c"]},
             "observation.part_q": {"dtype": "float32", "shape": [1], "names": None},
             "observation.images.front": {"dtype": "image", "shape": [6, 8, 3], "names": ["height", "width", "channels"]}}
    eps = [Episode(task, {"observation.state": rng.normal(size=(T, 3)), "observation.part_q": rng.normal(size=T),
                          "observation.images.front": rng.integers(0, 256, (T, 6, 8, 3), dtype=np.uint8)})
           for task, T in (("open the drawer", 5), ("close the drawer", 4), ("open the drawer", 3))]
    write_lerobot(tmp_path / "ds", eps, feats, fps=10, robot_type="franka_panda")
    info, ds, tasks, ep = _read_like_lerobot(tmp_path / "ds")
    assert info["codebase_version"] == "v3.0" and info["total_frames"] == 12 == len(ds) and info["total_tasks"] == 2
    assert tasks.index.name == "task" and tasks.loc["close the drawer", "task_index"] == 1
    assert ep["dataset_from_index"].tolist() == [0, 5, 9] and ep["dataset_to_index"].tolist() == [5, 9, 12]
    row = ds[6]  # episode 1, frame 1
    assert row["episode_index"] == 1 and row["frame_index"] == 1 and row["index"] == 6 and row["task_index"] == 1
    assert math.isclose(row["timestamp"], 0.1, rel_tol=1e-6)
    np.testing.assert_allclose(row["observation.state"], eps[1].frames["observation.state"][1], rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(row["observation.images.front"]), eps[1].frames["observation.images.front"][1])
    stats = json.loads((tmp_path / "ds" / "meta" / "stats.json").read_text())
    assert np.asarray(stats["observation.images.front"]["mean"]).shape == (3, 1, 1)
    assert stats["observation.state"]["count"] == [12] and len(stats["observation.state"]["q99"]) == 3
    with pytest.raises(InputError, match="not empty"):
        write_lerobot(tmp_path / "ds", eps, feats, fps=10)
    with pytest.raises(InputError, match="lacks feature"):
        write_lerobot(tmp_path / "ds2", eps, {**feats, "action": {"dtype": "float32", "shape": [2], "names": None}}, 10)
    with pytest.raises(InputError, match="reserved"):
        write_lerobot(tmp_path / "ds3", eps, {"a/b": feats["observation.state"]}, 10)


def _drawer_kitchen(revolute: bool = False):
    """A drawer cabinet at counter height (carcass z 0.5-0.8) with a bar handle 35 mm proud of
    its front; ``revolute``: the same front hinged at its left edge instead (the 'ground truth'
    a wrong twin is replayed in)."""
    from drawer_lib.bodies import PartBody, TwinModel

    x0, x1, z0, z1 = -0.3, 0.3, 0.5, 0.8
    walls = F.carcass(x0, x1, z0, z1, 0.5)
    shapes = F.drawer_box(x0 + F.T + 0.003, x1 - F.T - 0.003, z0 + F.T + 0.003, z1 - 0.02, 0.0, 0.45)
    handle = F.slab((-0.08, -0.035, 0.713), (0.08, -0.021, 0.727))
    if revolute:
        part = PartBody("drawer_0", "revolute", np.array([x0, 0.0, 0.65]), np.array([0.0, 0.0, -1.0]), (0.0, 1.6),
                        [], [shapes[0], handle], F.DENSITY)
    else:
        part = PartBody("drawer_0", "prismatic", np.array([0.0, 0.0, 0.65]), np.array([0.0, -1.0, 0.0]),
                        (0.0, 0.4), F.as_visual(shapes), shapes + [handle], F.DENSITY)
    static = [F.floor(), *walls]
    return TwinModel(static_visual=F.as_visual(static), static_collision=static, parts=[part])


@pytest.fixture(scope="module")
def robot_run(tmp_path_factory):
    from drawer_lib.robot.pipeline import GroundTruth, run_robot
    from drawer_lib.sim.mjcf import build_spec, write_mjcf

    d = tmp_path_factory.mktemp("robot")
    model = _drawer_kitchen()
    write_mjcf(build_spec(model), d / "twin")
    parts = F.parts_of(model)
    write_parts(d / "parts.json", parts)
    grasp = {"kind": "handle", "position": [0.0, -0.028, 0.72], "approach": [0.0, 1.0, 0.0],
             "closing_axis": [0.0, 0.0, 1.0], "width": 0.014}
    (d / "twin" / "twin.json").write_text(json.dumps({"parts": [{"id": "drawer_0", "grasp": grasp}]}))
    out = {}
    for name, gt_model in (("same", model), ("hinged", _drawer_kitchen(revolute=True))):
        gt_parts = F.parts_of(gt_model)
        gt = GroundTruth(lambda m=gt_model: build_spec(m), gt_parts)
        (d / name).mkdir()
        run = StageRun("robot", d / name, d / name, 0)
        cam = (16, 12) if name == "same" else (0, 0)
        out[name] = run_robot(RobotConfig(camera=cam), d / "twin", d / "parts.json", run, None, gt), d / name
    return out


def test_the_robot_opens_and_closes_the_drawer_and_it_transfers_to_itself(robot_run):
    m, d = robot_run["same"]
    assert m["robot_success"] == 1.0 and m["robot_transfer_success"] == 1.0, m
    a = json.loads((d / "attempts.json").read_text())["parts"][0]
    assert a["twin"]["q_hold"] >= 0.85 * 0.8 * 0.4 and a["twin"]["q_end"] < 0.05
    assert a["twin"]["max_arm_contact_m"] < 0.01 and a["transfer"]["gt_id"] == "drawer_0"
    info, ds, tasks, ep = _read_like_lerobot(d / "dataset")
    assert info["total_episodes"] == 3 == m["dataset_episodes"] and list(tasks.index) == [
        "open the prismatic drawer_0", "close the prismatic drawer_0",
        "pick up the block from the counter and place it in the drawer drawer_0"]
    assert np.asarray(ds[0]["observation.images.front"]).shape == (12, 16, 3)
    q = np.array(ds["observation.part_q"])
    assert q.max() >= 0.85 * 0.32 and np.isfinite(np.array(ds["action"])).all()


def test_the_robot_takes_the_block_from_the_counter_into_the_opened_drawer(robot_run):
    """The carcass top (z 0.8) is the counter: the block stands on it behind the front, the
    drawer is opened to 80 % of its 0.4 m, and the block ends inside the drawer, on its bottom
    (z 0.5 + 18 + 3 + 12 mm), in the twin and in the ground truth (the same kitchen)."""
    m, d = robot_run["same"]
    assert m["robot_pick_place_n"] == 1 and m["robot_pick_place_success"] == 1.0, m
    assert m["robot_pick_place_transfer_success"] == 1.0
    (r,) = json.loads((d / "attempts.json").read_text())["pick_place"]
    assert r["counter_z"] == pytest.approx(0.8, abs=1e-6) and r["q_open"] == pytest.approx(0.32)
    assert r["pick"][2] == pytest.approx(0.8 + 0.025 + 0.001, abs=1e-6) and r["pick"][1] > 0.1
    end = np.asarray(r["twin"]["object_end"])
    assert -0.32 < end[1] < 0.0 and abs(end[0]) < 0.25  # in the opened drawer, in front of the carcass
    assert end[2] == pytest.approx(0.5 + F.T + 0.003 + F.TD + 0.025, abs=0.003)  # standing on its bottom
    assert r["episodes"] == [2] and r["transfer"]["placed"]


def test_a_wrong_joint_does_not_transfer_and_says_why(robot_run):
    m, d = robot_run["hinged"]
    assert m["robot_open_success"] == 1.0 and m["robot_transfer_success"] == 0.0
    a = json.loads((d / "attempts.json").read_text())["parts"][0]
    assert a["transfer"]["reason"] == "wrong axis" and not a["transfer"]["opened"]
    (r,) = json.loads((d / "attempts.json").read_text())["pick_place"]
    assert r["twin"]["placed"] and r["transfer"] == {"placed": False, "reason": "wrong axis", "gt_id": "drawer_0"}
    assert "observation.images.front" not in json.loads((d / "dataset" / "meta" / "info.json").read_text())["features"]


def test_the_ground_truth_kitchen_has_the_layouts_true_joints():
    import yaml

    from drawer_lib.capture.config import SceneConfig
    from drawer_lib.config.typed import to_typed
    from drawer_lib.robot.pipeline import scene_ground_truth
    from drawer_lib.sim.config import SimConfig
    from drawer_lib.sim.mjcf import part_index

    root = Path(__file__).resolve().parents[2]
    sc = to_typed(SceneConfig, yaml.safe_load((root / "conf" / "scene" / "kitchen_tiny.yaml").read_text()), "tiny",
                  strict=False)
    gt = scene_ground_truth(sc, SimConfig())
    m = gt.spec_factory().compile()
    arts = [p for p in gt.parts.parts if p.articulated]
    assert arts
    for p in arts:
        ix = part_index(m, p.id)
        assert ix["joint"] >= 0 and np.allclose(m.jnt_range[ix["joint"]], p.limits)
        ax = np.asarray(p.axis.direction) / np.linalg.norm(p.axis.direction)
        assert np.allclose(m.jnt_axis[ix["joint"]], ax, atol=1e-9)
        expect = mujoco.mjtJoint.mjJNT_HINGE if p.kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE
        assert m.jnt_type[ix["joint"]] == expect
        assert m.body_mass[ix["body"]] > 0.1  # its pieces are solids with the part density
    video = to_typed(SceneConfig, {"source": "video", "video": {"path": "x.mp4"}}, "v", strict=False)
    assert scene_ground_truth(video, SimConfig()) is None


def test_the_block_avoids_what_stands_on_the_counter_and_needs_a_counter():
    """The first spot probed (15 cm behind the front, centred) is taken by a cup: the block goes
    to the next free one; with the carcass's top removed there is no counter (the rays meet the
    drawer, a part, or the floor far below) and no spot; a block wider than the hand is refused."""
    from dataclasses import replace

    from drawer_lib.errors import ConfigError
    from drawer_lib.robot.pick_place import add_object, counter_spot
    from drawer_lib.robot.plan import PickPlaceConfig
    from drawer_lib.sim.mjcf import build_spec

    pp = PickPlaceConfig()
    model = _drawer_kitchen()
    part = F.parts_of(model).parts[0]

    def spot(tm):
        spec = build_spec(tm)
        add_object(spec, np.array([0.0, 0.0, -10.0]), pp)
        m = spec.compile()
        d = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d)
        return counter_spot(m, d, part, pp)

    pos, z = spot(model)
    assert z == pytest.approx(0.8) and pos[:2] == pytest.approx([0.0, 0.15])
    cup = F.cup(0.0, 0.15, 0.8, "cup_0", radius=0.03)
    pos2, _ = spot(replace(model, rigid=[cup]))
    assert abs(pos2[0]) == pytest.approx(0.1) or pos2[1] > 0.2  # moved off the cup
    assert np.hypot(pos2[0], pos2[1] - 0.15) > 0.03 + 0.02
    no_top = [s for s in model.static_collision if not (s.box.center[2] > 0.78)]
    assert spot(replace(model, static_collision=no_top)) is None
    with pytest.raises(ConfigError, match="gripper's opening"):
        PickPlaceConfig(size=(0.04, 0.09, 0.05))


def test_the_base_search_takes_a_pose_that_clears_the_contact_limit_by_the_margin():
    """Contacts (m) in search order, limit 5 mm, margin 1.5 mm: a pose 4.7 mm deep is held back
    for a later one at 2 mm, and the search stops there; with none clear, the first held back
    is taken and flagged; a pose over the limit is never taken."""
    from drawer_lib.robot.pipeline import choose_with_margin

    read = []

    def passing(items):
        for d, name in items:
            read.append(name)
            yield d, name

    assert choose_with_margin(passing([(0.0047, "a"), (0.002, "b"), (0.001, "c")]), 0.005, 0.0015) == ("b", False)
    assert read == ["a", "b"]  # read lazily: nothing after the choice is planned
    assert choose_with_margin(passing([(0.006, "x"), (0.0042, "a"), (0.0049, "b")]), 0.005, 0.0015) == ("a", True)
    assert choose_with_margin(passing([(0.006, "x")]), 0.005, 0.0015) == (None, False)
    assert choose_with_margin(passing([(0.0047, "a")]), 0.005, 0.0) == ("a", False)  # no margin: the first
    assert choose_with_margin(passing([(0.0035, "a")]), 0.005, 0.0015) == ("a", False)  # at the margin: clear
    with pytest.raises(ConfigError, match="collision_margin"):
        RobotConfig(collision_margin=0.005)
    with pytest.raises(ConfigError, match="collision_margin"):
        RobotConfig(collision_margin=-0.001)
