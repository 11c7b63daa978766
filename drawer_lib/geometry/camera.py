"""Camera conventions and pure camera ops (numpy). See :mod:`drawer_lib.geometry` for conventions."""

from dataclasses import dataclass

import numpy as np
from jaxtyping import Float

# diag(1, -1, -1) flips the y and z camera axes: OpenGL (y up, z back) <-> OpenCV (y down, z fwd).
_GL_CV_FLIP = np.diag([1.0, -1.0, -1.0, 1.0])


def opengl_to_opencv(c2w_gl: Float[np.ndarray, "*B 4 4"]) -> Float[np.ndarray, "*B 4 4"]:
    """Camera-to-world in the OpenGL convention -> camera-to-world in the OpenCV convention.

    >>> import numpy as np
    >>> opengl_to_opencv(np.eye(4))[:3, :3].diagonal().tolist()
    [1.0, -1.0, -1.0]
    """
    return c2w_gl @ _GL_CV_FLIP


def opencv_to_opengl(c2w_cv: Float[np.ndarray, "*B 4 4"]) -> Float[np.ndarray, "*B 4 4"]:
    """Inverse of :func:`opengl_to_opencv` (the flip is its own inverse)."""
    return c2w_cv @ _GL_CV_FLIP


def invert_rigid(T: Float[np.ndarray, "*B 4 4"]) -> Float[np.ndarray, "*B 4 4"]:
    """Inverse of rigid transforms [R t; 0 1] -> [R^T -R^T t; 0 1] (exact, no matrix inverse)."""
    R = T[..., :3, :3]
    t = T[..., :3, 3:]
    out = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3:] = -Rt @ t
    out[..., 3, 3] = 1.0
    return out


def check_rigid(T: np.ndarray, tol: float = 1e-4) -> str | None:
    """Return why ``T`` is not a finite rigid 4x4 transform, or None when it is.

    Checks shape, finiteness, the last row (0, 0, 0, 1), R^T R = I and det R = +1 within ``tol``.
    """
    T = np.asarray(T)
    if T.shape != (4, 4):
        return f"shape {T.shape} is not (4, 4)"
    if not np.all(np.isfinite(T)):
        return "has non-finite entries"
    if np.abs(T[3] - np.array([0.0, 0.0, 0.0, 1.0])).max() > tol:
        return f"last row {T[3].tolist()} is not [0, 0, 0, 1]"
    R = T[:3, :3].astype(np.float64)
    ortho = np.abs(R.T @ R - np.eye(3)).max()
    if ortho > tol:
        return f"rotation block is not orthonormal (max |R^T R - I| = {ortho:.3g})"
    det = float(np.linalg.det(R))
    if det < 0:
        return f"rotation block is a reflection (det = {det:.3g})"
    return None


