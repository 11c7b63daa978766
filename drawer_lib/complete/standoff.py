"""How far a part's handle stands out of its front, measured in the capture's metric depth.

The images give a handle's place and extent (``parts.json``'s handle evidence) but not its
depth: the twin's handle box stands ``complete.handle.proud`` (35 mm) out of the front unless
the capture has metric depth, in which case this module measures it. Every valid depth pixel
of the views is lifted to a world point and taken into the front's frame (u, v in the plane,
n along the outward normal, m). Two sets of points are kept per handle:

- the **ring**: points in the front's rectangle, within ``RING`` (m) of the handle's rectangle
  but at least ``GAP`` (m) from it, within ``RING_N`` of the front's plane: the front around
  the handle. Their median n is the front's surface as the depth sees it (the articulated
  front's plane can sit a few mm off it);
- the **box**: points over the handle's rectangle (its evidence's extent, at least ``MIN_HALF``
  a side), ``-RING_N`` to ``MAX_OUT`` in front of the plane, taken relative to the ring's n.

A handle's surface seen from the views is mostly its outer face, and some of the box's points
are the front around or behind a bar: the points standing more than ``MIN_OUT`` out are the
handle's. Its standoff (m, the outer face above the front's surface) is where they are densest
(:func:`densest`, a ``BANDWIDTH`` kernel): the face is the handle's largest surface seen
square-on, while its sides spread over every height below it and pull a median down (1 to
2.5 mm on a 30 mm block with 1 to 4 mm of noise; the densest height is within 0.5 mm there).
``noise_m`` records the depth's spread on the ring (1.4826 x its median absolute deviation:
the sensor's noise and whatever else the ring holds, a neighbour's edge). With fewer than
``min_points`` of them over at least ``min_points`` box points the handle is ``flush`` (a
recessed pull, or one the depth does not resolve). Too few ring or box points: not measured,
with the reason. Lengths m; the depth must be metric.
"""

import math
from collections.abc import Iterable, Iterator

import numpy as np

from drawer_lib.geometry.boxes import front_frame
from drawer_lib.geometry.camera import Intrinsics, pixel_dirs
from drawer_lib.io.parts import Part

RING = 0.03  # m: the ring around the handle's rectangle that gives the front's surface
GAP = 0.01  # m: the ring starts this far outside the handle's rectangle
RING_N = 0.02  # m: ring points within this of the front's plane
MAX_OUT = 0.08  # m: box points up to this in front of the plane
MIN_OUT = 0.004  # m: a box point this far above the front's surface is the handle's
MIN_HALF = 0.01  # m: the handle's rectangle is at least this each side of its centre
BIN = 0.0005  # m: the grid of the handle points' density
BANDWIDTH = 0.002  # m: its kernel's


def handle_rect(part: Part) -> tuple[float, float, float, float] | None:
    """(cu, cv, half_u, half_v) m: the handle's rectangle in the front's (u, v) frame, from
    ``part.extra["handle"]`` (``a_u``, ``a_v`` in the front's unit square, ``size`` along u
    and v); None without handle evidence."""
    h = part.extra.get("handle")
    if not h:
        return None
    w, hgt = part.front.size
    su, sv = h.get("size") or (0.0, 0.0)
    return ((float(h["a_u"]) - 0.5) * w, (float(h["a_v"]) - 0.5) * hgt,
            max(float(su) / 2, MIN_HALF), max(float(sv) / 2, MIN_HALF))


def depth_views(capture, frames: Iterable[int]) -> Iterator[tuple[np.ndarray, Intrinsics, np.ndarray]]:
    """(metric z-depth [H, W] m, intrinsics, OpenCV camera-to-world [4, 4]) of each of
    ``frames`` of a :class:`drawer_lib.io.capture.Capture`, read one at a time."""
    for i in frames:
        yield capture.depth(i), capture.frame_intrinsics(i), capture.frames[i].c2w


