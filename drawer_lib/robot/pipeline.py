"""What the ``robot`` stage does: a Panda opens and closes every articulated part of the twin,
and each demonstration is replayed in the ground-truth kitchen.

Per part with a grasp (``twin.json``): find a base pose (:func:`drawer_lib.robot.plan.
base_candidates`, kinematic IK and collision checks), solve the IK along the whole path, then
simulate it in the twin as it loads (drives off: the robot moves the part by its handle alone),
with the stability study's integrator and timestep. The part is *opened* when its joint reaches
``success_fraction`` x the target (``open_fraction`` of its upper limit) by the end of the hold,
*closed* when it is back below (1 - ``success_fraction``) x the target at the end.

Transfer (scenes with a procedural ground truth): the same actions (joint targets and gripper
commands, tick by tick, the base where it stood) replayed open-loop in the kitchen's own model
(:func:`drawer_lib.robot.gt_kitchen.layout_twin_model`: its true joints, handles and boxes). The twin
part is matched to a GT part by front overlap; the GT part is opened when its joint reaches
``success_fraction`` x min(the twin's target, ``open_fraction`` x its own upper limit).

Failure reasons: in the twin ``unreachable`` (no base pose passes, or the IK loses the path),
``handle missed`` (when the grip has closed, no finger touches the part or the fingers hold
nothing: closer than 3 mm), ``grip lost`` (the fingers close on nothing while pulling),
``collision`` (the arm
presses into the scene deeper than 1 cm), ``diverged``, ``opened short``; after transfer also
``no such part`` (no GT part under the twin's front), ``wrong axis`` (another joint kind, or an
axis > 15° off), ``wrong hinge side``. The first that applies is reported.

Outputs: ``attempts.json`` (per part: base, pitch, results, reasons, episode indices), the
dataset (:mod:`drawer_lib.robot.dataset`, two episodes per demonstration: open, then close),
metrics.
"""

import json
import math
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from drawer_lib.errors import InputError
from drawer_lib.io.images import write_json
from drawer_lib.io.parts import Part, PartsFile, read_parts
from drawer_lib.metrics.articulation import hinge_side, match_parts, part_kind
from drawer_lib.robot.dataset import Episode, write_lerobot
from drawer_lib.robot.execute import PlanningScene, Recording, episode_model, run_episode
from drawer_lib.robot.ik import PandaIK
from drawer_lib.robot.panda import ARM, FINGERS
from drawer_lib.robot.plan import (PHASES, RobotConfig, base_candidates, grasp_pose, key_ticks, open_width,
                                   solve_path, task_path)
from drawer_lib.paths import stage_name
from drawer_lib.runner import StageRun
from drawer_lib.sim.mjcf import INTEGRATOR_ENUM, load_twin

COLLISION_FAIL = 0.01  # m: an arm contact deeper than this is a collision failure
EMPTY_GRIP = 0.003  # m: fingers closer than this hold nothing
AXIS_FAIL_DEG = 15.0


@dataclass
class GroundTruth:
    """A scene's own kitchen: a factory of its MuJoCo spec and its parts."""

    spec_factory: object
    parts: PartsFile


def _phase_end(rec: Recording, phase: str) -> int:
    idx = np.flatnonzero(rec.phase == PHASES.index(phase))
    return int(idx[-1]) if len(idx) else len(rec.phase) - 1


def _twin_reason(rec: Recording, opened: bool) -> str | None:
    """Why a demonstration did not open its part (module docstring), from its recording."""
    if opened:
        return None
    if rec.problem and "NaN" in rec.problem:
        return "diverged"
    g = _phase_end(rec, "grip")
    width = rec.state[:, 7] + rec.state[:, 8]  # the fingers' opening, m
    if not rec.touch[g] or width[g] < EMPTY_GRIP:
        return "handle missed"
    moving = rec.phase == PHASES.index("open")
    if (width[moving] < EMPTY_GRIP).any():
        return "grip lost"
    if rec.collision.max(initial=0.0) > COLLISION_FAIL:
        return "collision"
    return "opened short"


def _axis_angle_deg(a: Part, b: Part) -> float:
    da, db = np.asarray(a.axis.direction), np.asarray(b.axis.direction)
    c = float(da @ db / (np.linalg.norm(da) * np.linalg.norm(db)))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def _transfer_reason(twin: Part, gt: Part | None, rec: Recording | None, opened: bool) -> str | None:
    if opened:
        return None
    if gt is None:
        return "no such part"
    if gt.kind != twin.kind or _axis_angle_deg(twin, gt) > AXIS_FAIL_DEG:
        return "wrong axis"
    if twin.kind == "revolute" and hinge_side(twin) != hinge_side(gt):
        return "wrong hinge side"
    return "not run" if rec is None else _twin_reason(rec, False)


FEATURES_BASE = {
    "observation.state": {"dtype": "float32", "shape": [9], "names": [*ARM, *FINGERS]},
    "action": {"dtype": "float32", "shape": [8], "names": [*(f"{n}.target" for n in ARM), "gripper.finger_target"]},
    "observation.ee_pose": {"dtype": "float32", "shape": [7], "names": ["x", "y", "z", "qw", "qx", "qy", "qz"]},
    "observation.part_q": {"dtype": "float32", "shape": [1], "names": None},
}


