"""The interaction test: each hypothesis' motion swept through the reconstructed scene.

A front that opens as hypothesis H moves its panel along H's joint (the part
:func:`~drawer_lib.articulation.joints.make_part` would build). Where the moving panel comes
within ``clearance`` of the scene's surface (points sampled on the reconstructed mesh), the
motion is blocked: a door whose swing hits a neighbouring unit or a wall, a flap that hits a
shelf in front of it, a drawer pulled into an island. A drawer also needs room behind it: its
box (the front's rectangle, inset, reaching back the drawer's travel) must not cut through a
surface the cameras saw there (a back panel or a wall at 10 cm is no drawer).

``clear`` is the fraction of the motion (0 .. 1 of the joint's range) before the first
contact; :func:`blocked_hypotheses` excludes a hypothesis whose ``clear`` is below
``min_clear``, with why. Sliding doors are not swept (they run in their own track, which
:func:`~drawer_lib.articulation.decide.missing_evidence` already asks for).

The front's own surface is not an obstacle: the points within its rectangle (grown by
``own_margin``) that lie from ``own_depth`` behind to ``own_proud`` in front of its plane (its
panel, its handle) move with it. Lengths in metres; a front's frame is (u, v, normal) about the
centre of its outer face (:class:`~drawer_lib.io.parts.Front`).
"""

from dataclasses import dataclass

import numpy as np
from jaxtyping import Float
from scipy.spatial import cKDTree

from drawer_lib.articulation.config import InteractionConfig, JointsConfig
from drawer_lib.articulation.joints import make_part
from drawer_lib.articulation.vocab import HYPOTHESES, Decision
from drawer_lib.geometry.joints import apply_transform, joint_transform
from drawer_lib.io.parts import Front


@dataclass(frozen=True)
class Obstacles:
    """The scene's surface as points [P, 3] in a k-d tree."""

    points: np.ndarray
    tree: cKDTree

    @staticmethod
    def of(points: Float[np.ndarray, "P 3"]) -> "Obstacles":
        pts = np.asarray(points, np.float64).reshape(-1, 3)
        if not np.isfinite(pts).all():
            raise ValueError("interaction: obstacle points must be finite")
        return Obstacles(pts, cKDTree(pts))


def front_coords(front: Front, points: np.ndarray) -> np.ndarray:
    """[N, 3] (u, v, z) of ``points`` in the front's frame (z: out of the front, along its normal)."""
    rel = np.asarray(points, np.float64) - np.asarray(front.center)
    return np.stack([rel @ np.asarray(front.u), rel @ front.v, rel @ np.asarray(front.normal)], axis=-1)


def own_surface(front: Front, points: np.ndarray, cfg: InteractionConfig) -> np.ndarray:
    """[N] bool: the points that belong to the front itself (its panel and handle)."""
    c = front_coords(front, points)
    return ((np.abs(c[:, 0]) <= front.size[0] / 2 + cfg.own_margin)
            & (np.abs(c[:, 1]) <= front.size[1] / 2 + cfg.own_margin)
            & (c[:, 2] >= -cfg.own_depth) & (c[:, 2] <= cfg.own_proud))


def panel_samples(front: Front, spacing: float, inset: float = 0.0, depth: float = 0.0) -> np.ndarray:
    """[N, 3] points on the front's outer face (inset by ``inset`` from its edges) on a grid of
    about ``spacing``; with ``depth`` > 0 also on the four sides of the box reaching ``depth``
    behind it (a drawer's box)."""
    w, h = max(front.size[0] - 2 * inset, 1e-3), max(front.size[1] - 2 * inset, 1e-3)
    nu, nv = max(int(np.ceil(w / spacing)) + 1, 2), max(int(np.ceil(h / spacing)) + 1, 2)
    uu, vv = np.meshgrid(np.linspace(-w / 2, w / 2, nu), np.linspace(-h / 2, h / 2, nv))
    uvz = [np.stack([uu.ravel(), vv.ravel(), np.zeros(uu.size)], -1)]
    if depth > 0:
        nz = max(int(np.ceil(depth / spacing)) + 1, 2)
        zz = np.linspace(-depth, 0.0, nz)
        for fixed, lin, axis in ((w / 2, np.linspace(-h / 2, h / 2, nv), 0), (h / 2, np.linspace(-w / 2, w / 2, nu), 1)):
            for s in (-1.0, 1.0):
                a, z = np.meshgrid(lin, zz)
                side = np.zeros((a.size, 3))
                side[:, axis] = s * fixed
                side[:, 1 - axis] = a.ravel()
                side[:, 2] = z.ravel()
                uvz.append(side)
    uvz = np.concatenate(uvz)
    c, u, v, n = np.asarray(front.center), np.asarray(front.u), front.v, np.asarray(front.normal)
    return c + uvz[:, :1] * u + uvz[:, 1:2] * v + uvz[:, 2:3] * n


def scene_near(front: Front, obstacles: Obstacles, cfg: InteractionConfig, reach: float) -> cKDTree | None:
    """A k-d tree of the obstacle points within ``reach`` (+ ``cfg.clearance``) of the front's
    centre that are not the front's own surface (:func:`own_surface`); None when there are none."""
    idx = obstacles.tree.query_ball_point(np.asarray(front.center), reach + cfg.clearance)
    near = obstacles.points[np.asarray(idx, np.int64)] if len(idx) else np.zeros((0, 3))
    near = near[~own_surface(front, near, cfg)]
    return cKDTree(near) if len(near) else None


