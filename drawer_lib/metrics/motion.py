"""Motion EMD (the paper's Tab. 5, 1.41e-5 for DRAWER; docs/formats.md#motion-emd).

For a predicted part matched to a GT one: an ``n`` x ``n`` grid of points on each front, opened
by the same amount (revolute min(pi/2, both upper limits), prismatic the smaller upper limit)
in ``T`` equal steps — the prediction as the simulated twin moves it, the GT by its joint —
projected into one camera and normalised by (W, H). The cost between two tracks is the mean
over steps of their squared distance; the EMD is the optimal one-to-one assignment of the
predicted tracks to the GT ones (Hungarian: equal counts, uniform weights), its mean cost per
track. Units: normalised image coordinates squared.
"""

from collections.abc import Callable, Sequence

import numpy as np
from jaxtyping import Float
from scipy.optimize import linear_sum_assignment

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import Camera
from drawer_lib.geometry.joints import joint_transform
from drawer_lib.io.parts import Front, Part

GRID = 8
STEPS = 20


def front_grid(front: Front, n: int = GRID) -> Float[np.ndarray, "P 3"]:
    """[n*n, 3] points at the centres of an n x n grid of cells on the front's rectangle (m)."""
    s = (np.arange(n) + 0.5) / n - 0.5
    a, b = np.meshgrid(s * front.size[0], s * front.size[1], indexing="ij")
    return (np.asarray(front.center) + a.reshape(-1, 1) * np.asarray(front.u) + b.reshape(-1, 1) * front.v)


def opening_amount(pred: Part, gt: Part) -> float:
    """How far both are opened (rad or m): revolute min(pi/2, both upper limits), prismatic the
    smaller upper limit."""
    if pred.kind != gt.kind:
        raise InputError(f"motion EMD: {pred.id} is {pred.kind} but its GT {gt.id} is {gt.kind}")
    hi = min(pred.limits[1], gt.limits[1])
    return float(min(np.pi / 2, hi) if gt.kind == "revolute" else hi)


def step_values(amount: float, steps: int = STEPS) -> Float[np.ndarray, "T"]:
    """The T joint values amount * k / T, k = 1..T (the closed pose, shared by both, left out)."""
    return amount * np.arange(1, steps + 1) / steps


def kinematic_tracks(part: Part, points: Float[np.ndarray, "P 3"], qs: Float[np.ndarray, "T"]) -> Float[np.ndarray, "T P 3"]:
    """``points`` (on the part at q = 0) moved by the part's joint to each q of ``qs`` (m)."""
    o, d = np.asarray(part.axis.origin), np.asarray(part.axis.direction)
    out = np.empty((len(qs), len(points), 3))
    for t, q in enumerate(qs):  # T = 20 transforms
        T = joint_transform(part.kind, o, d, float(q))
        out[t] = points @ T[:3, :3].T + T[:3, 3]
    return out


def project_tracks(tracks: Float[np.ndarray, "T P 3"], cam: Camera) -> Float[np.ndarray, "T P 2"]:
    """World tracks (m) into ``cam``, in normalised image coordinates (x / W, y / H). Points
    behind the camera raise: a track must be visible to be scored."""
    T, P, _ = tracks.shape
    uv, z = cam.project(tracks.reshape(-1, 3))
    if not np.all(z > 1e-6):
        raise InputError(f"motion EMD: {int((z <= 1e-6).sum())} track points lie behind the camera")
    wh = np.array([cam.intrinsics.width, cam.intrinsics.height], np.float64)
    return (uv / wh).reshape(T, P, 2)


def track_emd(pred: Float[np.ndarray, "T P 2"], gt: Float[np.ndarray, "T Q 2"]) -> float:
    """EMD between two sets of tracks with uniform weights and equal counts: the mean cost of the
    optimal one-to-one assignment, cost = mean over steps of the squared distance."""
    if pred.shape != gt.shape:
        raise InputError(f"track_emd: shapes {pred.shape} and {gt.shape} differ")
    diff = pred[:, :, None, :] - gt[:, None, :, :]  # [T, P, Q, 2]
    cost = (diff ** 2).sum(-1).mean(0)  # [P, Q]
    if not np.isfinite(cost).all():
        raise InputError("track_emd: non-finite tracks")
    r, c = linear_sum_assignment(cost)
    return float(cost[r, c].mean())