def _episodes(rec: Recording, part: Part, camera: bool) -> list[Episode]:
    """The recording as two episodes: open (approach .. hold) and close (close .. retreat)."""
    name = str(part.extra.get("family", part.kind))
    split = _phase_end(rec, "hold") + 1
    out = []
    for task, sl in ((f"open the {name} {part.id}", slice(0, split)), (f"close the {name} {part.id}",
                                                                        slice(split, len(rec.time)))):
        if sl.stop - sl.start < 1:
            continue
        fr = {"observation.state": rec.state[sl], "action": rec.action[sl], "observation.ee_pose": rec.tcp[sl],
              "observation.part_q": rec.part_q[sl]}
        if camera:
            fr["observation.images.front"] = rec.images[sl]
        out.append(Episode(task, fr))
    return out


def run_robot(cfg: RobotConfig, twin_dir: Path, parts_path: Path, run: StageRun, option: tuple[str, float] | None,
              gt: GroundTruth | None) -> dict:
    """The stage (module docstring): writes ``attempts.json`` and the dataset; returns metrics.
    ``option``: (integrator, timestep s) to simulate with, the stability study's choice (None:
    the twin's own)."""
    xml, _ = load_twin(twin_dir, parts_path)
    index_path = Path(twin_dir) / stage_name("twin", "index")
    if not index_path.is_file():
        raise InputError(f"{index_path}: missing (run the twin stage first)")
    grasps = {p["id"]: p.get("grasp") for p in json.loads(index_path.read_text())["parts"]}
    parts = [p for p in read_parts(parts_path).parts if p.articulated]
    if cfg.max_parts is not None:
        parts = parts[: cfg.max_parts]
    if option is not None:
        option = (INTEGRATOR_ENUM[option[0]], float(option[1]))

    def twin_spec():
        return mujoco.MjSpec.from_file(str(xml))

    matched: dict[str, Part] = {}
    if gt is not None and cfg.transfer:
        mt = match_parts(PartsFile(tuple(parts)), gt.parts)
        matched = {mt.pred[i].id: mt.gt[j] for i, j, _ in mt.pairs}
    elif cfg.transfer:
        run.skip("robot_transfer_success", "the scene has no ground-truth kitchen to replay in")
    cam = tuple(cfg.camera) if min(cfg.camera) > 0 else (0, 0)
    ik = PandaIK()
    ps = PlanningScene(twin_spec)
    attempts, episodes = [], []
    t_plan = t_sim = t_gt = 0.0
    tol = (cfg.ik_tol_m, math.radians(cfg.ik_tol_deg))
    for p in run.progress(parts, desc="parts", total=len(parts)):
        t0 = time.perf_counter()
        a: dict = {"id": p.id, "kind": part_kind(p), "joint": p.kind}
        g = grasps.get(p.id)
        q_goal = cfg.open_fraction * p.limits[1]
        found, n_tried = None, 0
        if g is not None:
            fo = open_width(g, cfg)
            for base, pitch, flip in base_candidates(p, g, cfg.base, q_goal):
                n_tried += 1
                G = grasp_pose(g, pitch, flip)
                ticks = task_path(p, G, cfg, fo)
                idx = key_ticks(ticks)
                qs, ep, er = solve_path(ik, base, ticks, idx, give_up=tol)
                if ep > tol[0] or er > tol[1] or any(
                        ps.collisions(base, q, p.id, ticks[i].q_part, cfg.collision_depth, fo)
                        for i, q in zip(idx, qs)):
                    continue
                qs, ep, er = solve_path(ik, base, ticks, list(range(len(ticks))), q0=qs[0])
                if ep <= 2 * tol[0] and er <= 2 * tol[1]:
                    found = (base, pitch, flip, ticks, qs, ep, er)
                    break
        a["base_candidates_tried"] = n_tried
        t_plan += time.perf_counter() - t0
        if found is None:
            a["twin"] = {"opened": False, "closed": False, "reason": "unreachable" if g else "no grasp"}
            if gt is not None and cfg.transfer:
                gp = matched.get(p.id)
                a["transfer"] = {"opened": False, "reason": "failed in the twin", "gt_id": gp.id if gp else None}
            attempts.append(a)
            continue
        base, pitch, flip, ticks, qs, ep, er = found
        a |= {"base": {"pos": list(base.pos), "yaw": base.yaw}, "pitch_rad": pitch, "flip": flip,
              "ik_error_m": ep, "ik_error_rad": er, "q_goal": q_goal}
        actions = np.column_stack([qs, [tk.finger for tk in ticks]])
        t0 = time.perf_counter()
        m = episode_model(twin_spec, base, option, cam, np.asarray(g["position"]))
        rec = run_episode(m, ticks, actions, p.id, PHASES, cam)
        t_sim += time.perf_counter() - t0
        q_hold, q_end = float(rec.part_q[_phase_end(rec, "hold")]), float(rec.part_q[-1])
        opened = bool(q_hold >= cfg.success_fraction * q_goal and rec.problem is None)
        closed = bool(opened and q_end <= (1 - cfg.success_fraction) * q_goal)
        a["twin"] = {"opened": opened, "closed": closed, "q_hold": q_hold, "q_end": q_end,
                     "max_arm_contact_m": float(rec.collision.max(initial=0.0)), "problem": rec.problem,
                     "reason": _twin_reason(rec, opened), "sim_steps": rec.sim_steps}
        eps = _episodes(rec, p, cam[0] > 0)
        a["episodes"] = list(range(len(episodes), len(episodes) + len(eps)))
        episodes += eps
        if gt is not None and cfg.transfer:
            gp = matched.get(p.id)
            tr: dict = {"gt_id": gp.id if gp else None}
            grec = None
            if gp is not None:
                t0 = time.perf_counter()
                gm = episode_model(gt.spec_factory, base, option, (0, 0), np.asarray(g["position"]))
                grec = run_episode(gm, ticks, actions, gp.id, PHASES)
                t_gt += time.perf_counter() - t0
                gq = float(grec.part_q[_phase_end(grec, "hold")])
                goal = min(q_goal, cfg.open_fraction * gp.limits[1])
                ok = bool(gp.kind == p.kind and gq >= cfg.success_fraction * goal and grec.problem is None)
                tr |= {"opened": ok, "q_hold": gq, "goal": goal, "gt_kind": part_kind(gp)}
            else:
                ok = False
                tr["opened"] = False
            tr["reason"] = _transfer_reason(p, gp, grec, ok)
            a["transfer"] = tr
        attempts.append(a)

    camera = cam[0] > 0
    feats = dict(FEATURES_BASE)
    if camera:
        feats["observation.images.front"] = {"dtype": "image", "shape": [cam[1], cam[0], 3],
                                             "names": ["height", "width", "channels"]}
    metrics = _metrics(attempts, gt is not None and cfg.transfer)
    metrics |= {"robot_plan_s": round(t_plan, 3), "robot_sim_s": round(t_sim, 3), "robot_transfer_s": round(t_gt, 3)}
    if episodes:
        info = write_lerobot(run.out("dataset"), episodes, feats, cfg.fps, robot_type="franka_panda")
        size = sum(f.stat().st_size for f in run.out("dataset").rglob("*") if f.is_file())
        metrics |= {"dataset_episodes": info["total_episodes"], "dataset_frames": info["total_frames"],
                    "dataset_bytes": size}
    else:
        run.skip("dataset", "no demonstration ran")
        run.out("dataset").mkdir(parents=True)
    write_json(run.out("attempts"), {"parts": attempts})
    return metrics


