"""What the ``robot`` stage does: a Panda opens and closes every articulated part of the twin,
puts a block from the counter into an opened drawer (:mod:`drawer_lib.robot.pick_place`), and
each demonstration is replayed in the ground-truth kitchen.

Per part with a grasp (``twin.json``): find a base pose (:func:`drawer_lib.robot.plan.
base_candidates`, kinematic IK and collision checks), solve the IK along the whole path, then
simulate it in the twin as it loads (drives off: the robot moves the part by its handle alone),
with the stability study's integrator and timestep. The part is *opened* when its joint reaches
``success_fraction`` x the target (``open_fraction`` of its stop: its upper limit, or where a
neighbour or the carcass stops it, ``twin.json`` ``stop``) by the end of the hold,
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

Outputs: ``attempts.json`` (per part: base, pitch, results, reasons, episode indices; per
pick-and-place: the spots, base, results, reasons), the dataset (:mod:`drawer_lib.robot.dataset`,
two episodes per opening demonstration: open, then close; one per pick-and-place), metrics.
"""

import json
import math
import time
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TypeVar

import mujoco
import numpy as np

from drawer_lib.errors import InputError
from drawer_lib.io.images import write_json
from drawer_lib.io.parts import Part, PartsFile, read_parts
from drawer_lib.metrics.articulation import hinge_side, match_parts, part_kind
from drawer_lib.robot.dataset import Episode, write_lerobot
from drawer_lib.robot.execute import PlanningScene, Recording, episode_model, run_episode
from drawer_lib.robot.ik import PandaIK
from drawer_lib.robot.pick_place import (OBJECT, PICK_PHASES, Site, front_frame, ray_down, counter_spot,
                                         object_in_part, pick_key_ticks, pick_place_path, place_spot, with_object)
from drawer_lib.robot.panda import ARM, FINGERS
from drawer_lib.robot.plan import (PHASES, RobotConfig, base_candidates, grasp_pose, key_ticks, open_width,
                                   solve_path, task_path)
from drawer_lib.paths import stage_name
from drawer_lib.runner import StageRun
from drawer_lib.sim.mjcf import INTEGRATOR_ENUM, load_twin

COLLISION_FAIL = 0.01  # m: an arm contact deeper than this is a collision failure
EMPTY_GRIP = 0.003  # m: fingers closer than this hold nothing
AXIS_FAIL_DEG = 15.0
T = TypeVar("T")


@dataclass
class GroundTruth:
    """A scene's own kitchen: a factory of its MuJoCo spec and its parts."""

    spec_factory: object
    parts: PartsFile


def _phase_end(rec: Recording, phase: str) -> int:
    idx = np.flatnonzero(rec.phase == PHASES.index(phase))
    return int(idx[-1]) if len(idx) else len(rec.phase) - 1


def choose_with_margin(passing: Iterable[tuple[float, T]], limit: float, margin: float) -> tuple[T | None, bool]:
    """The base search's choice (:mod:`drawer_lib.robot.plan`): of ``passing`` ((deepest
    contact m, candidate) in search order, read lazily), the first whose contact is at most
    ``limit - margin``; else the first at most ``limit``, flagged (True); else (None, False)."""
    held = None
    for deepest, item in passing:
        if deepest > limit:
            continue
        if deepest <= limit - margin:
            return item, False
        if held is None:
            held = item
    return held, held is not None


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


def _frames(rec: Recording, sl: slice, camera: bool) -> dict[str, np.ndarray]:
    """The dataset features (:data:`FEATURES_BASE`, and the camera) of ``rec``'s frames ``sl``."""
    fr = {"observation.state": rec.state[sl], "action": rec.action[sl], "observation.ee_pose": rec.tcp[sl],
          "observation.part_q": rec.part_q[sl]}
    if camera:
        fr["observation.images.front"] = rec.images[sl]
    return fr


