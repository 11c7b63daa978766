"""The ``complete/`` folder (format ``drawer.complete/1``): the scene cut into bodies, what the
``twin`` stage turns into MJCF / URDF / USD and per-body Gaussians.

    complete/
      complete.json          {"schema", "bodies": [body], "info": {...}}
      meshes/<body>.ply      the body's visual mesh (world frame, q = 0)
      collision/<body>.<k>.ply  convex collision meshes (boxes are inline in complete.json)
      gaussians/<body>.ply   the body's Gaussians (INRIA layout, world frame, q = 0)

A body: ``{"id", "kind": static | revolute | prismatic | rigid, "visual": [file], "collision":
[shape], "density", "gaussians": file | null, "axis": {"origin", "direction"}, "limits",
"interior": {...}}`` (axis and limits for parts only); a shape is ``{"kind": "box", "center",
"rotation" (3x3, columns = box axes), "half"}`` or ``{"kind": "mesh", "file"}``. All lengths
in metres, world frame of the capture.
"""

import json
from pathlib import Path

import numpy as np
import trimesh

from drawer_lib.errors import InputError
from drawer_lib.paths import stage_name
from drawer_lib.bodies import PartBody, RigidBody, Shape, TwinModel, box_shape, mesh_shape
from drawer_lib.splat.ply import write_gaussian_ply
from drawer_lib.splat.render import Gaussians

SCHEMA = "drawer.complete/1"
STATIC = "static"


def _shape_json(s: Shape, folder: Path, stem: str) -> dict:
    if s.kind == "box":
        return {"kind": "box", **s.box.to_json()}
    rel = f"{stage_name('complete', 'collision')}/{stem}.ply"
    trimesh.Trimesh(s.vertices, s.faces, process=False).export(folder / rel)
    return {"kind": "mesh", "file": rel}


def _mesh_file(shapes: list[Shape], folder: Path, body: str) -> list[str]:
    meshes = [trimesh.Trimesh(*s.triangles(), process=False) for s in shapes]
    if not meshes:
        return []
    rel = f"{stage_name('complete', 'meshes')}/{body}.ply"
    trimesh.util.concatenate(meshes).export(folder / rel)
    return [rel]


def write_complete(folder: Path, model: TwinModel, gaussians: dict[str, Gaussians], interiors: dict[str, dict],
                   info: dict, grasps: dict[str, dict] | None = None) -> Path:
    """Write ``model`` (static scene, parts, rigid objects), each body's Gaussians (keyed by body
    id, ``static`` for the scene), each part's interior record and grasp frame
    (:func:`~drawer_lib.complete.grasp.grasp_frame`) into ``folder`` (which must exist and be
    empty: the stage runner renames it into place)."""
    folder = Path(folder)
    for sub in ("meshes", "collision", "gaussians"):
        (folder / stage_name("complete", sub)).mkdir()
    bodies = []

    def body(bid: str, kind: str, visual, collision, density, extra: dict) -> dict:
        g = gaussians.get(bid)
        gfile = None
        if g is not None and len(g.means):
            gfile = f"{stage_name('complete', 'gaussians')}/{bid}.ply"
            write_gaussian_ply(folder / gfile, g)
        return {"id": bid, "kind": kind, "visual": _mesh_file(visual, folder, bid),
                "collision": [_shape_json(s, folder, f"{bid}.{k}") for k, s in enumerate(collision)],
                "density": density, "gaussians": gfile, **extra}

    bodies.append(body(STATIC, "static", model.static_visual, model.static_collision, None, {}))
    for p in model.parts:
        bodies.append(body(p.id, p.kind, p.visual, p.collision, p.density,
                           {"axis": {"origin": np.asarray(p.axis_origin).tolist(),
                                     "direction": np.asarray(p.axis_direction).tolist()},
                            "limits": list(map(float, p.limits)), "interior": interiors.get(p.id, {}),
                            "grasp": (grasps or {}).get(p.id)}))
    for r in model.rigid:
        bodies.append(body(r.id, "rigid", r.visual, r.collision, r.density, {}))
    index = folder / stage_name("complete", "index")
    index.write_text(json.dumps({"schema": SCHEMA, "bodies": bodies, "info": info}, indent=1))
    return index


def _read_shape(d: dict, folder: Path, what: str) -> Shape:
    if d.get("kind") == "box":
        return box_shape(d["center"], d["half"], np.asarray(d["rotation"], np.float64))
    if d.get("kind") == "mesh":
        m = trimesh.load(folder / d["file"], process=False, force="mesh")
        return mesh_shape(np.asarray(m.vertices), np.asarray(m.faces))
    raise InputError(f"{what}: unknown shape kind {d.get('kind')!r}")


def _read_visual(files: list[str], folder: Path) -> list[Shape]:
    out = []
    for f in files:
        m = trimesh.load(folder / f, process=False, force="mesh")
        out.append(mesh_shape(np.asarray(m.vertices), np.asarray(m.faces)))
    return out


def read_complete(folder: Path) -> tuple[TwinModel, dict[str, Path], dict]:
    """(the model, {body id: its Gaussians' PLY}, the raw complete.json) of a ``complete/``."""
    folder = Path(folder)
    path = folder / stage_name("complete", "index")
    if not path.is_file():
        raise InputError(f"{path}: missing (run the complete stage first)")
    d = json.loads(path.read_text())
    if d.get("schema") != SCHEMA:
        raise InputError(f"{path}: schema {d.get('schema')!r}, expected {SCHEMA!r}")
    static_visual, static_collision, parts, rigid = [], [], [], []
    gauss = {}
    for b in d["bodies"]:
        what = f"{path}: body {b.get('id')!r}"
        vis = _read_visual(b["visual"], folder)
        col = [_read_shape(s, folder, what) for s in b["collision"]]
        if b.get("gaussians"):
            gauss[b["id"]] = folder / b["gaussians"]
        if b["kind"] == "static":
            static_visual, static_collision = vis, col
        elif b["kind"] in ("revolute", "prismatic"):
            parts.append(PartBody(b["id"], b["kind"], np.asarray(b["axis"]["origin"], np.float64),
                                        np.asarray(b["axis"]["direction"], np.float64), tuple(b["limits"]), vis, col,
                                        float(b["density"])))
        elif b["kind"] == "rigid":
            rigid.append(RigidBody(b["id"], vis, col, float(b["density"])))
        else:
            raise InputError(f"{what}: unknown kind {b['kind']!r}")
    return TwinModel(static_visual, static_collision, parts, rigid), gauss, d
