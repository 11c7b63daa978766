"""Rigid objects as closed solids: the visible shell of an object closed against the surface it
stands on, its mass properties from a density table, and convex collision pieces.

Conventions: world frame, metres, +z up; volume m^3, density kg/m^3, mass kg, inertia kg·m^2
about the centre of mass in world axes.

A reconstructed object is an open shell: the cameras never see its underside, often not its
back. Closing (``method``):
- ``closed``: the shell is already watertight;
- ``extrude``: every boundary loop near the support (or whose hole faces down) is projected
  straight down onto the support plane, the band between loop and projection is added and the
  projected loop is capped; other holes (in a side, on top) are capped in place. The cap is a
  fan from the loop's centroid, so a non-star-shaped loop overlaps itself; the signed volume
  (and so the mass properties) stays exact, as a fan over any closed polygon sums to its area;
- ``hull``: when the shell is too broken (non-manifold edges, too many loops or boundary
  edges) or the closed result is not watertight or not a valid volume: the convex hull of the
  shell and its footprint (its vertices projected onto the support).
"""

import math
import time
from dataclasses import dataclass, field

import numpy as np
import trimesh
from jaxtyping import Float, Int
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from drawer_lib.complete.config import RigidConfig
from drawer_lib.complete.cut import submesh
from drawer_lib.errors import InputError
from drawer_lib.io.parts import Part, PartsFile
from drawer_lib.bodies import Shape, convex_pieces, mesh_shape

_MERGE = 1e-7  # m: vertices closer than this are one


# ----------------------------------------------------------------------------------- faces


def rigid_faces(part: Part, mesh: trimesh.Trimesh, cfg: RigidConfig,
                face_labels: Int[np.ndarray, "F"] | None = None) -> Int[np.ndarray, "K"]:
    """The faces [K] of ``mesh`` that show rigid ``part``: with ``face_labels`` [F] (the
    decompose stage's segment id per face of its perception mesh) those of the part's
    ``segment``; else the faces whose centroid lies in the part's ``bounds`` grown by
    ``bounds_margin`` (x, y, and above) and more than ``above_support`` above its bottom (the
    supporting surface under it is not the object). Raises :class:`InputError` naming the part
    when none is found."""
    if part.kind != "rigid":
        raise InputError(f"part {part.id}: kind {part.kind!r} is not rigid")
    F = np.asarray(mesh.faces)
    if face_labels is not None and part.extra.get("segment") is not None:
        labels = np.asarray(face_labels)
        if labels.shape != (len(F),):
            raise InputError(f"part {part.id}: {len(labels)} face labels for a mesh of {len(F)} faces")
        faces = np.flatnonzero(labels == int(part.extra["segment"]))
        how = f"segment {part.extra['segment']}"
    else:
        if part.bounds is None:
            raise InputError(f"part {part.id}: no face labels and no bounds to find its faces")
        lo, hi = np.asarray(part.bounds[0], np.float64), np.asarray(part.bounds[1], np.float64)
        m = cfg.bounds_margin
        C = np.asarray(mesh.vertices, np.float64)[F].mean(1) if len(F) else np.zeros((0, 3))
        faces = np.flatnonzero(np.all(C[:, :2] >= lo[:2] - m, 1) & np.all(C[:, :2] <= hi[:2] + m, 1)
                               & (C[:, 2] > lo[2] + cfg.above_support) & (C[:, 2] <= hi[2] + m))
        how = "its bounds"
    if len(faces) == 0:
        raise InputError(f"rigid part {part.id}: no mesh faces in {how} (an empty segment)")
    return faces.astype(np.int64)


def support_height(mesh: trimesh.Trimesh, shell_faces: Int[np.ndarray, "K"], cfg: RigidConfig) -> tuple[float, str]:
    """(height z (m) of the surface the shell stands on, how it was found): the median height of
    the up-facing faces of ``mesh`` outside the shell within ``support_xy`` of its footprint,
    from ``support_below`` under to ``support_above`` over its lowest point ("faces"); its
    lowest point when fewer than ``support_min_faces`` qualify ("lowest point")."""
    V, F = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    S = V[np.unique(F[shell_faces])]
    zmin = float(S[:, 2].min())
    lo, hi = S[:, :2].min(0) - cfg.support_xy, S[:, :2].max(0) + cfg.support_xy
    C = V[F].mean(1)  # [F, 3]
    N = np.asarray(mesh.face_normals, np.float64)
    other = np.ones(len(F), bool)
    other[shell_faces] = False
    sel = (other & (N[:, 2] > math.cos(math.radians(cfg.support_deg))) & np.all(C[:, :2] >= lo, 1)
           & np.all(C[:, :2] <= hi, 1) & (C[:, 2] >= zmin - cfg.support_below) & (C[:, 2] <= zmin + cfg.support_above))
    if sel.sum() >= cfg.support_min_faces:
        return float(np.median(C[sel, 2])), "faces"
    return zmin, "lowest point"


