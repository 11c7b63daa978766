"""Fronts seen in the images: every front rectified from every view that sees it, at the
images' resolution, so that the evidence for a kind and a hinge side (the handle) does not hang
on the coarse mesh.

A front's rectangle (grown by a margin) is sampled on a grid of ``res`` metres in its own frame;
each train view projects the grid and, where the cell is in the image, faces the camera within
``max_angle_deg`` and is not hidden behind the reconstructed surface (the view's ray-cast depth
is not nearer than the cell by more than ``occlusion_tol`` + 2 % of the depth), counts the cell
as seen, as covered by a "handle" mask, and adds its colour. A handle stands a few centimetres
proud of its front, so the handle map samples the plane ``handle_offset`` in front of the front
(less parallax between views). The handle rate (covered / seen) is what the masks say about a
cell, averaged over every view that saw it: a pull missed in a third of the views or ragged by
a pixel still stands out; a pull that no view's mask holds does not.

Shapes: a front's grid is [Gv, Gu] (v bottom -> top, u left -> right); cell (i, j) has its
centre at ``center + (u0 + (j + 0.5) res) u + (v0 + (i + 0.5) res) v``.
"""

from dataclasses import dataclass

import numpy as np
from jaxtyping import Float

from drawer_lib.articulation.config import RectifyConfig
from drawer_lib.geometry.camera import Camera, pixel_of
from drawer_lib.io.parts import Front


@dataclass(frozen=True)
class View:
    """One train view as rectification reads it: its camera, the ray-cast depth of the
    reconstructed surface (z, m, [H, W], 0 where no surface), the union of its "handle" masks
    (bool [H, W]) or None, its image (uint8 [H, W, 3]) or None, and its frame's ``stem`` (how
    a segment names the views whose detections it matched) and its other (non-handle) instance
    masks as a label map (uint16 [H, W], 0 = none) or None."""

    camera: Camera
    depth: Float[np.ndarray, "H W"]
    handles: np.ndarray | None = None
    image: np.ndarray | None = None
    stem: str = ""
    instances: np.ndarray | None = None


