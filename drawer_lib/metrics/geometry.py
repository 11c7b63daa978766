"""Mesh accuracy against a ground-truth mesh (docs/formats.md#geometry).

Points are sampled on each mesh (area-uniform) and measured to the *surface* of the other with
exact point-to-triangle distances (Open3D's Embree BVH), not to the other's samples. Only what
the train views could see is scored:

- a GT point counts when some train view sees it: its face points towards the camera, it
  projects into the image in front of the camera, and its depth matches the GT depth at that
  pixel within ``vis_tol`` (a depth test; the facing test keeps the back faces of thin panels,
  which lie within the tolerance behind their front faces, out);
- a predicted point counts unless no train view sees it at or in front of the observed (GT)
  surface: points hidden behind the GT surface in every view that contains them (interiors) are
  not scored, floaters in free space are.

Chamfer-L1 = mean of the two directions' mean distances (m); precision / recall at tau are the
fractions of counted predicted / GT points within tau of the other surface, F = 2PR / (P + R);
normal consistency = mean over both directions of |n . n_closest|.
"""

from dataclasses import dataclass

import numpy as np
import trimesh
from jaxtyping import Float

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import Intrinsics, pixel_of
from drawer_lib.geometry.raycast import Raycaster
from drawer_lib.geometry.sampling import sample_triangles

THRESHOLDS = {"fscore_1cm": 0.01, "fscore_2cm": 0.02}


@dataclass(frozen=True)
class SurfaceSamples:
    points: np.ndarray  # [N, 3]
    normals: np.ndarray  # [N, 3] unit face normals


def sample_surface(mesh: trimesh.Trimesh, n: int, seed: int = 0) -> SurfaceSamples:
    """``n`` area-uniform samples with their face normals (zero-area faces are never drawn)."""
    if len(mesh.faces) == 0:
        raise InputError("sample_surface: mesh has no faces")
    tri = np.asarray(mesh.triangles, np.float64)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    p, f = sample_triangles(tri, n, np.random.default_rng(seed), areas=area)
    nrm = cross[f] / np.maximum(2 * area[f], 1e-300)[:, None]
    return SurfaceSamples(p, nrm)


class SurfaceDistance:
    """Exact unsigned distance from points to a mesh surface, with the closest face's normal."""

    def __init__(self, mesh: trimesh.Trimesh):
        import open3d as o3d

        self._o3d = o3d
        m = o3d.t.geometry.TriangleMesh()
        m.vertex.positions = o3d.core.Tensor(np.ascontiguousarray(mesh.vertices, np.float32))
        m.triangle.indices = o3d.core.Tensor(np.ascontiguousarray(mesh.faces, np.int32))
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(m)
        self.face_normals = np.asarray(mesh.face_normals, np.float64)

    def __call__(self, points: Float[np.ndarray, "N 3"]) -> tuple[np.ndarray, np.ndarray]:
        """(distance [N], normal of the closest face [N, 3])."""
        q = self._o3d.core.Tensor(np.ascontiguousarray(points, np.float32))
        ans = self.scene.compute_closest_points(q)
        cp = ans["points"].numpy().astype(np.float64)
        fid = ans["primitive_ids"].numpy().astype(np.int64)
        return np.linalg.norm(cp - points, axis=1), self.face_normals[fid]


