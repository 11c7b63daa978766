"""Ground truth of a procedural kitchen: parts file, closed scene mesh, per-face instance ids."""

from pathlib import Path

import numpy as np
import trimesh

from drawer_lib.io.parts import Axis, IgnoreBox, Part, PartsFile, write_parts
from drawer_lib.paths import capture_name
from drawer_lib.synth.layout import KitchenLayout
from drawer_lib.synth.meshes import concat

IGNORE_MARGIN = 0.02  # ignore boxes extend this far beyond a fixed front's geometry (m)


def layout_parts(layout: KitchenLayout) -> PartsFile:
    """The ``drawer.parts/1`` ground truth: articulated fronts, rigid objects, ignore boxes."""
    parts, ignore = [], []
    for e in layout.parts():
        if e.articulated:
            parts.append(Part(
                id=e.name,
                kind="revolute" if e.joint == "hinge" else "prismatic",
                axis=Axis(tuple(map(float, e.axis_origin)), tuple(map(float, e.axis_dir))),
                limits=(float(e.limits[0]), float(e.limits[1])),
                front=e.front,
                instance_id=e.instance_id,
                extra={"family": e.family},
            ))
        elif e.joint == "free":
            lo, hi = e.mesh().bounds
            parts.append(Part(
                id=e.name, kind="rigid", center=tuple(map(float, (lo + hi) / 2)),
                bounds=(tuple(map(float, lo)), tuple(map(float, hi))), instance_id=e.instance_id,
                extra={"family": e.label},
            ))
        else:  # fixed front that looks articulated
            lo, hi = e.mesh().bounds
            ignore.append(IgnoreBox(
                e.name, (tuple(map(float, lo - IGNORE_MARGIN)), tuple(map(float, hi + IGNORE_MARGIN))),
                e.front, e.instance_id,
            ))
    return PartsFile(tuple(parts), tuple(ignore))


def layout_mesh(layout: KitchenLayout) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The closed scene surface (all joints at 0) in world coordinates and the instance id of
    every face ([F] int, 0 = static scene). Pieces are kept as separate closed shells
    (no boolean union), exactly the triangles the renderer draws."""
    meshes, inst = [], []
    for e in layout.entities:
        m = e.mesh()
        meshes.append(m)
        inst.append(np.full(len(m.faces), e.instance_id, np.int32))
    m = concat(meshes)
    tm = trimesh.Trimesh(m.verts, m.faces, process=False)
    return tm, np.concatenate(inst)


def write_gt(layout: KitchenLayout, gt_dir: Path) -> tuple[PartsFile, trimesh.Trimesh, np.ndarray]:
    """Write ``gt/parts.json``, ``gt/mesh.ply`` and ``gt/mesh_instances.npy`` (per-face ids) into
    ``gt_dir`` (the capture's ``gt/``)."""
    gt_dir.mkdir(parents=True, exist_ok=True)
    parts = layout_parts(layout)
    write_parts(gt_dir.parent / capture_name("gt_parts"), parts)
    mesh, face_inst = layout_mesh(layout)
    mesh.export(gt_dir.parent / capture_name("gt_mesh"))
    np.save(gt_dir.parent / capture_name("gt_mesh_instances"), face_inst.astype(np.int32))
    return parts, mesh, face_inst