# --------------------------------------------------------------------------------- closing


def clean_shell(vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"]
                ) -> tuple[Float[np.ndarray, "U 3"], Int[np.ndarray, "G 3"]]:
    """Merge vertices closer than 1e-7 m, drop faces that repeat a vertex (index-degenerate)
    and duplicate faces (the same three vertices), and unused vertices. Zero-area faces with
    three distinct vertices are kept (they keep the shell's topology)."""
    key = np.round(vertices / _MERGE).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    f = inv.reshape(-1)[faces]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    _, keep = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    f = f[np.sort(keep)]
    used, inv2 = np.unique(f.reshape(-1), return_inverse=True)
    return vertices[first][used], inv2.reshape(-1, 3)


def unpinch(faces: Int[np.ndarray, "F 3"]) -> tuple[Int[np.ndarray, "F 3"], Int[np.ndarray, "U"]]:
    """Split every vertex whose faces form several fans (faces around it connected through
    shared edges; e.g. where two holes touch) into one vertex per fan. Returns (new faces
    [F, 3], the source vertex of each new vertex [U]). Assumes manifold edges (<= 2 faces)."""
    Fn = len(faces)
    wv = faces.reshape(-1)  # [3F] vertex of wedge 3 f + k
    e, key, cnt = _edges(faces)
    ent = np.flatnonzero(cnt == 2)
    ent = ent[np.argsort(key[ent], kind="stable")]
    i, j = ent[0::2], ent[1::2]  # the two entries of each interior edge
    fi, ki, fj, kj = i // 3, i % 3, j // 3, j % 3
    wa_i, wb_i = 3 * fi + ki, 3 * fi + (ki + 1) % 3  # wedges of entry i at its start / end vertex
    wa_j, wb_j = 3 * fj + kj, 3 * fj + (kj + 1) % 3
    same = wv[wa_i] == wv[wa_j]  # both entries run the same way (inconsistent winding)
    u = np.concatenate([wa_i, wb_i])
    v = np.concatenate([np.where(same, wa_j, wb_j), np.where(same, wb_j, wa_j)])
    n, lab = connected_components(coo_matrix((np.ones(len(u)), (u, v)), shape=(3 * Fn, 3 * Fn)), directed=False)
    src = np.zeros(n, np.int64)
    src[lab] = wv
    return lab.reshape(-1, 3).astype(np.int64), src