@dataclass
class Views:
    """Train cameras and the GT depth each of them observes."""

    intr: Intrinsics
    w2c: np.ndarray  # [C, 4, 4] OpenCV
    depth: np.ndarray  # [C, H, W] GT z-depth (0 = nothing)

    def project(self, k: int, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(in-image mask [N], observed GT depth at the pixel [N], point depth [N]) for view k."""
        i, j, z, inside = pixel_of(X, self.w2c[k], self.intr)
        obs = np.zeros(len(X))
        obs[inside] = self.depth[k, i[inside], j[inside]]
        return inside & (obs > 0), obs, z


def gt_views(gt_mesh: trimesh.Trimesh, intr: Intrinsics, w2c: np.ndarray) -> Views:
    rc = Raycaster(np.asarray(gt_mesh.vertices), np.asarray(gt_mesh.faces))
    depth = np.stack([rc.depth_normals(intr, T)[0] for T in w2c])
    return Views(intr, np.asarray(w2c, np.float64), depth)


def seen_mask(views: Views, X: np.ndarray, N: np.ndarray, vis_tol: float) -> np.ndarray:
    """GT points (with outward normals ``N``) some view sees: facing the camera, in the image and
    at the observed depth (relative tolerance ``vis_tol`` of the depth, at least 5 mm)."""
    seen = np.zeros(len(X), bool)
    for k in range(len(views.w2c)):
        ok, obs, z = views.project(k, X)
        center = -views.w2c[k, :3, :3].T @ views.w2c[k, :3, 3]
        facing = np.einsum("nc,nc->n", N, center - X) > 0
        seen |= ok & facing & (np.abs(z - obs) <= np.maximum(vis_tol * obs, 0.005))
    return seen


def not_hidden_mask(views: Views, X: np.ndarray, hidden_tol: float) -> np.ndarray:
    """Predicted points some view sees at or in front of the observed surface (+``hidden_tol``)."""
    keep = np.zeros(len(X), bool)
    for k in range(len(views.w2c)):
        ok, obs, z = views.project(k, X)
        keep |= ok & (z <= obs + hidden_tol)
    return keep


class MeshEvaluator:
    """Scores predicted meshes against one GT mesh seen by fixed train views.

    The GT side (samples, visibility, distance structure) is built once, so scoring several
    meshes (e.g. along a training curve) costs only the predicted side.
    """

    def __init__(self, gt_mesh: trimesh.Trimesh, intr: Intrinsics, w2c: np.ndarray, n_points: int = 500_000,
                 vis_tol: float = 0.01, hidden_tol: float = 0.02, seed: int = 0):
        self.views = gt_views(gt_mesh, intr, w2c)
        self.n_points, self.hidden_tol, self.seed = n_points, hidden_tol, seed
        s = sample_surface(gt_mesh, n_points, seed)
        m = seen_mask(self.views, s.points, s.normals, vis_tol)
        if not m.any():
            raise InputError("MeshEvaluator: no GT surface is seen by the train views")
        self.gt = SurfaceSamples(s.points[m], s.normals[m])
        self.to_gt = SurfaceDistance(gt_mesh)

    def __call__(self, pred: trimesh.Trimesh) -> dict[str, float]:
        """Chamfer-L1, F-scores at 1 and 2 cm, precision/recall, normal consistency."""
        if len(pred.faces) == 0:
            raise InputError("MeshEvaluator: predicted mesh is empty")
        s = sample_surface(pred, self.n_points, self.seed + 1)
        m = not_hidden_mask(self.views, s.points, self.hidden_tol)
        if not m.any():
            raise InputError("MeshEvaluator: no predicted surface lies where the train views look")
        p_pts, p_nrm = s.points[m], s.normals[m]
        d_p, n_gt_at_p = self.to_gt(p_pts)
        d_g, n_p_at_g = SurfaceDistance(pred)(self.gt.points)
        out = {"chamfer_l1": 0.5 * (d_p.mean() + d_g.mean()),
               "accuracy": d_p.mean(), "completeness": d_g.mean()}
        for name, tau in THRESHOLDS.items():
            prec, rec = (d_p < tau).mean(), (d_g < tau).mean()
            out[name] = 0.0 if prec + rec == 0 else 2 * prec * rec / (prec + rec)
            out[f"precision_{name[7:]}"], out[f"recall_{name[7:]}"] = prec, rec
        out["normal_consistency"] = 0.5 * (np.abs(np.sum(p_nrm * n_gt_at_p, 1)).mean()
                                           + np.abs(np.sum(self.gt.normals * n_p_at_g, 1)).mean())
        out["n_pred_points_scored"] = float(m.sum())
        out["n_gt_points_scored"] = float(len(self.gt.points))
        return {k: float(v) for k, v in out.items()}
