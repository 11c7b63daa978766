"""Simulated sensors on top of exact renders: depth camera, monocular priors, 2D detector.

Each function takes exact per-frame quantities and a ``numpy.random.Generator`` and returns what
a real sensor or model would deliver; with the ``exact``/perfect settings of their configs they
return the exact quantities (up to the format's quantisation / normalisation).
"""

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import Camera, Intrinsics, pixel_dirs
from drawer_lib.geometry.rotations import axis_angle_to_matrix
from drawer_lib.synth.config import DepthSensorConfig, DetectionsConfig, MonoConfig


def smooth_field(rng: np.random.Generator, H: int, W: int, max_cycles: float = 1.5, terms: int = 4) -> np.ndarray:
    """A smooth random field in [-1, 1] over the image: a few low-frequency plane waves."""
    yy, xx = np.mgrid[0:H, 0:W]
    u, v = xx / W, yy / H
    f = np.zeros((H, W))
    for _ in range(terms):
        a = rng.uniform(0, 2 * np.pi)
        k = rng.uniform(0.3, max_cycles)
        f += np.cos(2 * np.pi * k * (np.cos(a) * u + np.sin(a) * v) + rng.uniform(0, 2 * np.pi))
    m = np.abs(f).max()
    return f / m if m > 0 else f


def depth_edges(z: np.ndarray, rel_jump: float) -> np.ndarray:
    """Pixels next to a depth discontinuity larger than ``rel_jump`` (relative), [H, W] bool."""
    e = np.zeros(z.shape, bool)
    for ax in (0, 1):
        a = np.diff(z, axis=ax)
        m = np.minimum(np.take(z, range(z.shape[ax] - 1), axis=ax), np.take(z, range(1, z.shape[ax]), axis=ax))
        jump = np.abs(a) > rel_jump * np.maximum(m, 1e-6)
        if ax == 0:
            e[:-1] |= jump
            e[1:] |= jump
        else:
            e[:, :-1] |= jump
            e[:, 1:] |= jump
    return e


def sensor_depth(z: np.ndarray, normals_cam: np.ndarray, intr: Intrinsics,
                 cfg: DepthSensorConfig, rng: np.random.Generator) -> np.ndarray:
    """Metric z-depth as a depth camera measures it, float32 [H, W], 0 = invalid.

    ``z``: exact z-depth (0 where nothing was hit); ``normals_cam``: camera-facing unit normals
    in the OpenCV camera frame; ``intr``: the camera's intrinsics (of the [H, W] image).
    """
    z = np.asarray(z, np.float64)
    valid = np.isfinite(z) & (z > 0)
    if cfg.exact:
        return np.where(valid, z, 0.0).astype(np.float32)
    H, W = z.shape
    valid &= (z >= cfg.min_range) & (z <= cfg.max_range)
    d = pixel_dirs(intr, normalize=True)
    cos_inc = np.abs(np.einsum("hwc,hwc->hw", d, normals_cam))
    inc = np.rad2deg(np.arccos(np.clip(cos_inc, 0.0, 1.0)))
    band = max(cfg.grazing_band_deg, 1e-6)
    p_drop = np.clip((inc - (cfg.grazing_deg - band)) / band, 0.0, 1.0)
    valid &= rng.random((H, W)) >= p_drop
    if cfg.edge_px > 0:
        edges = depth_edges(np.where(z > 0, z, 0.0), cfg.edge_jump)
        edges = ndimage.binary_dilation(edges, iterations=max(cfg.edge_px - 1, 0)) if cfg.edge_px > 1 else edges
        valid &= ~edges
    valid &= rng.random((H, W)) >= cfg.dropout
    sigma = cfg.sigma_base + cfg.sigma_quad * (z - cfg.z_ref) ** 2
    noisy = z + sigma * rng.normal(size=z.shape)
    valid &= noisy > 0
    return np.where(valid, noisy, 0.0).astype(np.float32)


