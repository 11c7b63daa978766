"""Simulated sensors on top of exact renders: depth camera, monocular priors, 2D detector.

Each function takes exact per-frame quantities and a ``numpy.random.Generator`` and returns what
a real sensor or model would deliver; with the ``exact``/perfect settings of their configs they
return the exact quantities (up to the format's quantisation / normalisation).
"""

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import Intrinsics, pixel_dirs
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
                        cfg: DetectionsConfig, rng: np.random.Generator) -> tuple[np.ndarray, list[dict], DetectionStats]:
    """A detector's instance masks for one frame.

    ``entity_map``: [H, W] entity index per pixel (-1 = nothing); ``handle_map``: [H, W] bool,
    pixels of handles; ``entities[k]`` describes entity k. Returns (uint16 [H, W] label map with
    ids local to the frame, [{"id", "label", "score"}], stats).
    """
    stats = DetectionStats()
    H, W = entity_map.shape
    cands: list[tuple[np.ndarray, str, str]] = []  # (mask, kind, typed label)
    fronts: list[int] = []
    for k, ent in enumerate(entities):
        if ent.kind == "none":
            continue
        m = entity_map == k
        if not m.any():
            continue
        if ent.kind == "front":
            body, hand = m & ~handle_map, m & handle_map
            if body.sum() >= cfg.min_area_px:
                fronts.append(len(cands))
                cands.append((body, "front", ent.typed_label))
            if cfg.detect_handles and hand.sum() >= cfg.min_area_px // 3:
                cands.append((hand, "handle", "handle"))
        elif m.sum() >= cfg.min_area_px:
            cands.append((m, "object", ent.typed_label))
    stats.candidates = len(cands)

    # merges of touching fronts (union-find over candidate indices)
    parent = list(range(len(cands)))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    if cfg.p_merge > 0 and len(fronts) > 1:
        grown = {i: ndimage.binary_dilation(cands[i][0], iterations=2) for i in fronts}
        for ai, a in enumerate(fronts):
            for b in fronts[ai + 1:]:
                if (grown[a] & cands[b][0]).any() and rng.random() < cfg.p_merge:
                    ra, rb = find(a), find(b)
                    if ra != rb:
                        parent[rb] = ra
                        stats.merged += 1
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