def _metrics(attempts: list[dict], transfer: bool) -> dict:
    n = len(attempts)
    m: dict = {"robot_parts": n}
    if not n:
        return m
    opened = sum(a["twin"]["opened"] for a in attempts)
    closed = sum(a["twin"]["closed"] for a in attempts)
    m |= {"robot_success": (opened + closed) / (2 * n), "robot_open_success": opened / n,
          "robot_close_success": closed / n}
    reasons = Counter(a["twin"]["reason"] for a in attempts if a["twin"]["reason"])
    m |= {f"robot_fail_{r.replace(' ', '_')}": c for r, c in sorted(reasons.items())}
    kinds = sorted({a["kind"] for a in attempts})
    for k in kinds:
        ks = [a for a in attempts if a["kind"] == k]
        m[f"robot_{k}_n"] = len(ks)
        m[f"robot_{k}_opened"] = sum(a["twin"]["opened"] for a in ks)
    if transfer:
        t_ok = sum(a.get("transfer", {}).get("opened", False) for a in attempts)
        m |= {"robot_transfer_success": t_ok / n,
              "robot_transfer_given_twin": t_ok / opened if opened else None}
        tr = Counter(a["transfer"]["reason"] for a in attempts if a.get("transfer", {}).get("reason"))
        m |= {f"robot_transfer_fail_{r.replace(' ', '_')}": c for r, c in sorted(tr.items())}
        for k in kinds:
            ks = [a for a in attempts if a["kind"] == k]
            m[f"robot_{k}_transferred"] = sum(a.get("transfer", {}).get("opened", False) for a in ks)
    return m


def scene_ground_truth(scene, sim) -> GroundTruth | None:
    """The ground-truth kitchen of a procedural scene (``scene.source == "synth"``): its own
    physical model built with the twin's simulation config ``sim`` (joints, contacts,
    densities), and its parts; None for other scenes."""
    if scene is None or getattr(scene, "source", None) != "synth" or scene.synth is None:
        return None
    from drawer_lib.sim.mjcf import build_spec
    from drawer_lib.robot.gt_kitchen import layout_twin_model
    from drawer_lib.synth.gt import layout_parts
    from drawer_lib.synth.layout import sample_layout

    layout = sample_layout(scene.synth)
    model = layout_twin_model(layout, sim.densities.part, sim.densities.rigid)
    return GroundTruth(lambda: build_spec(model, sim), layout_parts(layout))