def mono_depth(z: np.ndarray, cfg: MonoConfig, rng: np.random.Generator) -> np.ndarray:
    """Relative depth in [0, 1], float32 [H, W]: an unknown per-frame scale and shift of a
    blurred, smoothly warped and noisy z-depth (exact: only the per-frame normalisation).

    Pixels without depth (z = 0) are filled with the nearest valid value first, as a network
    predicts something everywhere."""
    z = np.asarray(z, np.float64)
    hole = ~(np.isfinite(z) & (z > 0))
    if hole.all():
        raise InputError("mono_depth: the frame sees no surface (no valid depth)")
    if hole.any():
        idx = ndimage.distance_transform_edt(hole, return_distances=False, return_indices=True)
        z = z[tuple(idx)]
    d = z
    if not cfg.exact:
        if cfg.depth_blur_px > 0:
            d = ndimage.gaussian_filter(d, cfg.depth_blur_px)
        d = d * (1.0 + cfg.depth_warp * smooth_field(rng, *z.shape))
        d = d * (1.0 + cfg.depth_noise * rng.normal(size=z.shape))
    lo, hi = d.min(), d.max()
    if hi - lo <= 1e-9 * max(abs(hi), 1.0):
        return np.zeros(z.shape, np.float32)
    return ((d - lo) / (hi - lo)).astype(np.float32)


def mono_normals(n_cam: np.ndarray, cfg: MonoConfig, rng: np.random.Generator) -> np.ndarray:
    """Camera-frame unit normals as a monocular estimator gives them, float16 [H, W, 3]."""
    n = np.asarray(n_cam, np.float64)
    hole = np.linalg.norm(n, axis=-1) < 0.5
    if hole.any() and not hole.all():
        idx = ndimage.distance_transform_edt(hole, return_distances=False, return_indices=True)
        n = n[tuple(idx)]
    elif hole.all():
        n = np.broadcast_to(np.array([0.0, 0.0, -1.0]), n.shape).copy()
    if not cfg.exact:
        H, W, _ = n.shape
        amp = np.tan(np.deg2rad(cfg.normal_noise_deg))
        p = np.stack([smooth_field(rng, H, W, max_cycles=3.0) for _ in range(3)], -1) * amp
        p -= np.einsum("hwc,hwc->hw", p, n)[..., None] * n
        n = n + p
        if cfg.normal_blur_px > 0:
            n = np.stack([ndimage.gaussian_filter(n[..., c], cfg.normal_blur_px) for c in range(3)], -1)
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-9)
        if cfg.normal_frontal_pull > 0:  # toward facing the camera (OpenCV camera: -z)
            n = (1.0 - cfg.normal_frontal_pull) * n + cfg.normal_frontal_pull * np.array([0.0, 0.0, -1.0])
            n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-9)
        if cfg.normal_bias_deg > 0:  # one rotation for the whole frame, drawn from a child
            # generator: the frame's later draws (depth noise, detections) stay as they were
            axis = rng.spawn(1)[0].normal(size=3)
            axis /= np.linalg.norm(axis)
            n = n @ axis_angle_to_matrix(axis, float(np.deg2rad(cfg.normal_bias_deg))).T
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-9)
    return n.astype(np.float16)


# ---------------------------------------------------------------------------------------------
# 2D detections


@dataclass(frozen=True)
class DetectableEntity:
    """What the detector simulation needs to know about an entity of the layout."""

    kind: str  # front | object | none
    typed_label: str  # drawer | door | cup | bottle | ...


@dataclass
class DetectionStats:
    candidates: int = 0
    detected: int = 0
    missed: int = 0
    merged: int = 0
    false: int = 0
    world_false: int = 0  # detections of the false fronts fixed in the world


@dataclass(frozen=True)
class FalseFront:
    """A rectangle fixed on a static surface that a detector takes for a front: ``centre`` [3]
    (m, world), unit ``normal``, ``u`` (horizontal where the surface allows) and ``v`` in its
    plane, half sizes ``half`` (m, along u and v), the label it is given."""

    centre: np.ndarray
    normal: np.ndarray
    u: np.ndarray
    v: np.ndarray
    half: tuple[float, float]
    label: str