def interpolate_tracks(q: Float[np.ndarray, "K"], points: Float[np.ndarray, "K P 3"],
                       targets: Float[np.ndarray, "T"], q0: float, rest: Float[np.ndarray, "P 3"]) -> Float[np.ndarray, "T P 3"]:
    """Recorded tracks (``points`` when the joint reached each increasing ``q``) at ``targets``,
    linearly between samples, from the ``rest`` points at ``q0``; beyond the last sample the
    last pose (a part that stopped stays where it stopped)."""
    qq = np.concatenate([[q0], np.asarray(q, np.float64)])
    pp = np.concatenate([np.asarray(rest, np.float64)[None], np.asarray(points, np.float64)])
    if np.any(np.diff(qq) <= 0):
        raise InputError("interpolate_tracks: the recorded joint values must increase")
    flat = pp.reshape(len(qq), -1)
    out = np.stack([np.interp(targets, qq, flat[:, j]) for j in range(flat.shape[1])], axis=1)
    return out.reshape(len(targets), *pp.shape[1:])


def motion_emd(pred: Sequence[Part], gt: Sequence[Part], pairs: Sequence[tuple[int, int]], tracks,
               cam: Camera, steps: int = STEPS) -> tuple[dict, list[dict]]:
    """The motion EMD of every correct pair (indices into ``pred`` and ``gt``) from the
    simulated ``tracks`` (``simulate/tracks.npz``: ``<id>/q``, ``<id>/points``,
    ``<id>/front_points``) against the GT's joint, seen by ``cam``. Returns ({"emd", "emd_max",
    "n_emd"} over the pairs seen, or {} without any; per-pair rows)."""

    def simulated(p: Part, qs: np.ndarray) -> np.ndarray:
        key = f"{p.id}/points"
        if key not in tracks:
            raise InputError(f"motion EMD: no simulated track for part {p.id!r} (rerun the simulate stage)")
        rest = tracks[f"{p.id}/front_points"]
        return interpolate_tracks(tracks[f"{p.id}/q"], tracks[key], qs + p.limits[0], p.limits[0], rest)

    return _pair_emds(pred, gt, pairs, simulated, cam, steps)


def kinematic_motion_emd(pred: Sequence[Part], gt: Sequence[Part], pairs: Sequence[tuple[int, int]], cam: Camera,
                         steps: int = STEPS, grid: int = GRID) -> tuple[dict, list[dict]]:
    """:func:`motion_emd` with the prediction moved by its own joint instead of simulated
    (the benchmark's kitchens have no twin): the error of the inferred joint alone."""

    def kinematic(p: Part, qs: np.ndarray) -> np.ndarray:
        return kinematic_tracks(p, front_grid(p.front, grid), qs + p.limits[0])

    return _pair_emds(pred, gt, pairs, kinematic, cam, steps)


def _pair_emds(pred: Sequence[Part], gt: Sequence[Part], pairs: Sequence[tuple[int, int]],
               pred_tracks: Callable[[Part, np.ndarray], np.ndarray], cam: Camera, steps: int) -> tuple[dict, list[dict]]:
    """The EMD rows of ``pairs``; ``pred_tracks(part, qs)`` -> [T, P, 3] the prediction's points
    at the joint values ``qs`` (from its closed pose); the GT moves by its joint, on a grid of
    as many points on its own front."""
    rows = []
    for i, j in pairs:
        p, g = pred[i], gt[j]
        amount = opening_amount(p, g)
        qs = step_values(amount, steps)
        moved = pred_tracks(p, qs)
        gtr = kinematic_tracks(g, front_grid(g.front, int(round(np.sqrt(moved.shape[1])))), qs + g.limits[0])
        row = {"pred": p.id, "gt": g.id, "kind": g.kind, "amount": amount, "emd": None}
        try:
            row["emd"] = track_emd(project_tracks(moved, cam), project_tracks(gtr, cam))
        except InputError as e:  # a track behind the camera: not scored, said why
            row["skipped"] = str(e)
        rows.append(row)
    es = np.array([r["emd"] for r in rows if r["emd"] is not None])
    if not len(es):
        return {}, rows
    return {"emd": float(es.mean()), "emd_max": float(es.max()), "n_emd": len(rows)}, rows
