"""Similarity alignment (Umeyama) and the world frame of an RGB-only reconstruction."""

from dataclasses import dataclass

import numpy as np
from jaxtyping import Float

from drawer_lib.errors import InputError
from drawer_lib.geometry.rotations import rotation_angle


@dataclass(frozen=True)
class Sim3:
    """x -> s R x + t."""

    s: float
    R: np.ndarray  # [3, 3]
    t: np.ndarray  # [3]

    def apply(self, X: np.ndarray) -> np.ndarray:
        return self.s * X @ self.R.T + self.t

    def apply_c2w(self, c2w: Float[np.ndarray, "*B 4 4"]) -> np.ndarray:
        """Transform camera-to-world poses (rotation R, centre s R c + t)."""
        out = np.array(c2w, np.float64, copy=True)
        out[..., :3, :3] = self.R @ c2w[..., :3, :3]
        out[..., :3, 3] = self.apply(c2w[..., :3, 3])
        return out


def umeyama(src: Float[np.ndarray, "N 3"], dst: Float[np.ndarray, "N 3"]) -> Sim3:
    """Least-squares similarity with dst ~ s R src + t (Umeyama 1991). Needs N >= 3 points
    that are not collinear (ValueError otherwise)."""
    src, dst = np.asarray(src, np.float64), np.asarray(dst, np.float64)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3 or len(src) < 3:
        raise InputError(f"umeyama: need matching [N>=3, 3] point sets, got {src.shape} and {dst.shape}")
    mu_s, mu_d = src.mean(0), dst.mean(0)
    xs, xd = src - mu_s, dst - mu_d
    var_s = (xs**2).sum() / len(src)
    if var_s < 1e-18:
        raise InputError("umeyama: source points coincide")
    cov = xd.T @ xs / len(src)
    U, D, Vt = np.linalg.svd(cov)
    if D[1] < 1e-12 * max(D[0], 1e-300):
        raise InputError("umeyama: points are collinear; the rotation is not determined")
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1
    R = U @ S @ Vt
    s = float(np.trace(np.diag(D) @ S) / var_s)
    t = mu_d - s * R @ mu_s
    return Sim3(s, R, t)


@dataclass(frozen=True)
class PoseErrors:
    n: int
    rot_err_deg: np.ndarray  # [n]
    center_err: np.ndarray  # [n], in the reference's units
    sim3: Sim3


def pose_errors(est_c2w: np.ndarray, ref_c2w: np.ndarray) -> PoseErrors:
    """Errors of estimated OpenCV camera-to-world poses after the similarity that best maps the
    estimated camera centres onto the reference ones."""
    sim = umeyama(est_c2w[:, :3, 3], ref_c2w[:, :3, 3])
    al = sim.apply_c2w(est_c2w)
    rot = np.rad2deg(rotation_angle(al[:, :3, :3], ref_c2w[:, :3, :3]))
    cen = np.linalg.norm(al[:, :3, 3] - ref_c2w[:, :3, 3], axis=1)
    return PoseErrors(len(est_c2w), rot, cen, sim)


def estimate_up(c2w: np.ndarray) -> np.ndarray:
    """Gravity direction of hand-held cameras (OpenCV c2w [C, 4, 4]): people hold cameras with
    little roll, so every camera's x axis is near-horizontal; up is the unit vector most
    orthogonal to all of them (smallest eigenvector of sum x x^T), signed like the mean camera
    up (-y). When every camera has the same yaw that vector is not determined and the mean
    camera up, made orthogonal to the common x axis, is used instead."""
    X = c2w[:, :3, 0]
    evals, evecs = np.linalg.eigh(X.T @ X)
    mean_up = -c2w[:, :3, 1].mean(0)
    if evals[1] > 4.0 * evals[0] + 1e-9 * evals[2]:
        z = evecs[:, 0]
    else:
        xa = evecs[:, 2]
        z = mean_up - (mean_up @ xa) * xa
    n = np.linalg.norm(z)
    if n < 1e-9:
        raise InputError("estimate_up: camera orientations do not determine an up direction")
    z = z / n
    return z if z @ mean_up >= 0 else -z


def gravity_frame(c2w: np.ndarray, points: np.ndarray, depths: np.ndarray, median_depth_m: float) -> Sim3:
    """A similarity to a world frame for an RGB-only capture (see VideoConfig): +z = the
    :func:`estimate_up` direction, +y = mean horizontal viewing direction, origin at the median
    of ``points``, scale so that the median of ``depths`` becomes ``median_depth_m``."""
    z = estimate_up(c2w)
    fwd = c2w[:, :3, 2].mean(0)
    fwd = fwd - (fwd @ z) * z
    if np.linalg.norm(fwd) < 1e-9:  # looking straight up/down on average: any horizontal axis
        fwd = np.cross(z, [1.0, 0, 0]) if abs(z[0]) < 0.9 else np.cross(z, [0, 1.0, 0])
    y = fwd / np.linalg.norm(fwd)
    x = np.cross(y, z)
    R = np.stack([x, y, z])  # rows: new axes in old coordinates -> new = R old
    d = np.asarray(depths, np.float64)
    d = d[np.isfinite(d) & (d > 0)]
    if len(d) == 0:
        raise InputError("gravity_frame: no positive point depths to fix the scale")
    s = median_depth_m / float(np.median(d))
    origin = np.median(points, axis=0) if len(points) else c2w[:, :3, 3].mean(0)
    return Sim3(s, R, -s * R @ origin)