@dataclass
class RectifiedFront:
    """A front's grid: origin (``u0``, ``v0``, m from the centre), ``res`` (m); per cell
    ``seen`` (views that see it, int [Gv, Gu]), ``handle`` (of those, views whose handle mask
    covers it at the handle offset), ``rgb`` (mean colour in [0, 1], [Gv, Gu, 3]; NaN where
    no view saw it, or where no view had an image) and the instance-mask boundaries: ``edge_u``
    (views in which cells (i, j) and (i, j + 1), both seen, lie in different instance masks, or
    one in none; [Gv, Gu], the last column 0), ``edge_v`` (likewise (i, j) and (i + 1, j)) and
    ``pair_u`` / ``pair_v`` (the views that saw both cells of the pair)."""

    u0: float
    v0: float
    res: float
    seen: np.ndarray
    handle: np.ndarray
    handle_seen: np.ndarray
    rgb: np.ndarray
    edge_u: np.ndarray | None = None
    edge_v: np.ndarray | None = None
    pair_u: np.ndarray | None = None
    pair_v: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.seen.shape

    def uv(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell centres (u [Gv, Gu], v [Gv, Gu]) in metres from the front's centre."""
        gv, gu = self.shape
        uu = self.u0 + (np.arange(gu) + 0.5) * self.res
        vv = self.v0 + (np.arange(gv) + 0.5) * self.res
        return np.meshgrid(uu, vv)

    def handle_rate(self, min_views: int) -> np.ndarray:
        """Fraction of the views seeing a cell (at the handle offset) whose handle mask covers
        it; 0 where fewer than ``min_views`` saw it."""
        ok = self.handle_seen >= min_views
        return np.where(ok, self.handle / np.maximum(self.handle_seen, 1), 0.0)


WINDOW_INNER = ((0.2, 0.8), (0.25, 0.7))  # a window's panel: these fractions of a front's width and height
WINDOW_RING = (0.08, 0.1, 0.8)  # its frame: the outer fraction of the width either side and of the height at the
# bottom, below this fraction of the height (clear of a pull along the top)


def window_contrast(front: Front, rf: RectifiedFront, min_cells: int = 20) -> float | None:
    """How much the middle of ``front`` differs from its frame on the rectified image ``rf``:
    |median grey of the frame - median grey of the panel| in [0, 1] (:data:`WINDOW_INNER`,
    :data:`WINDOW_RING`; grey = mean of the colour channels, cells no view saw left out). An
    oven's or a microwave's window and a glass door's pane stand out by a quarter of the grey
    range or more; a drawer's or a plain door's panel is its frame's colour. A median ignores a
    pull across part of the panel. None without an image or with fewer than ``min_cells`` seen
    cells in either region."""
    if rf.rgb is None:
        return None
    uu, vv = rf.uv()
    a, b = uu / front.size[0] + 0.5, vv / front.size[1] + 0.5  # 0..1 across the front
    g = rf.rgb.mean(axis=2)
    ok = np.isfinite(g) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
    (a0, a1), (b0, b1) = WINDOW_INNER
    side, bottom, top = WINDOW_RING
    inner = ok & (a > a0) & (a < a1) & (b > b0) & (b < b1)
    ring = ok & ((a < side) | (a > 1 - side) | (b < bottom)) & (b < top)
    if inner.sum() < min_cells or ring.sum() < min_cells:
        return None
    return float(abs(np.median(g[ring]) - np.median(g[inner])))


def front_grid(front: Front, res: float, margin: float, anchor: str = "size") -> tuple[float, float, int, int]:
    """(u0, v0, Gu, Gv): the grid covering the rectangle grown by ``margin`` on every side.
    ``anchor``: ``size``, as many cells as cover it, centred on the front's centre (a size
    that crosses a multiple of ``res`` changes the count's parity and moves every cell by half
    a cell); ``centre``, cells centred at whole multiples of ``res`` from the front's centre (an
    odd count, at least as many), so a change of the size adds or drops cells at the border
    and never moves the others."""
    w, h = front.size
    if anchor == "centre":
        ku = max(0, int(np.ceil((w / 2 + margin) / res - 0.5)))
        kv = max(0, int(np.ceil((h / 2 + margin) / res - 0.5)))
        return -(ku + 0.5) * res, -(kv + 0.5) * res, 2 * ku + 1, 2 * kv + 1
    if anchor != "size":
        raise ValueError(f"front_grid: anchor = {anchor!r}, expected 'size' or 'centre'")
    gu = max(1, int(np.ceil((w + 2 * margin) / res)))
    gv = max(1, int(np.ceil((h + 2 * margin) / res)))
    return -gu * res / 2, -gv * res / 2, gu, gv


def grid_points(front: Front, u: np.ndarray, v: np.ndarray, offset: float = 0.0) -> np.ndarray:
    """World points [..., 3] of in-plane coordinates (``u``, ``v``) (m from the centre),
    ``offset`` m along the outward normal."""
    c, nu, nn = np.asarray(front.center), np.asarray(front.u), np.asarray(front.normal)
    return c + u[..., None] * nu + v[..., None] * front.v + offset * nn


def _sample(view: View, pts: np.ndarray, normal: np.ndarray, cos_min: float, tol: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(seen [N], rows [N], cols [N]) of world points ``pts`` [N, 3] in ``view``."""
    it = view.camera.intrinsics
    r, c, z, ok = pixel_of(pts, view.camera.w2c, it, near=1e-3)
    to_cam = view.camera.center - pts
    dist = np.linalg.norm(to_cam, axis=1)
    ok &= (to_cam @ normal) >= cos_min * np.maximum(dist, 1e-12)
    d = view.depth[r, c]
    ok &= (d <= 0) | (d >= z - (tol + 0.02 * z))
    return ok, r, c


def rectify_front(front: Front, views: list[View], cfg: RectifyConfig, detected: np.ndarray | None = None
                  ) -> RectifiedFront:
    """The front's grid seen from every view (module docstring). ``detected`` (bool [len(views)]):
    the views whose detections hold the front; when at least ``cfg.min_views`` of them, only
    they count for the handle map (a detector that misses a front in most views misses its
    handle there too: a front seen in a quarter of the views keeps its handle)."""
    u0, v0, gu, gv = front_grid(front, cfg.res, cfg.margin, cfg.grid_anchor)
    uu, vv = np.meshgrid(u0 + (np.arange(gu) + 0.5) * cfg.res, v0 + (np.arange(gv) + 0.5) * cfg.res)
    plane = grid_points(front, uu, vv).reshape(-1, 3)
    proud = grid_points(front, uu, vv, cfg.handle_offset).reshape(-1, 3)
    normal = np.asarray(front.normal, np.float64)
    cos_min = float(np.cos(np.deg2rad(cfg.max_angle_deg)))
    n = gu * gv
    seen = np.zeros(n, np.int32)
    hit = np.zeros(n, np.int32)
    hseen = np.zeros(n, np.int32)
    rgb_sum = np.zeros((n, 3))
    rgb_n = np.zeros(n, np.int32)
    shape = (gv, gu)
    edge_u, edge_v = np.zeros(shape, np.int32), np.zeros(shape, np.int32)
    pair_u, pair_v = np.zeros(shape, np.int32), np.zeros(shape, np.int32)
    if detected is not None and int(np.sum(detected)) < cfg.min_views:
        detected = None
    for t, view in enumerate(views):
        ok, r, c = _sample(view, plane, normal, cos_min, cfg.occlusion_tol)
        seen += ok
        if view.image is not None:
            rgb_sum[ok] += view.image[r[ok], c[ok]] / 255.0
            rgb_n += ok
        if view.instances is not None:
            lab = np.where(ok, view.instances[r, c], 0).reshape(shape)
            okg = ok.reshape(shape)
            both_u, both_v = okg[:, :-1] & okg[:, 1:], okg[:-1, :] & okg[1:, :]
            pair_u[:, :-1] += both_u
            pair_v[:-1, :] += both_v
            edge_u[:, :-1] += both_u & (lab[:, :-1] != lab[:, 1:])
            edge_v[:-1, :] += both_v & (lab[:-1, :] != lab[1:, :])
        if view.handles is not None and (detected is None or detected[t]):
            okh, rh, ch = _sample(view, proud, normal, cos_min, cfg.occlusion_tol)
            hseen += okh
            hit += okh & view.handles[rh, ch]
    with np.errstate(invalid="ignore", divide="ignore"):
        rgb = np.where(rgb_n[:, None] > 0, rgb_sum / rgb_n[:, None], np.nan)
    has_inst = any(v.instances is not None for v in views)
    return RectifiedFront(u0, v0, cfg.res, seen.reshape(shape), hit.reshape(shape), hseen.reshape(shape),
                          rgb.reshape(shape + (3,)), *((edge_u, edge_v, pair_u, pair_v) if has_inst else ()))


def handle_points(front: Front, rf: RectifiedFront, cfg: RectifyConfig) -> tuple[np.ndarray, np.ndarray]:
    """The cells the handle masks hold (rate >= ``min_rate`` over >= ``min_views`` views): their
    centres on the front's plane [M, 3] and their rates [M] (weights for
    :func:`~drawer_lib.articulation.handles.handle_candidates`)."""
    rate = rf.handle_rate(cfg.min_views)
    keep = rate >= cfg.min_rate
    uu, vv = rf.uv()
    return grid_points(front, uu[keep], vv[keep]), rate[keep]


def rectify_fronts(fronts: list[Front], views: list[View], cfg: RectifyConfig,
                   detected: list[np.ndarray | None] | None = None
                   ) -> tuple[list[RectifiedFront], np.ndarray, np.ndarray]:
    """Every front rectified (``detected[k]``: :func:`rectify_front`'s for front k), and the
    handle cells of all of them together: (rectified fronts, points [M, 3], rates [M]). A cell
    in the margin of two fronts appears once per front; the handle assignment gives each point
    to the front it lies deepest in."""
    det = detected if detected is not None else [None] * len(fronts)
    rfs = [rectify_front(f, views, cfg, d) for f, d in zip(fronts, det)]
    pts, rates = [np.zeros((0, 3))], [np.zeros(0)]
    for f, rf in zip(fronts, rfs):
        p, r = handle_points(f, rf, cfg)
        pts.append(p)
        rates.append(r)
    return rfs, np.concatenate(pts), np.concatenate(rates)
