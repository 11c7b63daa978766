"""Lens distortion of the OPENCV camera model (k1, k2, p1, p2; COLMAP's and nerfstudio's
``OPENCV``) and the undistortion of images to a pinhole camera (numpy).

Normalised image coordinates x = (u - cx) / fx, y = (v - cy) / fy (pixel centres at +0.5, the
library convention). The model maps undistorted (x, y) to distorted (x_d, y_d):

    r^2 = x^2 + y^2,  radial = 1 + k1 r^2 + k2 r^4
    x_d = x radial + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y
"""

import numpy as np
from jaxtyping import Float

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import Intrinsics, pixel_dirs


def distort(xy: Float[np.ndarray, "*B 2"], dist: tuple[float, float, float, float]) -> Float[np.ndarray, "*B 2"]:
    """Distorted normalised coordinates of undistorted ones (the model above).

    >>> distort(np.array([[0.1, 0.0]]), (0.1, 0.0, 0.0, 0.0)).round(6).tolist()
    [[0.1001, 0.0]]
    """
    k1, k2, p1, p2 = dist
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], -1)


def undistort(xy_d: Float[np.ndarray, "*B 2"], dist: tuple[float, float, float, float], iters: int = 50,
              tol: float = 1e-12) -> Float[np.ndarray, "*B 2"]:
    """Undistorted normalised coordinates of distorted ones: the inverse of :func:`distort` by
    Newton's method on the 2x2 Jacobian of the model (converges in a few steps wherever the model
    is invertible). Raises :class:`InputError` where it does not converge (a distortion so strong
    that the image folds over)."""
    xy_d = np.asarray(xy_d, np.float64)
    k1, k2, p1, p2 = dist
    xy = xy_d.copy()
    for _ in range(iters):
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2 * r2
        dr = 2 * k1 + 4 * k2 * r2  # d radial / d (r^2) * 2
        # Jacobian of distort at (x, y)
        j00 = radial + x * dr * x + 2 * p1 * y + 6 * p2 * x
        j01 = x * dr * y + 2 * p1 * x + 2 * p2 * y
        j10 = y * dr * x + 2 * p1 * x + 2 * p2 * y
        j11 = radial + y * dr * y + 6 * p1 * y + 2 * p2 * x
        res = distort(xy, dist) - xy_d
        det = j00 * j11 - j01 * j10
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        step = np.stack([(j11 * res[..., 0] - j01 * res[..., 1]) / det, (-j10 * res[..., 0] + j00 * res[..., 1]) / det], -1)
        xy = xy - step
        if np.abs(step).max(initial=0.0) < tol:
            break
    err = np.abs(distort(xy, dist) - xy_d).max(initial=0.0)
    # a root on the far side of a fold (radial factor <= 0 or the map's Jacobian not positive)
    # is not the point the lens imaged
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    folded = bool(np.any(radial <= 0)) or bool(np.any(det <= 0)) if xy.size else False
    if not np.isfinite(err) or err > 1e-7 or folded:
        raise InputError(f"undistort: the distortion {tuple(dist)} cannot be inverted over the image "
                         f"(residual {err:.3g}); it folds the image over")
    return xy


def undistorted_intrinsics(intr: Intrinsics, samples: int = 200) -> Intrinsics:
    """Pinhole intrinsics of the same image size whose every pixel sees a point the distorted
    image holds (OpenCV's ``getOptimalNewCameraMatrix`` with alpha = 0): the largest
    axis-aligned rectangle inside the undistorted image border maps onto the whole output."""
    W, H = intr.width, intr.height
    t = np.linspace(0.0, 1.0, samples)
    edges = {"left": np.stack([np.zeros_like(t), t * H], -1), "right": np.stack([np.full_like(t, W), t * H], -1),
             "top": np.stack([t * W, np.zeros_like(t)], -1), "bottom": np.stack([t * W, np.full_like(t, H)], -1)}
    und = {k: undistort(np.stack([(uv[:, 0] - intr.cx) / intr.fx, (uv[:, 1] - intr.cy) / intr.fy], -1), intr.dist)
           for k, uv in edges.items()}
    x0, x1 = und["left"][:, 0].max(), und["right"][:, 0].min()
    y0, y1 = und["top"][:, 1].max(), und["bottom"][:, 1].min()
    if not (x1 > x0 and y1 > y0):
        raise InputError(f"undistort: the distortion {intr.dist} leaves no valid image region")
    fx, fy = W / (x1 - x0), H / (y1 - y0)
    return Intrinsics(float(fx), float(fy), float(-x0 * fx), float(-y0 * fy), W, H)


def undistortion_map(src: Intrinsics, dst: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) [H, W]: where each pixel of the undistorted image ``dst`` (pinhole) lies in
    the distorted image ``src``, as continuous array coordinates (pixel (i, j) at (i, j))."""
    d = pixel_dirs(dst)[..., :2]  # undistorted normalised coordinates of the output pixel centres
    xd = distort(d, src.dist)
    cols = xd[..., 0] * src.fx + src.cx - 0.5
    rows = xd[..., 1] * src.fy + src.cy - 0.5
    return rows, cols


def remap(img: np.ndarray, rows: np.ndarray, cols: np.ndarray, nearest: bool = False) -> np.ndarray:
    """``img`` [H, W] or [H, W, C] sampled at (``rows``, ``cols``) [h, w]: bilinear (RGB,
    continuous values) or ``nearest`` (labels, depth: no values are mixed across edges); points
    outside take the nearest border pixel. The dtype is kept (integers rounded)."""
    from scipy.ndimage import map_coordinates

    order = 0 if nearest else 1
    chans = img[..., None] if img.ndim == 2 else img
    out = np.stack([map_coordinates(chans[..., c].astype(np.float64), [rows, cols], order=order, mode="nearest")
                    for c in range(chans.shape[-1])], -1)
    if np.issubdtype(img.dtype, np.integer):
        info = np.iinfo(img.dtype)
        out = np.clip(np.round(out), info.min, info.max)
    out = out.astype(img.dtype)
    return out[..., 0] if img.ndim == 2 else out