def _edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(directed edges [3F, 2] in face order, undirected key of each [3F], use count of each)."""
    e = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    s = np.sort(e, axis=1)
    key = s[:, 0] * (int(faces.max()) + 1) + s[:, 1]
    _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    return e, key, cnt[inv.reshape(-1)]


def close_shell(vertices: Float[np.ndarray, "V 3"], faces: Int[np.ndarray, "F 3"], support_z: float,
                cfg: RigidConfig) -> tuple[trimesh.Trimesh, str, str]:
    """Close an open shell (outward faces) standing on the plane z = ``support_z`` (m).
    Returns (closed solid, method ``closed`` | ``extrude`` | ``hull``, the reason for the
    method). See the module doc."""
    V, F = clean_shell(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
    if len(F) == 0:
        raise InputError("close_shell: the shell has no faces with three distinct vertices")
    V = V.copy()
    V[:, 2] = np.maximum(V[:, 2], support_z)  # nothing sinks into the support
    e, key, cnt = _edges(F)
    if np.any(cnt > 2):
        return _hull(V, support_z), "hull", f"{len(np.unique(key[cnt > 2]))} non-manifold edges"
    F, src = unpinch(F)  # holes touching at a vertex become separate loops
    V = V[src]
    e, key, cnt = _edges(F)
    bnd = cnt == 1
    if not bnd.any():
        m = trimesh.Trimesh(V, F, process=False)
        if m.is_winding_consistent and _volume(V, F) > 0:
            return m, "closed", "the shell is watertight"
        return _hull(V, support_z), "hull", "a closed shell with inconsistent or inward faces"
    frac = bnd.sum() / len(np.unique(key))
    if frac > cfg.max_boundary_frac:
        return _hull(V, support_z), "hull", f"{frac:.0%} of the edges are boundary edges"
    B = e[bnd]  # [E, 2] directed boundary edges a -> b as their faces run
    _, lab = connected_components(coo_matrix((np.ones(len(B)), (B[:, 0], B[:, 1])), shape=(len(V), len(V))),
                                       directed=False)
    loop_of_edge = lab[B[:, 0]]
    loops, loop_of_edge = np.unique(loop_of_edge, return_inverse=True)  # only components with edges
    if len(loops) > cfg.max_loops:
        return _hull(V, support_z), "hull", f"{len(loops)} boundary loops (more than {cfg.max_loops})"
    L = len(loops)
    # per loop: centroid of its vertices, the cap's outward area vector, its lowest point
    cnt_v = np.bincount(loop_of_edge, minlength=L)[:, None]
    cen = np.stack([np.bincount(loop_of_edge, weights=V[B[:, 0], i], minlength=L) for i in range(3)], 1) / cnt_v
    a, b = V[B[:, 0]], V[B[:, 1]]
    tri_area = np.cross(b - cen[loop_of_edge], a - cen[loop_of_edge]) / 2  # cap triangle (c, b, a)
    area_vec = np.stack([np.bincount(loop_of_edge, weights=tri_area[:, i], minlength=L) for i in range(3)], 1)
    zlow = np.full(L, np.inf)
    np.minimum.at(zlow, loop_of_edge, np.minimum(a[:, 2], b[:, 2]))
    nz = area_vec[:, 2] / np.maximum(np.linalg.norm(area_vec, axis=1), 1e-30)
    extrude = (zlow - support_z <= cfg.bottom_band) | (nz < -math.cos(math.radians(cfg.bottom_deg)))
    ext_e = extrude[loop_of_edge]  # [E]
    nV = len(V)
    # projected copies of the extruded loops' vertices (an index of its own unless already on the plane)
    ev = np.unique(B[ext_e].reshape(-1))
    on_plane = V[ev, 2] - support_z <= _MERGE
    proj = np.arange(nV)
    new = ev[~on_plane]
    proj[new] = nV + np.arange(len(new))
    Pv = V[new].copy()
    Pv[:, 2] = support_z
    # cap centres: projected for extruded loops, in place for the others
    cap_c = cen.copy()
    cap_c[extrude, 2] = support_z
    ci = nV + len(new) + np.arange(L)
    A, Bb = B[:, 0], B[:, 1]
    Ap, Bp = proj[A], proj[Bb]
    skirt = np.concatenate([np.stack([Bb, A, Ap], 1)[ext_e], np.stack([Bb, Ap, Bp], 1)[ext_e]])
    caps = np.where(ext_e[:, None], np.stack([ci[loop_of_edge], Bp, Ap], 1), np.stack([ci[loop_of_edge], Bb, A], 1))
    Fc = np.concatenate([F, skirt, caps])
    Fc = Fc[(Fc[:, 0] != Fc[:, 1]) & (Fc[:, 1] != Fc[:, 2]) & (Fc[:, 0] != Fc[:, 2])]
    Vc = np.concatenate([V, Pv, cap_c])
    m = trimesh.Trimesh(Vc, Fc, process=False)
    _, _, cnt2 = _edges(Fc)
    hull = _hull(V, support_z)
    why = f"{int(extrude.sum())} loop(s) extruded to the support, {int((~extrude).sum())} capped in place"
    if not np.all(cnt2 == 2) or not m.is_winding_consistent:
        return hull, "hull", "closing left open or inconsistent edges"
    vol = _volume(Vc, Fc)
    if vol < 0:
        m = trimesh.Trimesh(Vc, Fc[:, ::-1], process=False)
        vol = -vol
    hv = _volume(np.asarray(hull.vertices), np.asarray(hull.faces))
    if not (vol > 0 and vol <= hv * (1 + 1e-6)):
        return hull, "hull", f"the closed shell's volume {vol:.3g} m^3 is not within its hull's {hv:.3g}"
    return m, "extrude", why


def _hull(V: np.ndarray, support_z: float) -> trimesh.Trimesh:
    """The convex hull of points [V, 3] and their projections onto z = ``support_z``."""
    P = np.concatenate([V, np.column_stack([V[:, :2], np.full(len(V), support_z)])])
    try:
        h = trimesh.convex.convex_hull(P, qhull_options="QbB Pp Qt")
    except Exception as e:  # qhull: flat input
        raise InputError(f"the shell and its footprint span no volume ({type(e).__name__})") from None
    if not _volume(np.asarray(h.vertices), np.asarray(h.faces)) > 0:
        raise InputError("the shell and its footprint span no volume")
    return h


def _volume(V: np.ndarray, F: np.ndarray) -> float:
    """Signed volume (m^3) enclosed by the triangles F [F, 3] over V [V, 3]."""
    tri = V[F]
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


# ------------------------------------------------------------------------------- the solids


@dataclass(eq=False)
class RigidSolid:
    """One rigid object: its ``shell`` (the faces ``faces`` [K] of the input mesh), the closed
    ``solid`` and how it was made (``method``, ``reason``), the ``support_z`` (m) it stands on,
    mass properties (``volume`` m^3, ``density`` kg/m^3, ``mass`` kg, ``center_mass`` [3] m,
    ``inertia`` [3, 3] kg·m^2 about the centre of mass, world axes), convex collision ``pieces``
    and their ``fidelity`` (:func:`~drawer_lib.complete.static_collision.collision_fidelity`
    against the solid)."""

    id: str
    label: str | None
    faces: np.ndarray
    shell: trimesh.Trimesh
    solid: trimesh.Trimesh
    method: str
    reason: str
    support_z: float
    support_source: str
    volume: float
    density: float
    mass: float
    center_mass: np.ndarray
    inertia: np.ndarray
    pieces: list[Shape] = field(default_factory=list)
    fidelity: dict = field(default_factory=dict)
    wall_s: float = 0.0

    def stats(self) -> dict:
        return {"label": self.label, "n_shell_faces": int(len(self.faces)), "method": self.method,
                "reason": self.reason, "support_z": round(self.support_z, 4), "support_source": self.support_source,
                "volume_m3": self.volume, "density": self.density, "mass_kg": self.mass,
                "center_mass": [round(float(x), 4) for x in self.center_mass], "n_hulls": len(self.pieces),
                "hull_chamfer_l1": self.fidelity.get("chamfer_l1"), "wall_s": round(self.wall_s, 3)}


def top_label(part: Part) -> str | None:
    """The part's most voted label (``extra["labels"]`` {label: votes}), lower case, or None."""
    votes = part.extra.get("labels") or {}
    if not isinstance(votes, dict) or not votes:
        return None
    return str(max(votes.items(), key=lambda kv: kv[1])[0]).lower()


