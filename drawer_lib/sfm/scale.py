"""Metric scale of an RGB-only reconstruction from what it shows.

Structure-from-motion recovers a kitchen up to an unknown scale. Three cues give it, each as an
estimate of log(scale) with a standard deviation, fused by inverse variance:

* ``counter``: the worktop's height above the floor. Horizontal surfaces are sharp peaks in the
  histogram of the SfM points' heights (a vertical front spreads its points over its height);
  the floor is the lowest peak below every camera, the worktop the strongest peak between
  ``counter_window`` of the cameras' height above the floor. Kitchen worktops stand
  ``counter_height_m`` = 0.91 m above the floor (0.90-0.92 m in Europe, 36 in in the US);
  ``counter_sigma`` = 0.12 was chosen on the benchmark's train split, whose worktops stand
  0.70-1.09 m, so the cue is trusted no more than a kitchen of unusual height allows. A user
  who measured theirs gives it (``video.counter_height_m``), and the cue is then as sure as the
  peaks are sharp. SfM finds few points on a plain worktop: the peak is not always there.
* ``camera``: the cameras' height above the floor: a phone held while walking, ``camera_height_m``
  (1.45 m) within ``camera_sigma`` (log).
* ``median_depth``: the median depth of the SfM points, ``median_depth_m`` within
  ``median_depth_sigma`` (log): the weakest, and the only one without a floor.

A cue that disagrees with the others by more than ``max_z`` standard deviations is dropped and
reported (a row of handles taken for the worktop). Lengths in the reconstruction's units unless
named ``_m``; the frame is gravity-aligned (+z up).
"""

import math
from dataclasses import dataclass, field

import numpy as np
from jaxtyping import Float

from drawer_lib.errors import ConfigError, InputError


@dataclass(frozen=True)
class ScaleConfig:
    """How a video's metric scale is estimated (``capture.video.scale``; module doc). ``method``:
    ``reconstruction`` (the cues) or ``median_depth`` (the median depth alone, the old guess).
    ``bin_rel``: the height histogram's bin as a fraction of the cameras' height above the
    lowest points; ``min_peak``: a peak holds at least this fraction of the points and
    ``peak_prominence`` x the median count of its search window;
    ``counter_window``: where the worktop is looked for, as fractions of the cameras' height
    above the floor. ``metric_sigma``: the frame is called metric when the estimate's log
    standard deviation is at most this (0.1: about 10 %)."""

    method: str = "reconstruction"
    counter_height_m: float = 0.91
    counter_sigma: float = 0.12
    measured_counter_sigma: float = 0.01
    camera_height_m: float = 1.45
    camera_sigma: float = 0.15
    median_depth_m: float = 1.8
    median_depth_sigma: float = 0.35
    bin_rel: float = 0.012
    min_peak: float = 0.01
    peak_prominence: float = 1.5
    counter_window: tuple[float, float] = (0.45, 0.85)
    max_z: float = 3.0
    metric_sigma: float = 0.1

    def __post_init__(self):
        if self.method not in ("reconstruction", "median_depth"):
            raise ConfigError(f"video.scale.method = {self.method!r} must be reconstruction or median_depth")
        for k in ("counter_height_m", "counter_sigma", "measured_counter_sigma", "camera_height_m", "camera_sigma",
                  "median_depth_m", "median_depth_sigma", "bin_rel", "min_peak", "peak_prominence", "max_z",
                  "metric_sigma"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"video.scale.{k} = {v} must be finite and > 0")
        lo, hi = self.counter_window
        if not 0 < lo < hi < 1:
            raise ConfigError(f"video.scale.counter_window = {self.counter_window} must satisfy 0 < lo < hi < 1")


@dataclass
class ScaleEstimate:
    """``factor``: multiply the reconstruction's lengths by it to get metres; ``sigma``: the
    standard deviation of log(factor) (0.05: about 5 %); ``cues``: per cue its factor, sigma,
    whether it was used and why not; ``floor`` / ``counter``: the peaks' heights (units) or None."""

    factor: float
    sigma: float
    cues: dict = field(default_factory=dict)
    floor: float | None = None
    counter: float | None = None

    def to_json(self) -> dict:
        return {"factor": round(self.factor, 6), "sigma_log": round(self.sigma, 4),
                "floor": None if self.floor is None else round(self.floor, 4),
                "counter": None if self.counter is None else round(self.counter, 4), "cues": self.cues}


def height_peaks(z: Float[np.ndarray, "N"], bin_w: float) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres [B], counts smoothed over 3 bins [B]) of the heights ``z``."""
    lo, hi = float(z.min()), float(z.max())
    n = max(int(math.ceil((hi - lo) / bin_w)), 1)
    h, e = np.histogram(z, bins=n, range=(lo, lo + n * bin_w))
    sm = np.convolve(h.astype(float), [1.0, 1.0, 1.0], mode="same")
    return (e[:-1] + e[1:]) / 2, sm


def _peak(centres: np.ndarray, counts: np.ndarray, lo: float, hi: float, min_count: float,
          prominence: float) -> float | None:
    """The height of the strongest bin of ``counts`` within [lo, hi] holding at least
    ``min_count`` points and ``prominence`` x the window's median count, or None."""
    sel = np.nonzero((centres >= lo) & (centres <= hi))[0]
    if len(sel) < 3:
        return None
    c = counts[sel]
    k = int(np.argmax(c))
    if c[k] < min_count or c[k] < prominence * np.median(c):
        return None
    return float(centres[sel[k]])