def measure_standoffs(parts: list[Part], views: Iterable[tuple[np.ndarray, Intrinsics, np.ndarray]],
                      min_points: int = 20) -> dict[str, dict]:
    """Each handled part's standoff (module doc) from ``views`` ((z-depth [H, W] m with 0 or a
    non-finite value where invalid, intrinsics, OpenCV camera-to-world [4, 4]), streamed).
    Returns {part id: record}: ``standoff_m`` (m, the handle's outer face above the front's
    surface; 0.0 when ``flush``), ``flush`` (bool), ``points`` (box points above ``MIN_OUT``),
    ``box_points``, ``ring_points``, ``views`` (views with a handle point), ``noise_m`` (the
    depth's noise on the ring, m), ``iqr_m`` (the spread of the handle points' heights),
    ``surface_offset_m`` (the front's surface measured, relative to the part's plane); or
    ``standoff_m`` None and ``why``. Parts without handle evidence are left out."""
    if min_points < 1:
        raise ValueError(f"measure_standoffs: min_points = {min_points} must be >= 1")
    fronts = {}
    for p in parts:
        r = handle_rect(p)
        if r is not None:
            fronts[p.id] = (np.asarray(p.front.center, np.float64), front_frame(p.front.normal, p.front.u),
                            np.asarray(p.front.size, np.float64), r)
    ring: dict[str, list[np.ndarray]] = {k: [] for k in fronts}
    box: dict[str, list[np.ndarray]] = {k: [] for k in fronts}
    box_view: dict[str, list[np.ndarray]] = {k: [] for k in fronts}
    for vi, (z, intr, c2w) in enumerate(views):
        z = np.asarray(z, np.float32)
        ok = np.isfinite(z) & (z > 0)
        if not ok.any():
            continue
        P = (pixel_dirs(intr)[ok] * z[ok, None].astype(np.float64)) @ np.asarray(c2w)[:3, :3].T + np.asarray(c2w)[:3, 3]
        for pid, (c, R, (w, h), (cu, cv, hu, hv)) in fronts.items():
            L = (P - c) @ R
            du, dv, n = np.abs(L[:, 0] - cu), np.abs(L[:, 1] - cv), L[:, 2]
            near = (np.abs(L[:, 0]) <= w / 2) & (np.abs(L[:, 1]) <= h / 2) & (n > -RING_N)
            in_box = near & (du <= hu) & (dv <= hv) & (n <= MAX_OUT)
            in_ring = (near & (n < RING_N) & (du <= hu + RING) & (dv <= hv + RING)
                       & ~((du <= hu + GAP) & (dv <= hv + GAP)))
            ring[pid].append(n[in_ring])
            box[pid].append(n[in_box])
            box_view[pid].append(np.full(int(in_box.sum()), vi))
    out = {}
    for pid in fronts:
        rn, bn, bv = (np.concatenate(x[pid]) if x[pid] else np.zeros(0) for x in (ring, box, box_view))
        rec: dict = {"box_points": int(len(bn)), "ring_points": int(len(rn))}
        if len(rn) < min_points or len(bn) < min_points:
            out[pid] = rec | {"standoff_m": None, "why": f"{len(bn)} depth points over the handle and {len(rn)} "
                                                          f"around it (fewer than {min_points})"}
            continue
        n0 = float(np.median(rn))
        noise = 1.4826 * float(np.median(np.abs(rn - n0)))  # the depth's noise on the front, robust
        s = bn - n0
        up = s > MIN_OUT
        rec |= {"surface_offset_m": round(n0, 5), "noise_m": round(noise, 5), "points": int(up.sum()),
                "views": int(len(np.unique(bv[up])))}
        if up.sum() < min_points:
            out[pid] = rec | {"standoff_m": 0.0, "flush": True, "iqr_m": None}
            continue
        q1, q3 = np.quantile(s[up], [0.25, 0.75])
        out[pid] = rec | {"standoff_m": round(densest(s[up], BANDWIDTH), 5), "flush": False,
                          "iqr_m": round(float(q3 - q1), 5)}
    return out


def densest(x: np.ndarray, bandwidth: float) -> float:
    """The densest value of samples ``x`` [N] (m): the peak of their Gaussian kernel density
    of ``bandwidth`` (m) on a ``BIN`` grid; of equal peaks the highest."""
    x = np.asarray(x, np.float64)
    grid = np.arange(x.min() - 4 * bandwidth, x.max() + 4 * bandwidth + BIN, BIN)  # longer than the kernel
    edges = np.concatenate([grid - BIN / 2, [grid[-1] + BIN / 2]])
    hist = np.histogram(x, edges)[0].astype(np.float64)
    k = np.arange(-math.ceil(3 * bandwidth / BIN), math.ceil(3 * bandwidth / BIN) + 1) * BIN
    dens = np.convolve(hist, np.exp(-0.5 * (k / bandwidth) ** 2), mode="same")
    return float(grid[len(dens) - 1 - int(np.argmax(dens[::-1]))])


def standoff_summary(records: dict[str, dict]) -> dict:
    """Metrics of :func:`measure_standoffs`' records: how many were measured, flush, not
    measured, and the median standoff (m) of those measured and not flush."""
    got = [r["standoff_m"] for r in records.values() if r.get("standoff_m") is not None and not r.get("flush")]
    return {"handle_standoff_measured": len(got),
            "handle_standoff_flush": sum(bool(r.get("flush")) for r in records.values()),
            "handle_standoff_unmeasured": sum(r.get("standoff_m") is None for r in records.values()),
            "handle_standoff_median_m": round(float(np.median(got)), 5) if got else None}