def _episodes(rec: Recording, part: Part, camera: bool) -> list[Episode]:
    """The recording as two episodes: open (approach .. hold) and close (close .. retreat)."""
    name = str(part.extra.get("family", part.kind))
    split = _phase_end(rec, "hold") + 1
    out = []
    for task, sl in ((f"open the {name} {part.id}", slice(0, split)), (f"close the {name} {part.id}",
                                                                        slice(split, len(rec.time)))):
        if sl.stop - sl.start < 1:
            continue
        out.append(Episode(task, _frames(rec, sl, camera)))
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
    index = json.loads(index_path.read_text())["parts"]
    grasps = {p["id"]: p.get("grasp") for p in index}
    # how far each part opens in the twin: its upper limit, or where a neighbour or the carcass stops it
    stops = {p["id"]: p["stop"]["q"] for p in index if p.get("stop")}
    parts = [p for p in read_parts(parts_path).parts if p.articulated]
    all_parts = list(parts)
    if cfg.max_parts is not None:
        parts = parts[: cfg.max_parts]
    if option is not None:
        option = (INTEGRATOR_ENUM[option[0]], float(option[1]))

    def twin_spec():
        return mujoco.MjSpec.from_file(str(xml))

    matched: dict[str, Part] = {}
    if gt is not None and cfg.transfer:
        mt = match_parts(PartsFile(tuple(all_parts)), gt.parts)
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
        q_goal = cfg.open_fraction * min(p.limits[1], stops.get(p.id, p.limits[1]))
        n_tried = 0

        def passing():  # (deepest contact, plan) of each base pose that passes the IK and the contact limit
            nonlocal n_tried
            for base, pitch, flip in base_candidates(p, g, cfg.base, q_goal):
                n_tried += 1
                G = grasp_pose(g, pitch, flip)
                ticks = task_path(p, G, cfg, fo, q_goal)
                idx = key_ticks(ticks)
                qs, ep, er = solve_path(ik, base, ticks, idx, give_up=tol)
                if ep > tol[0] or er > tol[1]:
                    continue
                deepest = ps.deepest_contact(base, p.id, ((q, ticks[i].q_part, fo) for i, q in zip(idx, qs)))
                if deepest > cfg.collision_depth:
                    continue
                qs, ep, er = solve_path(ik, base, ticks, list(range(len(ticks))), q0=qs[0])
                if ep <= 2 * tol[0] and er <= 2 * tol[1]:
                    yield deepest, (base, pitch, flip, ticks, qs, ep, er, deepest, n_tried)

        found, low_margin = None, False
        if g is not None:
            fo = open_width(g, cfg)
            found, low_margin = choose_with_margin(passing(), cfg.collision_depth, cfg.collision_margin)
        a["base_candidates_tried"] = n_tried
        t_plan += time.perf_counter() - t0
        if found is None:
            a["twin"] = {"opened": False, "closed": False, "reason": "unreachable" if g else "no grasp"}
            if gt is not None and cfg.transfer:
                gp = matched.get(p.id)
                a["transfer"] = {"opened": False, "reason": "failed in the twin", "gt_id": gp.id if gp else None}
            attempts.append(a)
            continue
        base, pitch, flip, ticks, qs, ep, er, deepest, k_base = found
        a |= {"base": {"pos": list(base.pos), "yaw": base.yaw}, "pitch_rad": pitch, "flip": flip,
              "ik_error_m": ep, "ik_error_rad": er, "q_goal": q_goal, "base_candidate": k_base,
              "base_deepest_contact_m": deepest, "base_low_margin": low_margin}
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

    t0 = time.perf_counter()
    placements = []
    drawers = sorted((p for p in all_parts if p.kind == "prismatic" and p.extra.get("family", "drawer") == "drawer"),
                     key=lambda p: -float(p.front.corners()[:, 2].max()))[: cfg.pick_place.max_drawers]
    for p in run.progress(drawers, desc="pick and place", total=len(drawers)):
        q_open = cfg.open_fraction * min(p.limits[1], stops.get(p.id, p.limits[1]))
        rec_pp, eps = pick_and_place(cfg, p, q_open, twin_spec, ik, ps, option, cam,
                                     matched.get(p.id) if gt is not None and cfg.transfer else None,
                                     gt.spec_factory if gt is not None and cfg.transfer else None)
        rec_pp["episodes"] = list(range(len(episodes), len(episodes) + len(eps)))
        episodes += eps
        placements.append(rec_pp)
    t_pick = time.perf_counter() - t0

    camera = cam[0] > 0
    feats = dict(FEATURES_BASE)
    if camera:
        feats["observation.images.front"] = {"dtype": "image", "shape": [cam[1], cam[0], 3],
                                             "names": ["height", "width", "channels"]}
    metrics = _metrics(attempts, gt is not None and cfg.transfer)
    metrics |= _pick_metrics(placements, gt is not None and cfg.transfer)
    metrics |= {"robot_plan_s": round(t_plan, 3), "robot_sim_s": round(t_sim, 3), "robot_transfer_s": round(t_gt, 3),
                "robot_pick_place_s": round(t_pick, 3)}
    if episodes:
        info = write_lerobot(run.out("dataset"), episodes, feats, cfg.fps, robot_type="franka_panda")
        size = sum(f.stat().st_size for f in run.out("dataset").rglob("*") if f.is_file())
        metrics |= {"dataset_episodes": info["total_episodes"], "dataset_frames": info["total_frames"],
                    "dataset_bytes": size}
    else:
        run.skip("dataset", "no demonstration ran")
        run.out("dataset").mkdir(parents=True)
    write_json(run.out("attempts"), {"parts": attempts, "pick_place": placements})
    return metrics