def look_at_opencv(
    eye: Float[np.ndarray, "3"], target: Float[np.ndarray, "3"], up: Float[np.ndarray, "3"]
) -> Float[np.ndarray, "4 4"]:
    """OpenCV camera-to-world looking from ``eye`` at ``target`` with image-up close to ``up``.

    Raises ValueError when the viewing direction is (anti)parallel to ``up`` or has zero length.
    """
    fwd = np.asarray(target, np.float64) - np.asarray(eye, np.float64)
    n = np.linalg.norm(fwd)
    if n < 1e-12:
        raise ValueError("look_at: eye and target coincide")
    z = fwd / n
    x = np.cross(z, np.asarray(up, np.float64))  # right = forward x up; then y = forward x right (down)
    nx = np.linalg.norm(x)
    if nx < 1e-9:
        raise ValueError("look_at: viewing direction is parallel to up")
    x /= nx
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in the nerfstudio/COLMAP pixel convention (pixel centres at +0.5).

    ``dist`` holds OpenCV distortion (k1, k2, p1, p2); all zeros for PINHOLE.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    dist: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    @property
    def has_distortion(self) -> bool:
        return any(abs(d) > 0 for d in self.dist)

    def K(self) -> Float[np.ndarray, "3 3"]:
        """K in this convention: u = fx x/z + cx addresses the continuous image plane."""
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])

    def K_opencv(self) -> Float[np.ndarray, "3 3"]:
        """K for the OpenCV convention (centre of the top-left pixel at (0, 0)): c - 0.5."""
        K = self.K()
        K[0, 2] -= 0.5
        K[1, 2] -= 0.5
        return K

    def scaled(self, s: float) -> "Intrinsics":
        """Intrinsics of the image resized by ``s`` (exact for this pixel convention)."""
        return Intrinsics(
            self.fx * s, self.fy * s, self.cx * s, self.cy * s,
            int(round(self.width * s)), int(round(self.height * s)), self.dist,
        )

    @property
    def params(self) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy)."""
        return self.fx, self.fy, self.cx, self.cy

    @staticmethod
    def from_fovy(fovy_rad: float, width: int, height: int) -> "Intrinsics":
        """Square pixels, centred principal point, vertical field of view ``fovy_rad``."""
        f = 0.5 * height / np.tan(0.5 * fovy_rad)
        return Intrinsics(float(f), float(f), width / 2.0, height / 2.0, width, height)


def pixel_dirs(intr: Intrinsics, ii: np.ndarray | None = None, jj: np.ndarray | None = None,
               normalize: bool = False) -> np.ndarray:
    """Camera-frame directions through pixel centres (row i, column j at (j + 0.5, i + 0.5)):
    (x, y, 1), so the ray parameter of a point is its z-depth, or unit length with
    ``normalize``. All pixels [H, W, 3] by default, else those at rows ``ii`` and columns
    ``jj`` [N] -> [N, 3].

    >>> d = pixel_dirs(Intrinsics(10.0, 10.0, 2.0, 1.5, 4, 3))
    >>> d.shape, d[1, 1].tolist()
    ((3, 4, 3), [-0.05, 0.0, 1.0])
    """
    if ii is None or jj is None:
        jj, ii = np.meshgrid(np.arange(intr.width), np.arange(intr.height))
    d = np.stack([(np.asarray(jj) + 0.5 - intr.cx) / intr.fx, (np.asarray(ii) + 0.5 - intr.cy) / intr.fy,
                  np.ones(np.shape(ii))], -1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True) if normalize else d


@dataclass(frozen=True)
class Camera:
    """A posed pinhole camera: intrinsics and the OpenCV world-to-camera ``w2c`` [4, 4]. The one
    camera type of the library (splatting, ray casting, metrics, articulation)."""

    intrinsics: Intrinsics
    w2c: np.ndarray  # [4, 4] float64, OpenCV world-to-camera

    @property
    def width(self) -> int:
        return self.intrinsics.width

    @property
    def height(self) -> int:
        return self.intrinsics.height

    @property
    def c2w(self) -> np.ndarray:
        """[4, 4] OpenCV camera-to-world."""
        return invert_rigid(np.asarray(self.w2c, np.float64))

    @property
    def center(self) -> np.ndarray:
        """[3] camera centre in the world."""
        return self.c2w[:3, 3]

    def project(self, points: Float[np.ndarray, "N 3"]) -> tuple[Float[np.ndarray, "N 2"], Float[np.ndarray, "N"]]:
        """(continuous pixel coordinates [N, 2], z-depth [N]); see :func:`project_points`."""
        return project_points(points, self.w2c, self.intrinsics)

    def rays(self, ii: np.ndarray | None = None, jj: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """World ray origins and directions (camera-frame z = 1, so the ray parameter is the
        z-depth) through every pixel [H, W, 3] or through pixels (``ii``, ``jj``) [N, 3]."""
        c2w = self.c2w
        d = pixel_dirs(self.intrinsics, ii, jj) @ c2w[:3, :3].T
        return np.broadcast_to(c2w[:3, 3], d.shape), d


def project_points(
    points: Float[np.ndarray, "N 3"], w2c: Float[np.ndarray, "4 4"], intr: Intrinsics
) -> tuple[Float[np.ndarray, "N 2"], Float[np.ndarray, "N"]]:
    """Project world points to continuous pixel coordinates (this module's convention).

    Returns (uv [N, 2], z [N]); z <= 0 means behind the camera (uv is then meaningless).
    Distortion is ignored (PINHOLE).
    """
    pc = points @ w2c[:3, :3].T + w2c[:3, 3]
    z = pc[:, 2]
    zs = np.where(np.abs(z) < 1e-12, 1e-12, z)
    uv = np.stack([intr.fx * pc[:, 0] / zs + intr.cx, intr.fy * pc[:, 1] / zs + intr.cy], axis=-1)
    return uv, z


def pixel_of(points: Float[np.ndarray, "N 3"], w2c: Float[np.ndarray, "4 4"], intr: Intrinsics, near: float = 1e-9
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pixel each point falls in: (rows [N], cols [N], z-depth [N], inside [N]) where
    ``inside`` = in front of the camera (z > ``near``) and within the image; rows and cols of
    the other points are 0, so they can index an image safely."""
    uv, z = project_points(points, w2c, intr)
    ok = z > near
    uv = np.where(ok[:, None], uv, -1.0)
    j, i = np.floor(uv[:, 0]).astype(np.int64), np.floor(uv[:, 1]).astype(np.int64)
    ok &= (j >= 0) & (j < intr.width) & (i >= 0) & (i < intr.height)
    return np.where(ok, i, 0), np.where(ok, j, 0), z, ok


def normals_from_depth(z: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """Unit normals [H, W, 3] (OpenCV camera frame, facing the camera) of the surface a z-depth
    map [H, W] shows: the cross product of its back-projected points' central differences.
    Where that is degenerate (depth <= 0 or not finite nearby, a zero-area patch) the normal is
    the one facing the camera, (0, 0, -1).

    >>> n = normals_from_depth(np.full((4, 5), 2.0), Intrinsics(10.0, 10.0, 2.5, 2.0, 5, 4))
    >>> np.round(n[2, 2], 6).tolist() == [0.0, 0.0, -1.0]
    True
    """
    z = np.asarray(z, np.float64)
    if z.shape != (intr.height, intr.width):
        raise ValueError(f"depth {z.shape} does not match the camera's {intr.height}x{intr.width}")
    ok = np.isfinite(z) & (z > 0)
    p = pixel_dirs(intr) * np.where(ok, z, 0.0)[..., None]
    du, dv = np.gradient(p, axis=1), np.gradient(p, axis=0)
    n = np.cross(du, dv)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    bad = ~ok | ~np.isfinite(norm[..., 0]) | (norm[..., 0] <= 1e-12)
    bad |= ~(np.pad(ok, 1, mode="edge")[:-2, 1:-1] & np.pad(ok, 1, mode="edge")[2:, 1:-1]
             & np.pad(ok, 1, mode="edge")[1:-1, :-2] & np.pad(ok, 1, mode="edge")[1:-1, 2:])
    n = n / np.where(norm > 0, norm, 1.0)
    n = np.where((np.sum(n * p, axis=-1, keepdims=True) > 0), -n, n)
    n[bad] = (0.0, 0.0, -1.0)
    return n