@dataclass(frozen=True)
class PartFailures:
    """Detector failures that persist across views, decided once per capture (entity indices of
    the layout): ``never`` detected; ``sparse``: seen in a fraction of the views; ``merged``:
    pairs of touching fronts given one mask in most views; ``no_handle``: the handle is never
    found; ``swapped``: typed label drawer <-> door in every view; ``false_fronts``."""

    never: frozenset = frozenset()
    sparse: frozenset = frozenset()
    merged: tuple[tuple[int, int], ...] = ()
    no_handle: frozenset = frozenset()
    swapped: frozenset = frozenset()
    false_fronts: tuple[FalseFront, ...] = ()

    def summary(self) -> dict:
        return {"parts_never_detected": len(self.never), "parts_sparse": len(self.sparse),
                "pairs_merged": len(self.merged), "handles_never_found": len(self.no_handle),
                "labels_swapped": len(self.swapped), "false_fronts": len(self.false_fronts)}


def touching_pairs(boxes: dict[int, tuple[np.ndarray, np.ndarray]], gap: float = 0.015) -> list[tuple[int, int]]:
    """Pairs (a < b) of axis-aligned boxes ``{entity: (lo [3], hi [3])}`` (m) no farther apart
    than ``gap`` along every axis."""
    keys = sorted(boxes)
    out = []
    for i, a in enumerate(keys):
        for b in keys[i + 1:]:
            (la, ha), (lb, hb) = boxes[a], boxes[b]
            if np.all(np.maximum(la, lb) - np.minimum(ha, hb) <= gap):
                out.append((a, b))
    return out


def decide_part_failures(entities: list[DetectableEntity], front_boxes: dict[int, tuple[np.ndarray, np.ndarray]],
                         cfg: DetectionsConfig, rng: np.random.Generator) -> PartFailures:
    """Which parts fail in every view (:class:`PartFailures`, without the false fronts, which
    need a view: :func:`place_false_fronts`). ``front_boxes``: each front's box in the kitchen's
    frame, for which fronts touch. Draws from ``rng`` only for the failures that are on."""
    fronts = [k for k, e in enumerate(entities) if e.kind == "front"]
    parts = [k for k, e in enumerate(entities) if e.kind in ("front", "object")]

    def pick(keys, p):
        return frozenset(k for k in keys if rng.random() < p) if p > 0 else frozenset()

    never = pick(parts, cfg.p_never)
    sparse = pick([k for k in parts if k not in never], cfg.p_sparse)
    merged = ()
    if cfg.p_merge_part > 0:
        merged = tuple(pr for pr in touching_pairs({k: front_boxes[k] for k in fronts if k in front_boxes})
                       if rng.random() < cfg.p_merge_part)
    no_handle = pick(fronts, cfg.p_no_handle)
    swapped = pick([k for k in fronts if entities[k].typed_label in ("drawer", "door")], cfg.p_label_part)
    return PartFailures(never, sparse, merged, no_handle, swapped)


def _world_points(z: np.ndarray, cam: Camera) -> np.ndarray:
    """[H, W, 3] world points of the z-depth map ``z`` seen by ``cam``."""
    o, d = cam.rays()
    return o + d * z[..., None]


def place_false_fronts(n: int, z: np.ndarray, normals_cam: np.ndarray, static: np.ndarray, cam: Camera,
                       typed: bool, rng: np.random.Generator) -> tuple[FalseFront, ...]:
    """``n`` false fronts on static surfaces seen (facing the camera) in one view: each centred on
    a random such pixel, 0.3-0.6 m wide and 0.3-0.7 m high in the surface's plane, labelled
    ``front`` (or door / drawer with ``typed`` labels)."""
    d = pixel_dirs(cam.intrinsics, normalize=True)
    facing = static & (z > 0) & (np.einsum("hwc,hwc->hw", normals_cam, d) < -0.5)
    ys, xs = np.nonzero(facing)
    if n == 0 or len(ys) == 0:
        return ()
    X = _world_points(z, cam)
    R = cam.c2w[:3, :3]
    out = []
    for _ in range(n):
        k = rng.integers(len(ys))
        c = X[ys[k], xs[k]]
        nrm = R @ normals_cam[ys[k], xs[k]]
        nrm = nrm / np.linalg.norm(nrm)
        u = np.cross([0.0, 0.0, 1.0], nrm)
        u = u / np.linalg.norm(u) if np.linalg.norm(u) > 0.3 else np.array([1.0, 0.0, 0.0])
        v = np.cross(nrm, u)
        label = ("door" if rng.random() < 0.5 else "drawer") if typed else "front"
        out.append(FalseFront(c, nrm, u, v, (float(rng.uniform(0.15, 0.3)), float(rng.uniform(0.15, 0.35))), label))
    return tuple(out)