def sweep_reach(front: Front, joints: JointsConfig, carcass: float | None = None) -> float:
    """A distance (m) from the front's centre that no panel sample of any moving hypothesis
    leaves: a point p turned about an axis through a stays within |p - a| + |a - c| of the centre
    c (the midpoint a of a hinge edge is at most max(size) / 2 from c, p at most the diagonal
    from a); a drawer's box (reaching back as far as it travels) stays within half the
    diagonal plus its travel."""
    diag = float(np.hypot(*front.size))
    travel = make_part("sweep", Decision("drawer"), front, joints, {}, carcass).limits[1]
    return max(diag + max(front.size) / 2, diag / 2 + travel)


def _sweep(front: Front, hypothesis: str, tree: cKDTree | None, joints: JointsConfig, cfg: InteractionConfig,
           carcass: float | None) -> float:
    """:func:`sweep_clear` against ``tree`` (:func:`scene_near`, covering :func:`sweep_reach`)."""
    if hypothesis in ("fixed", "sliding") or tree is None:
        return 1.0
    fam, _, hinge = hypothesis.partition("_")
    part = make_part("sweep", Decision(fam, hinge or None), front, joints, {}, carcass)
    lo, hi = part.limits
    revolute = part.kind == "revolute"
    pts = panel_samples(front, cfg.spacing, cfg.inset, 0.0 if revolute else hi)
    per_q = max(front.size) if revolute else 1.0  # metres the farthest panel point moves per unit of q
    n_steps = max(int(np.ceil((hi - lo) * per_q / cfg.step)), 1)
    origin, direction = np.asarray(part.axis.origin), np.asarray(part.axis.direction)
    z0 = front_coords(front, pts)[:, 2]
    for i in range(1, n_steps + 1):
        q = lo + (hi - lo) * i / n_steps
        moved = apply_transform(joint_transform(part.kind, origin, direction, q), pts)
        if not revolute:  # the part of the box still behind the front's plane stays in its carcass
            moved = moved[z0 + q > cfg.own_depth]
        d, _ = tree.query(moved, distance_upper_bound=cfg.clearance)
        if int(np.isfinite(d).sum()) >= cfg.min_hits:
            return (i - 1) / n_steps
    return 1.0


def sweep_clear(front: Front, hypothesis: str, obstacles: Obstacles, joints: JointsConfig, cfg: InteractionConfig,
                carcass: float | None = None) -> float:
    """The fraction (0 .. 1) of hypothesis ``hypothesis``'s motion the front's panel travels
    before it comes within ``cfg.clearance`` of ``cfg.min_hits`` or more obstacle points other
    than the front's own (1.0: the whole range is free; a stray mesh point is no wall). The
    joint is the one the part would get (:func:`~drawer_lib.articulation.joints.make_part`: a
    door or flap on its hinge to ``joints.revolute_limit_deg``, a drawer out along its normal by
    its travel, its box reaching back as far: what of it comes out in front of the front's
    plane; what stays behind is :func:`room_behind`'s); the motion is sampled so that no panel point
    moves more than ``cfg.step`` between samples."""
    tree = scene_near(front, obstacles, cfg, sweep_reach(front, joints, carcass))
    return _sweep(front, hypothesis, tree, joints, cfg, carcass)


def room_behind(front: Front, obstacles: Obstacles, cfg: InteractionConfig) -> float:
    """How far (m, up to ``cfg.room_probe``) the front's rectangle (inset by ``cfg.inset``)
    reaches back before a surface the mesh shows: the ``cfg.room_percentile`` of the depths
    of the obstacle points inside that prism, behind ``cfg.own_depth`` (``cfg.room_probe``
    when fewer than ``cfg.min_hits`` lie there)."""
    idx = obstacles.tree.query_ball_point(np.asarray(front.center), float(np.hypot(*front.size)) / 2 + cfg.room_probe)
    c = front_coords(front, obstacles.points[np.asarray(idx, np.int64)]) if len(idx) else np.zeros((0, 3))
    inside = ((np.abs(c[:, 0]) <= front.size[0] / 2 - cfg.inset) & (np.abs(c[:, 1]) <= front.size[1] / 2 - cfg.inset)
              & (c[:, 2] < -cfg.own_depth) & (c[:, 2] > -cfg.room_probe))
    if inside.sum() < cfg.min_hits:
        return float(cfg.room_probe)
    return float(np.percentile(-c[inside, 2], cfg.room_percentile))


def interaction_evidence(front: Front, obstacles: Obstacles, joints: JointsConfig, cfg: InteractionConfig,
                         carcass: float | None = None) -> dict:
    """{"clear": {hypothesis: fraction of its motion that is free}, "room": room behind (m)}
    for every hypothesis that moves (:data:`~drawer_lib.articulation.vocab.HYPOTHESES` but
    ``fixed`` and ``sliding``)."""
    tree = scene_near(front, obstacles, cfg, sweep_reach(front, joints, carcass))  # one per front
    clear = {h: round(_sweep(front, h, tree, joints, cfg, carcass), 4) for h in HYPOTHESES if h not in ("fixed", "sliding")}
    return {"clear": clear, "room": round(room_behind(front, obstacles, cfg), 4)}


def blocked_hypotheses(evidence: dict, cfg: InteractionConfig) -> dict[str, str]:
    """{hypothesis: why it is implausible}: its motion is blocked before ``cfg.min_clear`` of
    its range, or (a drawer) the mesh shows a surface closer behind the front than
    ``cfg.drawer_min_room``."""
    out = {}
    for h, c in evidence["clear"].items():
        if c < cfg.min_clear:
            out[h] = f"its motion hits the scene after {c:.0%} of its range"
    if evidence["room"] < cfg.drawer_min_room and "drawer" not in out:
        out["drawer"] = f"a surface {evidence['room'] * 100:.0f} cm behind the front leaves no room for a drawer"
    return out