def _pick_reason(rec: Recording, placed: bool) -> str | None:
    """Why a pick-and-place did not put the block in the drawer (module docstring)."""
    if placed:
        return None
    if rec.problem:
        return "diverged"
    width = rec.state[:, 7] + rec.state[:, 8]
    g = int(np.flatnonzero(rec.phase == PICK_PHASES.index("grip"))[-1])
    if width[g] < EMPTY_GRIP:
        return "missed object"
    if (width[rec.phase == PICK_PHASES.index("carry")] < EMPTY_GRIP).any():
        return "dropped"
    return "missed drawer"


def pick_and_place(cfg: RobotConfig, p: Part, q_open: float, twin_spec, ik: PandaIK, ps: PlanningScene,
                   option, cam: tuple[int, int], gp: Part | None, gt_spec) -> tuple[dict, list[Episode]]:
    """One pick-and-place on drawer ``p`` opened to ``q_open`` (:mod:`drawer_lib.robot.pick_place`),
    replayed in the ground truth (``gt_spec``, with ``gp`` the matched GT part) when given.
    Returns its record for ``attempts.json`` and its episode (none when it did not run)."""
    pp = cfg.pick_place
    out: dict = {"id": p.id, "q_open": q_open}
    mt = with_object(twin_spec, np.array([0.0, 0.0, -10.0]), pp)().compile()  # the block parked below the floor
    d = mujoco.MjData(mt)
    mujoco.mj_kinematics(mt, d)
    spot = counter_spot(mt, d, p, pp)
    if spot is None:
        return out | {"twin": {"placed": False, "reason": "no counter"}}, []
    pick, counter_z = spot
    place = place_spot(mt, d, p, q_open, counter_z, pp)
    if place is None:
        return out | {"pick": pick.tolist(), "twin": {"placed": False, "reason": "no drawer bottom"}}, []
    c, n, u, top = front_frame(p)
    site = Site(pick, counter_z, place, q_open, n, u)
    ticks = pick_place_path(site, cfg, pp, top)
    idx = pick_key_ticks(ticks)
    tol = (cfg.ik_tol_m, math.radians(cfg.ik_tol_deg))
    pseudo = {"position": (0.5 * (pick + place)).tolist(), "approach": (-n).tolist(), "closing_axis": u.tolist()}
    seen = set()
    search = replace(cfg.base, heights=pp.base_heights, distances=pp.base_distances, pitches_deg=(0.0,))

    def passing():  # (deepest contact, plan) of each base pose that passes the IK and the contact limit
        for base, _, _ in base_candidates(p, pseudo, search, 0.0):
            key = (*np.round(base.pos, 4), round(base.yaw, 4))
            if key in seen:
                continue
            seen.add(key)
            qs, ep, er = solve_path(ik, base, ticks, idx, give_up=tol)
            if ep > tol[0] or er > tol[1]:
                continue
            deepest = ps.deepest_contact(base, p.id, ((q, q_open, max(0.0, ticks[i].finger)) for i, q in zip(idx, qs)))
            if deepest > cfg.collision_depth:
                continue
            qs, ep, er = solve_path(ik, base, ticks, list(range(len(ticks))), q0=qs[0])
            if ep <= 2 * tol[0] and er <= 2 * tol[1]:
                yield deepest, (base, qs, deepest, len(seen))

    found, low_margin = choose_with_margin(passing(), cfg.collision_depth, cfg.collision_margin)
    out |= {"pick": pick.tolist(), "place": place.tolist(), "counter_z": counter_z,
            "base_candidates_tried": len(seen)}
    if found is None:
        return out | {"twin": {"placed": False, "reason": "unreachable"}}, []
    base, qs, deepest, k_base = found
    out |= {"base": {"pos": list(base.pos), "yaw": base.yaw}, "base_candidate": k_base,
            "base_deepest_contact_m": deepest, "base_low_margin": low_margin}
    actions = np.column_stack([qs, [tk.finger for tk in ticks]])
    m = episode_model(with_object(twin_spec, pick, pp), base, option, cam, pick)
    rec = run_episode(m, ticks, actions, p.id, PICK_PHASES, cam, start={p.id: q_open},
                      probe=lambda m, d: {"placed": object_in_part(m, d, p.id, counter_z),
                                          "object_end": d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY,
                                                                                OBJECT)].tolist()})
    placed = bool(rec.extra.get("placed", False))
    out["twin"] = {"placed": placed, "reason": _pick_reason(rec, placed), "object_end": rec.extra.get("object_end"),
                   "problem": rec.problem, "sim_steps": rec.sim_steps}
    episode = Episode(f"pick up the block from the counter and place it in the drawer {p.id}",
                      _frames(rec, slice(None), cam[0] > 0))
    if gt_spec is not None:
        out["transfer"] = _pick_transfer(cfg, p, site, gp, gt_spec, base, ticks, actions, option)
    return out, [episode]