def density_of(label: str | None, cfg: RigidConfig) -> float:
    table = {k.lower(): v for k, v in cfg.density.items()}
    return float(table.get(label, cfg.default_density)) if label is not None else cfg.default_density


def build_rigid(part: Part, mesh: trimesh.Trimesh, cfg: RigidConfig, face_labels: Int[np.ndarray, "F"] | None = None,
                faces: Int[np.ndarray, "K"] | None = None, fidelity: bool = True) -> RigidSolid:
    """The closed solid, mass properties and convex pieces of rigid ``part`` shown by ``mesh``
    (world, m): its faces are ``faces`` when given, else :func:`rigid_faces`. Errors name the
    part."""
    t0 = time.perf_counter()
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError(f"rigid part {part.id}: the mesh has non-finite vertices")
    if faces is None:
        faces = rigid_faces(part, mesh, cfg, face_labels)
    elif len(faces) == 0:
        raise InputError(f"rigid part {part.id}: no mesh faces (an empty segment)")
    V, F = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    shell = submesh(V, F, faces)
    z, src = support_height(mesh, faces, cfg)
    try:
        solid, method, reason = close_shell(shell.vertices, shell.faces, z, cfg)
    except InputError as e:
        raise InputError(f"rigid part {part.id}: {e}") from None
    label = top_label(part)
    rho = density_of(label, cfg)
    mp = trimesh.triangles.mass_properties(solid.triangles, density=rho)
    if not (np.isfinite(mp.volume) and mp.volume > 0):
        raise InputError(f"rigid part {part.id}: its solid has no volume ({mp.volume})")
    if method == "hull" or cfg.max_hulls == 1:
        h = solid if method == "hull" else solid.convex_hull
        pieces = [mesh_shape(h.vertices, h.faces)]
    else:
        try:
            pieces = convex_pieces(solid.vertices, solid.faces, max_hulls=cfg.max_hulls, resolution=cfg.resolution,
                                   max_vertices_per_hull=cfg.max_hull_vertices)
        except ValueError:  # V-HACD found nothing of volume: the solid's hull
            h = solid.convex_hull
            pieces = [mesh_shape(h.vertices, h.faces)]
    fid = {}
    if fidelity:
        from drawer_lib.complete.static_collision import collision_fidelity

        fid = collision_fidelity(pieces, solid, n_points=cfg.fidelity_points)
    return RigidSolid(part.id, label, faces, shell, solid, method, reason, z, src, float(mp.volume), rho,
                      float(mp.mass), np.asarray(mp.center_mass, np.float64), np.asarray(mp.inertia, np.float64),
                      pieces, fid, time.perf_counter() - t0)


def build_rigids(parts: PartsFile, mesh: trimesh.Trimesh, cfg: RigidConfig,
                 face_labels: Int[np.ndarray, "F"] | None = None, fidelity: bool = True) -> list[RigidSolid]:
    """:func:`build_rigid` for every rigid part (in file order); [] when there is none."""
    return [build_rigid(p, mesh, cfg, face_labels, fidelity=fidelity) for p in parts.parts if p.kind == "rigid"]