def false_front_mask(ff: FalseFront, z: np.ndarray, static: np.ndarray, cam: Camera, tol: float = 0.02) -> np.ndarray:
    """[H, W] bool: the pixels of ``cam``'s view whose visible surface lies in the rectangle ``ff``
    (within ``tol`` m of its plane): where it is seen, occlusions included."""
    D = _world_points(z, cam) - ff.centre
    return (static & (z > 0) & (np.abs(D @ ff.normal) < tol) & (np.abs(D @ ff.u) < ff.half[0])
            & (np.abs(D @ ff.v) < ff.half[1]))


GENERIC = {"front": "front", "object": "object", "handle": "handle"}


def _ragged(mask: np.ndarray, cfg: DetectionsConfig, rng: np.random.Generator) -> np.ndarray:
    r = int(rng.integers(-cfg.ragged_px, cfg.ragged_px + 1)) if cfg.ragged_px > 0 else 0
    if r > 0:
        mask = ndimage.binary_dilation(mask, iterations=r)
    elif r < 0:
        eroded = ndimage.binary_erosion(mask, iterations=-r)
        mask = eroded if eroded.sum() >= 0.5 * mask.sum() else mask
    if cfg.boundary_noise_px > 0:
        ys, xs = np.nonzero(mask)
        if len(ys):
            pad = int(np.ceil(3 * cfg.boundary_noise_px)) + 2
            y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, mask.shape[0])
            x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, mask.shape[1])
            sub = mask[y0:y1, x0:x1]
            sd = ndimage.distance_transform_edt(sub) - ndimage.distance_transform_edt(~sub)
            noise = ndimage.gaussian_filter(rng.normal(size=sub.shape), 1.5)
            noise *= cfg.boundary_noise_px / max(noise.std(), 1e-9)
            out = mask.copy()
            out[y0:y1, x0:x1] = (sd + noise) > 0
            mask = out
    return mask


def _false_mask(rng: np.random.Generator, static: np.ndarray) -> np.ndarray | None:
    H, W = static.shape
    ys, xs = np.nonzero(static)
    if len(ys) == 0:
        return None
    k = rng.integers(len(ys))
    cy, cx = ys[k], xs[k]
    ry, rx = rng.uniform(0.05, 0.2) * H, rng.uniform(0.05, 0.2) * W
    yy, xx = np.mgrid[0:H, 0:W]
    ang = rng.uniform(0, np.pi)
    dy, dx = yy - cy, xx - cx
    a = (np.cos(ang) * dx + np.sin(ang) * dy) / rx
    b = (-np.sin(ang) * dx + np.cos(ang) * dy) / ry
    warp = 0.25 * smooth_field(rng, H, W, max_cycles=4.0)
    m = a**2 + b**2 < (1.0 + warp)
    return m