def _pick_transfer(cfg: RobotConfig, p: Part, site: Site, gp: Part | None, gt_spec, base, ticks, actions,
                   option) -> dict:
    """The pick-and-place's actions replayed in the ground-truth kitchen: the block on the real
    counter at the same (x, y), the matched part opened to the same q (clipped to its range)."""
    pp = cfg.pick_place
    if gp is None:
        return {"placed": False, "reason": "no such part", "gt_id": None}
    if gp.kind != "prismatic":
        return {"placed": False, "reason": "wrong axis", "gt_id": gp.id}
    mg = gt_spec().compile()
    dg = mujoco.MjData(mg)
    mujoco.mj_kinematics(mg, dg)
    _, _, _, top = front_frame(p)
    z, g = ray_down(mg, dg, site.pick[:2], top + pp.probe_height)
    static = mujoco.mj_name2id(mg, mujoco.mjtObj.mjOBJ_BODY, "static")
    if g < 0 or mg.geom_bodyid[g] != static:
        return {"placed": False, "reason": "no counter", "gt_id": gp.id}
    gpick = np.array([site.pick[0], site.pick[1], z + pp.size[2] / 2 + 0.001])
    q = float(min(site.q_open, gp.limits[1]))
    m = episode_model(with_object(gt_spec, gpick, pp), base, option, (0, 0), gpick)
    rec = run_episode(m, ticks, actions, gp.id, PICK_PHASES, start={gp.id: q},
                      probe=lambda m, d: {"placed": object_in_part(m, d, gp.id, z)})
    placed = bool(rec.extra.get("placed", False))
    return {"placed": placed, "reason": _pick_reason(rec, placed), "gt_id": gp.id, "gt_q_open": q,
            "counter_z": z, "problem": rec.problem}


def _pick_metrics(placements: list[dict], transfer: bool) -> dict:
    n = len(placements)
    m: dict = {"robot_pick_place_n": n}
    if not n:
        return m
    m["robot_pick_place_success"] = sum(r["twin"]["placed"] for r in placements) / n
    for r, c in sorted(Counter(x["twin"]["reason"] for x in placements if x["twin"]["reason"]).items()):
        m[f"robot_pick_place_fail_{r.replace(' ', '_')}"] = c
    if transfer:
        tr = [x.get("transfer", {"placed": False, "reason": "failed in the twin"}) for x in placements]
        m["robot_pick_place_transfer_success"] = sum(t["placed"] for t in tr) / n
        for r, c in sorted(Counter(t["reason"] for t in tr if t["reason"]).items()):
            m[f"robot_pick_place_transfer_fail_{r.replace(' ', '_')}"] = c
    return m


def _metrics(attempts: list[dict], transfer: bool) -> dict:
    n = len(attempts)
    m: dict = {"robot_parts": n}
    if not n:
        return m
    opened = sum(a["twin"]["opened"] for a in attempts)
    closed = sum(a["twin"]["closed"] for a in attempts)
    m |= {"robot_success": (opened + closed) / (2 * n), "robot_open_success": opened / n,
          "robot_close_success": closed / n,
          "robot_low_margin_bases": sum(bool(a.get("base_low_margin")) for a in attempts)}
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
