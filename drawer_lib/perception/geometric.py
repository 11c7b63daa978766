"""Decomposition without detections: front panels from the mesh and the images alone.

1. Vertical planar regions: faces whose normal is within ``vertical_deg`` of horizontal, grown
   over edges with a dihedral angle below ``smooth_deg``; regions of at least ``min_area`` m^2.
2. Each region is rasterised on its plane at ``cell`` (the facade): occupancy, the height of
   the mesh above the plane (depth steps between tracks), and the median colour over the train
   views that see the cell (depth-tested). The gaps between fronts show as thin lines of
   strong colour gradient; steps show as jumps in height.
3. Recursive XY-cut: a rectangle is split at the row or column whose edge strength, summed
   along it over the rectangle, is the largest and exceeds the ``edge_quantile`` of the
   facade's edge strength times the rectangle's extent, as long as both sides keep at least
   ``min_front`` m. Leaves are the front candidates; their faces become segments.

This is a weaker cue than a detector: it finds the lines between flush fronts only when the
images show them. The benchmark reports how it compares.
"""

import numpy as np

from drawer_lib.geometry.camera import pixel_of
from drawer_lib.geometry.frames import UP, plane_axes
from drawer_lib.io.capture import Capture
from drawer_lib.perception.config import DecomposeConfig, GeometricConfig
from drawer_lib.perception.decompose import Segment, face_geometry
from drawer_lib.perception.views import MeshViews, adjacency_edges, connected_components


def vertical_regions(views: MeshViews, g: GeometricConfig) -> list[np.ndarray]:
    mesh = views.mesh
    n = np.asarray(mesh.face_normals)
    vert = np.abs(n @ UP) < np.sin(np.deg2rad(g.vertical_deg))
    edges, dih = adjacency_edges(mesh)
    lab = connected_components(len(mesh.faces), edges[dih < g.smooth_deg], vert)
    area = np.asarray(mesh.area_faces)
    out = []
    for c in np.unique(lab[lab >= 0]):
        f = np.nonzero(lab == c)[0]
        if area[f].sum() >= g.min_area:
            out.append(f)
    return out


def _facade(views: MeshViews, cap: Capture, images: list[np.ndarray], faces: np.ndarray, g: GeometricConfig):
    """Plane frame (c, n, u, v), grid origin/shape, occupancy (the plane point is the surface a
    view sees), height of the mesh above the plane, median colour."""
    mesh = views.mesh
    nrm, _, c, _ = face_geometry(mesh, faces, 30.0)
    u, v = plane_axes(nrm)
    tri = np.asarray(mesh.triangles)[faces]
    pts = tri.reshape(-1, 3)
    uv = np.stack([(pts - c) @ u, (pts - c) @ v], -1)
    lo, hi = uv.min(0), uv.max(0)
    shape = np.maximum(np.ceil((hi - lo) / g.cell).astype(int), 1)
    gu = lo[0] + (np.arange(shape[0]) + 0.5) * g.cell
    gv = lo[1] + (np.arange(shape[1]) + 0.5) * g.cell
    UU, VV = np.meshgrid(gu, gv, indexing="ij")
    P = c + UU[..., None] * u + VV[..., None] * v  # [Nu, Nv, 3] points on the plane
    # occupancy and height from the face centroids
    cen = np.asarray(mesh.triangles_center)[faces]
    cu = np.clip(((cen - c) @ u - lo[0]) / g.cell, 0, shape[0] - 1).astype(int)
    cv = np.clip(((cen - c) @ v - lo[1]) / g.cell, 0, shape[1] - 1).astype(int)
    height = np.full(shape, np.nan)
    hsum = np.zeros(shape)
    hcnt = np.zeros(shape)
    np.add.at(hsum, (cu, cv), (cen - c) @ nrm)
    np.add.at(hcnt, (cu, cv), 1)
    height[hcnt > 0] = hsum[hcnt > 0] / hcnt[hcnt > 0]
    # median colour over the views that see each cell
    it = cap.intrinsics
    cols = []
    flat = P.reshape(-1, 3)
    for t, i in enumerate(views.frames):
        yi, xi, z, ok = pixel_of(flat, cap.frames[i].w2c, it, near=1e-3)
        d = np.zeros(len(flat))
        d[ok] = views.depth_maps[t][yi[ok], xi[ok]]
        ok &= np.abs(d - z) < 0.02  # visible: the mesh's first hit is this point
        img = images[t]
        col = np.full((len(flat), 3), np.nan, np.float32)
        col[ok] = img[yi[ok], xi[ok]]
        cols.append(col)
    stack = np.stack(cols) if cols else np.full((1, len(flat), 3), np.nan, np.float32)
    seen = np.isfinite(stack[..., 0]).any(0)
    colour = np.full((len(flat), 3), np.nan, np.float32)
    colour[seen] = np.nanmedian(stack[:, seen], 0)
    colour = colour.reshape(*shape, 3)
    occ = seen.reshape(shape)  # the plane point is the surface some view sees
    return (c, nrm, u, v), lo, shape, occ, height, colour


