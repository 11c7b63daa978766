"""Mesh clean-up with PyMeshLab: small components, quadric simplification, isotropic remeshing."""

from dataclasses import dataclass

import numpy as np
import trimesh

from drawer_lib.errors import ConfigError


@dataclass(frozen=True)
class CleanConfig:
    """``min_component_diag``: drop connected components whose bounding-box diagonal is below this
    (metres; 0 keeps all); ``target_faces``: quadric edge-collapse simplification to this many
    faces (0 = no simplification; meshes already smaller are left alone); ``remesh_iters`` > 0
    runs isotropic explicit remeshing with edge length ``remesh_edge`` (metres) afterwards."""

    min_component_diag: float = 0.05
    target_faces: int = 200_000
    remesh_iters: int = 0
    remesh_edge: float = 0.01

    def __post_init__(self):
        if self.min_component_diag < 0 or self.target_faces < 0 or self.remesh_iters < 0 or self.remesh_edge <= 0:
            raise ConfigError("mesh.clean: min_component_diag, target_faces, remesh_iters >= 0 and remesh_edge > 0")


def clean_mesh(mesh: trimesh.Trimesh, cfg: CleanConfig) -> tuple[trimesh.Trimesh, dict[str, int]]:
    """Cleaned copy of ``mesh`` and face counts after each step (keys ``faces_in``,
    ``faces_components``, ``faces_simplified``, ``faces_out``)."""
    import pymeshlab

    counts = {"faces_in": len(mesh.faces)}
    if len(mesh.faces) == 0:
        return mesh.copy(), counts | {"faces_components": 0, "faces_simplified": 0, "faces_out": 0}
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(mesh.vertices, np.float64),
                               face_matrix=np.asarray(mesh.faces, np.int32)))
    ms.meshing_remove_duplicate_vertices()
    ms.meshing_remove_null_faces()
    if cfg.min_component_diag > 0:
        ms.meshing_remove_connected_component_by_diameter(
            mincomponentdiag=pymeshlab.PureValue(cfg.min_component_diag), removeunref=True)
    counts["faces_components"] = ms.current_mesh().face_number()
    if 0 < cfg.target_faces < ms.current_mesh().face_number():
        ms.meshing_decimation_quadric_edge_collapse(targetfacenum=cfg.target_faces, preservenormal=True,
                                                    preservetopology=False, optimalplacement=True, autoclean=True)
    counts["faces_simplified"] = ms.current_mesh().face_number()
    if cfg.remesh_iters > 0 and ms.current_mesh().face_number() > 0:
        ms.meshing_isotropic_explicit_remeshing(iterations=cfg.remesh_iters,
                                                targetlen=pymeshlab.PureValue(cfg.remesh_edge))
    ms.meshing_remove_unreferenced_vertices()
    m = ms.current_mesh()
    out = trimesh.Trimesh(m.vertex_matrix().copy(), m.face_matrix().astype(np.int64), process=False)
    counts["faces_out"] = len(out.faces)
    return out, counts