def simulate_detections(entity_map: np.ndarray, handle_map: np.ndarray, entities: list[DetectableEntity],
                        cfg: DetectionsConfig, rng: np.random.Generator, failures: PartFailures | None = None,
                        world_false: list[tuple[np.ndarray, str]] = ()) -> tuple[np.ndarray, list[dict], DetectionStats]:
    """A detector's instance masks for one frame.

    ``entity_map``: [H, W] entity index per pixel (-1 = nothing); ``handle_map``: [H, W] bool,
    pixels of handles; ``entities[k]`` describes entity k; ``failures``: the failures that
    persist across views (:func:`decide_part_failures`); ``world_false``: this view's masks of
    the false fronts fixed in the world (:func:`false_front_mask`) with their labels. Returns
    (uint16 [H, W] label map with ids local to the frame, [{"id", "label", "score"}], stats).
    """
    stats = DetectionStats()
    H, W = entity_map.shape
    fail = failures or PartFailures()
    cands: list[tuple[np.ndarray, str, str]] = []  # (mask, kind, typed label)
    fronts: list[int] = []
    cand_of: dict[int, int] = {}  # entity -> its body's candidate
    for k, ent in enumerate(entities):
        if ent.kind == "none" or k in fail.never:
            continue
        m = entity_map == k
        if not m.any():
            continue
        if k in fail.sparse and rng.random() >= cfg.sparse_keep:
            continue
        typed = ent.typed_label
        if k in fail.swapped:
            typed = "door" if typed == "drawer" else "drawer"
        if ent.kind == "front":
            body, hand = m & ~handle_map, m & handle_map
            if body.sum() >= cfg.min_area_px:
                fronts.append(len(cands))
                cand_of[k] = len(cands)
                cands.append((body, "front", typed))
            if cfg.detect_handles and k not in fail.no_handle and hand.sum() >= cfg.min_area_px // 3:
                cands.append((hand, "handle", "handle"))
        elif m.sum() >= cfg.min_area_px:
            cands.append((m, "object", typed))
    stats.candidates = len(cands)

    # merges of touching fronts (union-find over candidate indices)
    parent = list(range(len(cands)))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    grown: dict[int, np.ndarray] = {}

    def touch(a: int, b: int) -> bool:  # the two candidates' masks within 2 px of each other
        if a not in grown:
            grown[a] = ndimage.binary_dilation(cands[a][0], iterations=2)
        return bool((grown[a] & cands[b][0]).any())

    def merge(a: int, b: int) -> None:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[rb] = ra
            stats.merged += 1

    if cfg.p_merge > 0 and len(fronts) > 1:
        for ai, a in enumerate(fronts):
            for b in fronts[ai + 1:]:
                if touch(a, b) and rng.random() < cfg.p_merge:
                    merge(a, b)
    for a, b in fail.merged:  # persistent merges: in most views where both are seen and touch
        if a in cand_of and b in cand_of and rng.random() < cfg.merge_views and touch(cand_of[a], cand_of[b]):
            merge(cand_of[a], cand_of[b])
    groups: dict[int, list[int]] = {}
    for i in range(len(cands)):
        groups.setdefault(find(i), []).append(i)

    lo, hi = cfg.score_range
    masks: list[tuple[np.ndarray, str, float]] = []
    for members in groups.values():
        if rng.random() < cfg.p_miss:
            stats.missed += 1
            continue
        mask = np.logical_or.reduce([cands[i][0] for i in members])
        main = max(members, key=lambda i: cands[i][0].sum())
        kind, typed = cands[main][1], cands[main][2]
        if cfg.labels == "generic":
            label = GENERIC[kind]
        else:
            label = typed
            if kind == "front" and label in ("drawer", "door") and rng.random() < cfg.label_confusion:
                label = "door" if label == "drawer" else "drawer"
        masks.append((_ragged(mask, cfg, rng), label, float(rng.uniform(lo, hi))))
        stats.detected += 1

    static = entity_map == 0
    for _ in range(rng.poisson(cfg.false_rate) if cfg.false_rate > 0 else 0):
        m = _false_mask(rng, static)
        if m is None or m.sum() < cfg.min_area_px:
            continue
        if cfg.labels == "generic":
            label = ["front", "object"][rng.integers(2)]
        else:
            label = ["door", "drawer", "object"][rng.integers(3)]
        masks.append((m, label, float(rng.uniform(lo, (lo + hi) / 2))))
        stats.false += 1

    for m, label in world_false:
        if m.sum() >= cfg.min_area_px:
            masks.append((_ragged(m, cfg, rng), label, float(rng.uniform(lo, hi))))
            stats.world_false += 1

    # paint in a random order (later masks win overlaps), then give ids local to the frame
    label_map = np.zeros((H, W), np.uint16)
    order = rng.permutation(len(masks))
    ids = rng.permutation(np.arange(1, len(masks) + 1))
    for o in order:
        label_map[masks[o][0]] = ids[o]
    dets = []
    present = set(np.unique(label_map).tolist())
    for o in range(len(masks)):
        i = int(ids[o])
        if i in present and (label_map == i).sum() >= max(cfg.min_area_px // 3, 1):
            dets.append({"id": i, "label": masks[o][1], "score": round(masks[o][2], 3)})
        else:
            label_map[label_map == i] = 0
    dets.sort(key=lambda d: d["id"])
    return label_map, dets, stats