def _edge_strength(colour: np.ndarray, height: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(strength of lines across u, i.e. between columns [Nu-1, Nv]; between rows [Nu, Nv-1])."""
    col = np.nan_to_num(colour, nan=0.0)
    h = np.nan_to_num(height, nan=0.0)
    du = np.abs(np.diff(col, axis=0)).sum(-1) + 20.0 * np.abs(np.diff(h, axis=0))
    dv = np.abs(np.diff(col, axis=1)).sum(-1) + 20.0 * np.abs(np.diff(h, axis=1))
    return du, dv


def xy_cut(du: np.ndarray, dv: np.ndarray, occ: np.ndarray, min_cells: int, thresh: float) -> list[tuple[int, int, int, int]]:
    """Leaves (u0, u1, v0, v1) (cell ranges, end exclusive) of the recursive cut."""
    out = []
    stack = [(0, occ.shape[0], 0, occ.shape[1])]
    while stack:
        u0, u1, v0, v1 = stack.pop()
        if occ[u0:u1, v0:v1].mean() < 0.5:
            continue
        best = None
        # a cut between columns k-1 and k (u) has strength mean over the rows of du[k-1]
        if u1 - u0 >= 2 * min_cells:
            s = du[u0:u1 - 1, v0:v1].mean(1)
            ks = np.arange(u0 + min_cells, u1 - min_cells + 1)
            if len(ks):
                k = ks[np.argmax(s[ks - 1 - u0])]
                best = (s[k - 1 - u0], "u", k)
        if v1 - v0 >= 2 * min_cells:
            s = dv[u0:u1, v0:v1 - 1].mean(0)
            ks = np.arange(v0 + min_cells, v1 - min_cells + 1)
            if len(ks):
                k = ks[np.argmax(s[ks - 1 - v0])]
                if best is None or s[k - 1 - v0] > best[0]:
                    best = (s[k - 1 - v0], "v", k)
        if best is None or best[0] < thresh:
            out.append((u0, u1, v0, v1))
            continue
        _, ax, k = best
        if ax == "u":
            stack += [(u0, k, v0, v1), (k, u1, v0, v1)]
        else:
            stack += [(u0, u1, v0, k), (u0, u1, k, v1)]
    return out


def decompose_geometric(cap: Capture, views: MeshViews, g: GeometricConfig, cfg: DecomposeConfig
                        ) -> tuple[list[Segment], np.ndarray, dict]:
    mesh = views.mesh
    cen_all = np.asarray(mesh.triangles_center)
    segs: list[Segment] = []
    regions = vertical_regions(views, g)
    min_cells = max(int(round(g.min_front / g.cell)), 1)
    images = [cap.image(i).astype(np.float32) / 255.0 for i in views.frames]  # read once, not per region
    for faces in regions:
        (c, nrm, u, v), lo, shape, occ, height, colour = _facade(views, cap, images, faces, g)
        du, dv = _edge_strength(colour, height)
        ref = np.concatenate([du.ravel(), dv.ravel()])
        if len(ref) == 0:
            continue
        thresh = float(np.quantile(ref, g.edge_quantile))
        cen = cen_all[faces]
        fu = ((cen - c) @ u - lo[0]) / g.cell
        fv = ((cen - c) @ v - lo[1]) / g.cell
        for u0, u1, v0, v1 in xy_cut(du, dv, occ, min_cells, thresh):
            sel = faces[(fu >= u0) & (fu < u1) & (fv >= v0) & (fv < v1)]
            if len(sel) < cfg.min_faces:
                continue
            n, area, cc, frac = face_geometry(mesh, sel, cfg.planar_deg)
            segs.append(Segment(len(segs), sel, 1.0, 0, {}, frac >= cfg.planar_frac, n, area, cc, source="geometric"))
    info = {"vertical_regions": len(regions), "segments": len(segs)}
    return segs, np.zeros(len(mesh.faces), np.int64), info