def _refine(z: np.ndarray, at: float | None, bin_w: float) -> float | None:
    """A peak's height refined to the median of the heights within 1.5 bins of it."""
    if at is None:
        return None
    near = z[np.abs(z - at) <= 1.5 * bin_w]
    return float(np.median(near)) if len(near) else at


def estimate_scale(points: Float[np.ndarray, "N 3"], cam_centres: Float[np.ndarray, "C 3"],
                   depths: Float[np.ndarray, "M"], cfg: ScaleConfig, measured_counter_m: float | None = None
                   ) -> ScaleEstimate:
    """The metric scale of a gravity-aligned reconstruction (module doc): ``points`` [N, 3] its
    SfM points, ``cam_centres`` [C, 3], ``depths`` the points' depths in the views (any
    number, > 0), all in the reconstruction's units; ``measured_counter_m`` a worktop height
    the user measured (m)."""
    P = np.asarray(points, np.float64)
    C = np.asarray(cam_centres, np.float64)
    d = np.asarray(depths, np.float64)
    d = d[np.isfinite(d) & (d > 0)]
    if len(d) == 0 or len(C) == 0:
        raise InputError("estimate_scale: no point depths or no cameras to fix the scale")
    cues: dict = {}
    md = math.log(cfg.median_depth_m / float(np.median(d)))
    cues["median_depth"] = {"factor": math.exp(md), "sigma": cfg.median_depth_sigma, "used": True}
    est: list[tuple[str, float, float]] = [("median_depth", md, cfg.median_depth_sigma)]
    floor = counter = None
    P = P[np.isfinite(P).all(1)]
    if cfg.method == "reconstruction" and len(P) >= 50:
        z = P[:, 2]
        cam_z = float(np.median(C[:, 2]))
        span = cam_z - float(np.percentile(z, 1))
        if span > 0:
            bin_w = cfg.bin_rel * span
            centres, counts = height_peaks(z, bin_w)
            floor = _refine(z, _peak(centres, counts, float(z.min()), float(np.percentile(z, 1)) + 0.15 * span,
                                     cfg.min_peak * len(z), cfg.peak_prominence), bin_w)
        if floor is not None and floor < C[:, 2].min():
            H = cam_z - floor
            cam = math.log(cfg.camera_height_m / H)
            cues["camera"] = {"factor": math.exp(cam), "sigma": cfg.camera_sigma, "used": True,
                              "height_units": round(H, 4)}
            est.append(("camera", cam, cfg.camera_sigma))
            lo, hi = cfg.counter_window
            counter = _refine(z, _peak(centres, counts, floor + lo * H, floor + hi * H, cfg.min_peak * len(z),
                                       cfg.peak_prominence), bin_w)
            if counter is not None:
                height_m = measured_counter_m if measured_counter_m is not None else cfg.counter_height_m
                sig = cfg.measured_counter_sigma if measured_counter_m is not None else cfg.counter_sigma
                sig = math.hypot(sig, 0.5 * bin_w / (counter - floor))  # where in its bins each peak lies
                cnt = math.log(height_m / (counter - floor))
                cues["counter"] = {"factor": math.exp(cnt), "sigma": round(sig, 4), "used": True,
                                   "height_units": round(counter - floor, 4), "height_m": height_m,
                                   "measured": measured_counter_m is not None}
                est.append(("counter", cnt, sig))
            else:
                cues["counter"] = {"used": False, "why": "no horizontal peak where a worktop would be"}
        else:
            floor = None
            cues["camera"] = {"used": False, "why": "no floor below the cameras"}
            cues["counter"] = {"used": False, "why": "no floor below the cameras"}
    # drop a cue that disagrees with the fusion of the others
    while len(est) > 2:
        worst, worst_z = None, 0.0
        for i, (name, v, s) in enumerate(est):
            rest = [e for j, e in enumerate(est) if j != i]
            w = np.array([1 / e[2] ** 2 for e in rest])
            m = float(np.sum(w * np.array([e[1] for e in rest])) / w.sum())
            zz = abs(v - m) / math.hypot(s, math.sqrt(1 / w.sum()))
            if zz > worst_z:
                worst, worst_z = i, zz
        if worst is None or worst_z <= cfg.max_z:
            break
        name = est[worst][0]
        cues[name] |= {"used": False, "why": f"disagrees with the other cues by {worst_z:.1f} sigma"}
        est.pop(worst)
    w = np.array([1 / e[2] ** 2 for e in est])
    v = float(np.sum(w * np.array([e[1] for e in est])) / w.sum())
    for c in cues.values():
        if "factor" in c:
            c["factor"] = round(c["factor"], 6)
    return ScaleEstimate(math.exp(v), float(math.sqrt(1 / w.sum())), cues, floor, counter)
