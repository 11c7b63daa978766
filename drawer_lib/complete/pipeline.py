"""What the ``complete`` stage does: parts + mesh + capture (+ the SDF, the appearance model)
-> ``complete/`` (:mod:`drawer_lib.complete.io`), the scene cut into bodies:

1. **interiors** (:mod:`~drawer_lib.complete.interiors`): a template per articulated part
   (drawer box, cabinet cavity with shelves, appliance cavity), its depth measured on the mesh
   and fitted jointly; DRAWER's fixed rule built beside it for comparison;
2. **cut** (:mod:`~drawer_lib.complete.cut`): each part's front faces become its body; the static
   remainder loses every face inside a part's swept volume (the cavity it moves through);
3. **rigid objects** (:mod:`~drawer_lib.complete.rigid`): closed solids, mass from a density
   table, convex pieces;
4. **static collision** (:mod:`~drawer_lib.complete.static_collision`): boxes from the SDF's
   occupancy near the visible surface, carved by the sweeps, the cavities and the rigid
   objects (above their support), plus the cavities' walls and shelves and a thin pad under
   each rigid object whose top is its support height;
5. **parts**: visual = the cut faces (+ a drawer's box), collision = the front panel as a box
   (inset by ``collision_clearance``), the handle as a box from its evidence
   (:mod:`~drawer_lib.complete.grasp`; the mesh's protrusion hull when there is none), a
   drawer's box walls; and each part's grasp frame. With metric depth, each handle's standoff
   is measured in it (:mod:`~drawer_lib.complete.standoff`) and recorded with the grasp; the
   box stands there with ``handle.standoff: depth``;
6. **Gaussians**: the appearance model's Gaussians go to the body whose front slab holds their
   anchor face (``static`` otherwise, or a rigid object's when inside its bounds), plus flat
   Gaussians on the interiors' walls coloured from the cabinet, less those a training view
   would see with every part closed (``gaussians.cull_visible``);
7. on synthetic scenes, the interior depth error against the GT mesh, fitted and DRAWER's rule
   side by side, and the collision's fidelity.

What a scene does not need is skipped and written down (no articulated part: no interiors or
cut; no rigid object: no solids; no appearance model: no Gaussians; no metric depth: no
handle standoffs).
"""

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import trimesh

from drawer_lib.articulation.fronts import sample_points
from drawer_lib.complete.config import CompleteConfig
from drawer_lib.complete.cut import body_owner, cut_parts, front_box, is_drawer
from drawer_lib.complete.grasp import grasp_frame, handle_box
from drawer_lib.complete.interiors.drawer_rule import drawer_rule_interiors
from drawer_lib.complete.interiors.evidence import floor_height
from drawer_lib.complete.interiors.fit import build_interiors
from drawer_lib.complete.interiors.texture import interior_colours
from drawer_lib.complete.io import STATIC, write_complete
from drawer_lib.complete.rigid import build_rigids
from drawer_lib.complete.standoff import depth_views, measure_standoffs, standoff_summary
from drawer_lib.complete.static_collision import collision_fidelity, static_collision
from drawer_lib.errors import InputError
from drawer_lib.geometry.boxes import front_frame
from drawer_lib.geometry.camera import Camera
from drawer_lib.io.capture import Capture
from drawer_lib.io.manifest import read_manifest
from drawer_lib.io.mesh import load_mesh
from drawer_lib.io.parts import read_parts
from drawer_lib.paths import LAYOUT, capture_name, stage_name
from drawer_lib.runner import StageRun
from drawer_lib.bodies import PartBody, RigidBody, Shape, TwinModel, box_shape, mesh_shape
from drawer_lib.splat.gaussians import blend_weights, box_surface_gaussians, concat, subset
from drawer_lib.splat.ply import read_gaussian_ply
from drawer_lib.splat.render import Gaussians
from drawer_lib.splat.sh import C0


@dataclass
class CompleteInputs:
    parts: Path  # articulate/parts.json
    mesh: Path  # mesh/mesh.ply
    decompose: Path | None  # decompose/ (perception mesh + face labels: the rigid objects' faces)
    field: Path | None  # sdf/field.pt
    appearance: Path | None  # appearance/<variant>/ (its model/)


def _mesh(m: trimesh.Trimesh) -> list[Shape]:
    return [mesh_shape(np.asarray(m.vertices), np.asarray(m.faces))] if len(m.faces) else []


def _handle_hull(body: trimesh.Trimesh, part, max_proud: float, min_proud: float = 0.005) -> list[Shape]:
    """The convex hull of the body's vertices standing ``min_proud`` to ``max_proud`` in front
    of the front and inside its rectangle (a handle), or nothing when fewer than 8 do. (The body
    also holds faces of the slab's margin: a neighbour's edge, the counter's lip; a handle never
    reaches past its own front.)"""
    v = np.asarray(body.vertices)
    f = part.front
    u, w, n = ((v - np.asarray(f.center)) @ front_frame(f.normal, f.u)).T
    proud = (np.abs(u) <= f.size[0] / 2) & (np.abs(w) <= f.size[1] / 2) & (n > min_proud) & (n <= max_proud)
    if proud.sum() < 8:
        return []
    try:
        h = trimesh.convex.convex_hull(v[proud])
    except Exception:  # coplanar points: no volume, no hull
        return []
    return [mesh_shape(np.asarray(h.vertices), np.asarray(h.faces))] if h.volume > 1e-9 else []


def _no_metric_depth(cap: Capture) -> str | None:
    """None when ``cap`` has metric depth on every frame, else why not."""
    if not cap.has("depth_file_path"):
        return "the capture has no depth maps"
    mf = cap.root / capture_name("manifest")
    if mf.is_file():
        return read_manifest(mf).missing("metric_scale")
    return None


def _dc_colours(g: Gaussians) -> np.ndarray:
    return np.clip(g.sh[:, 0].numpy() * C0 + 0.5, 0, 1)


def run_complete(cfg: CompleteConfig, cap: Capture, inp: CompleteInputs, run: StageRun, density_part: float = 600.0
                 ) -> dict:
    """Build the bodies (see the module doc) and write them into the stage folder."""
    if not inp.parts.is_file():
        raise InputError(f"{inp.parts}: missing (run the articulate stage first)")
    parts = read_parts(inp.parts)
    mesh = load_mesh(inp.mesh, "run the mesh stage first")
    arts = [p for p in parts.parts if p.articulated]
    m: dict = {"n_parts": len(arts), "n_rigid": sum(p.kind == "rigid" for p in parts.parts)}
    times: dict[str, float] = {}

    # 1. interiors
    t0 = time.perf_counter()
    pts, pt_face = sample_points(mesh, np.arange(len(mesh.faces)), cfg.sample_per_m2, seed=run.seed)
    nrm = np.asarray(mesh.face_normals)[pt_face]
    floor_z = floor_height(pts, nrm)
    interiors, fitted, rule = {}, {}, {}
    inter_json: dict[str, dict] = {}
    if arts:
        res = build_interiors(arts, pts, nrm, cfg.interiors, floor_z)
        fitted = {it.part_id: it for it in res.interiors}
        rule = {it.part_id: it for it in drawer_rule_interiors(arts, cfg.interiors, floor_z)}
        interiors = rule if cfg.interiors.method == "drawer_rule" else fitted
        inter_json = {k: it.to_json() for k, it in interiors.items()}
        m["interior_templates"] = {t: sum(it.template == t for it in interiors.values())
                                   for t in sorted({it.template for it in interiors.values()})}
    else:
        run.skip("interiors", "no articulated part")
    times["interiors_s"] = time.perf_counter() - t0

    # 2. cut
    t0 = time.perf_counter()
    depths = {p.id: interiors[p.id].start + interiors[p.id].depth for p in arts
              if is_drawer(p, cfg.cut) and p.id in interiors and interiors[p.id].body == p.id}
    cut = cut_parts(mesh, parts, cfg.cut, depths)
    m["static_faces"] = int(len(cut.static.faces))
    m["cavity_faces"] = int(sum(len(pc.cavity_faces) for pc in cut.parts.values()))
    times["cut_s"] = time.perf_counter() - t0

    # 3. rigid objects (before the static collision: their place is carved out of it)
    t0 = time.perf_counter()
    rigid_bodies, rigid_stats, rigid_carvers, pads = [], {}, [], []
    if m["n_rigid"]:
        rmesh, labels = mesh, None
        if inp.decompose is not None and (inp.decompose / stage_name("decompose", "mesh")).is_file():
            rmesh = load_mesh(inp.decompose / stage_name("decompose", "mesh"))
            labels = np.load(inp.decompose / stage_name("decompose", "face_labels"))["labels"]
        for s in build_rigids(parts, rmesh, cfg.rigid, labels):
            rigid_bodies.append(RigidBody(s.id, _mesh(s.solid), s.pieces, s.density))
            # the object is in the scene mesh and the field too: empty the cells above its support
            # (their centres), and give it a pad whose top is the support height (cells are
            # coarser than the 1 cm it may settle)
            lo, hi = s.solid.bounds
            half_xy = (hi[:2] - lo[:2]) / 2 + 0.01
            z0, z1 = s.support_z - 0.5 * cfg.static.cell + 1e-4, hi[2] + 0.01
            rigid_carvers.append(box_shape([*((lo[:2] + hi[:2]) / 2), (z0 + z1) / 2], [*half_xy, (z1 - z0) / 2]))
            pads.append(box_shape([*((lo[:2] + hi[:2]) / 2), s.support_z - 0.005], [*(half_xy + 0.01), 0.005]))
            rigid_stats[s.id] = {"method": s.method, "volume_l": 1000 * s.volume, "mass_kg": s.mass,
                                 "hulls": len(s.pieces)}
    else:
        run.skip("rigid", "no rigid object")
    times["rigid_s"] = time.perf_counter() - t0

    # 4. static collision
    t0 = time.perf_counter()
    field = None
    if cfg.static.source == "field":
        if inp.field is None or not inp.field.is_file():
            raise InputError(f"{inp.field}: missing (complete.static.source = field needs the sdf stage's field; "
                             "set complete.static.source: mesh for a mesh-only collision)")
        from drawer_lib.sdf.io import load_field

        field = load_field(inp.field)
    static_cavities = [it for it in interiors.values() if it.body == STATIC]
    carvers = [pc.sweep for pc in cut.parts.values()] + [it.outer for it in static_cavities]
    # a drawer's box walls (the interior template) are not its cut solid: their travel is
    # emptied too, exactly (not grown)
    wall_sweeps = [w.box.translated_hull(p.axis.direction, *p.limits) for p in arts
                   if p.kind == "prismatic" and (it := interiors.get(p.id)) is not None and it.body == p.id
                   for w in it.walls]
    sc = static_collision(cut.static, cfg.static, field, carvers, rigid_carvers + wall_sweeps)
    cavity_walls = [w for it in static_cavities for w in it.walls] + pads
    times["static_collision_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fid = collision_fidelity(sc.shapes, cut.static, cfg.static.fidelity_points)
    m.update({"n_static_boxes": len(sc.shapes), "n_cavity_walls": len(cavity_walls),
              "collision_chamfer_l1": fid["chamfer_l1"], "collision_fscore_2cm": fid.get("fscore_2cm")})
    times["fidelity_s"] = time.perf_counter() - t0

    # 5. parts; the handles' standoffs in the capture's metric depth (drawer_lib/complete/standoff.py)
    t0 = time.perf_counter()
    standoffs: dict[str, dict] = {}
    why = _no_metric_depth(cap)
    if why is None and any(p.extra.get("handle") for p in arts):
        pick = np.unique(np.linspace(0, len(cap.train) - 1, min(len(cap.train), cfg.handle.max_views)).round())
        frames = [cap.train[int(k)] for k in pick]  # at most max_views train views, evenly spaced
        standoffs = measure_standoffs(arts, depth_views(cap, run.progress(frames, desc="handle standoffs")),
                                      cfg.handle.min_points)
        m |= standoff_summary(standoffs)
    else:
        run.skip("handle_standoff", why or "no part has handle evidence")
    times["standoff_s"] = time.perf_counter() - t0
    bodies = []
    grasps: dict[str, dict] = {}
    n_handle = 0
    for p in arts:
        pc = cut.parts[p.id]
        it = interiors.get(p.id)
        moving_walls = list(it.walls) if it is not None and it.body == p.id else []
        # behind the outer face, one panel thick, inset by the clearance: reconstructed fronts
        # abut (shared edges) and must not touch their neighbours at q = 0
        panel = front_box(p.front, -cfg.cut.panel_thickness, 0.0, cfg.collision_clearance)
        grip = handle_box(p, cfg.handle, standoffs.get(p.id))
        handle = [grip] if grip is not None else _handle_hull(pc.body, p, cfg.cut.protrusion)
        grasps[p.id] = grasp_frame(p, cfg.handle)
        if p.id in standoffs:
            grasps[p.id]["standoff"] = standoffs[p.id]
        n_handle += grip is not None
        collision = [Shape("box", box=panel)] + handle + moving_walls
        bodies.append(PartBody(p.id, p.kind, np.asarray(p.axis.origin), np.asarray(p.axis.direction), p.limits,
                               _mesh(pc.body) + moving_walls, collision, density_part))

    m["n_handle_boxes"] = n_handle
    m["n_grasp_free_edge"] = sum(g["kind"] == "free_edge" for g in grasps.values())
    model = TwinModel(_mesh(cut.static) + cavity_walls, sc.shapes + cavity_walls, bodies, rigid_bodies).validate()

    # 6. Gaussians
    t0 = time.perf_counter()
    gauss: dict[str, Gaussians] = {}
    if inp.appearance is not None and (inp.appearance / LAYOUT["appearance"]["gaussians"]).is_file():
        gauss, interior = _body_gaussians(cfg, inp.appearance, arts, cut_cfg=cfg.cut, rigid=rigid_bodies,
                                          interiors=interiors)
        if cfg.gaussians.cull_visible is not None and any(v.any() for v in interior.values()):
            gauss, n_cull = cull_visible_interiors(gauss, interior, cap.cameras(cap.train),
                                                    cfg.gaussians.cull_visible, run.progress)
            m["n_interior_gaussians_culled"] = n_cull
        m["n_gaussians"] = {k: int(len(v.means)) for k, v in gauss.items()}
        m["n_interior_gaussians"] = int(sum(v.sum() for v in interior.values())) - m.get("n_interior_gaussians_culled", 0)
    else:
        run.skip("gaussians", f"no appearance model at {inp.appearance} (run appearance@<scene>-{cfg.gaussians.variant})")
    times["gaussians_s"] = time.perf_counter() - t0

    # 7. interiors against GT
    gt_mesh = cap.root / capture_name("gt_mesh")
    if arts and gt_mesh.is_file():
        from drawer_lib.metrics.interiors import interior_depth_error, summarise_depth_errors

        inst = cap.root / capture_name("gt_mesh_instances")
        rows = interior_depth_error(parts, load_mesh(gt_mesh), read_parts(cap.root / capture_name("gt_parts")),
                                    {k: (x.template, x.free_depth) for k, x in fitted.items()},
                                    {k: x.free_depth for k, x in rule.items()}, np.load(inst) if inst.is_file() else None)
        s = summarise_depth_errors(rows)
        m.update({"interior_depth_error": s.get("fitted_mean"), "interior_depth_error_max": s.get("fitted_max"),
                  "interior_depth_error_drawer_rule": s.get("rule_mean"),
                  "interior_depth_error_drawer_rule_max": s.get("rule_max"), "n_interiors_scored": s.get("n")})
        for k, r in rows.items():
            inter_json.setdefault(k, {})["gt"] = {x: r[x] for x in ("gt", "gt_depth", "fitted_error", "rule_error", "gt_solid")}
    else:
        run.skip("interior_depth_error", "no GT mesh" if arts else "no articulated part")
    m.update({k: round(v, 3) for k, v in times.items()})
    info = {"rigid": rigid_stats, "collision_fidelity": fid, "static_collision": sc.stats, "cut": cut.stats(),
            "floor_z": floor_z}
    write_complete(run.dir, model, gauss, inter_json, info, grasps)
    return m


def cull_visible_interiors(gauss: dict[str, Gaussians], interior: dict[str, np.ndarray], cams: list[Camera],
                           max_weight: float, progress: Callable = lambda it, **kw: it
                           ) -> tuple[dict[str, Gaussians], int]:
    """Drop the interior Gaussians (``interior[body]``: bool mask over ``gauss[body]``) whose
    blend weight (:func:`~drawer_lib.twin.gaussians.blend_weights`, pixels) in the closed scene
    (every body as given) exceeds ``max_weight`` in any of ``cams``. Returns the kept bodies and
    the number dropped."""
    names = list(gauss)
    allg = concat([gauss[k] for k in names])
    w = torch.zeros(len(allg.means), dtype=allg.means.dtype)
    for cam in progress(cams, desc="interior visibility", total=len(cams)):
        w = torch.maximum(w, blend_weights(allg, cam))
    out, n, start = {}, 0, 0
    for k in names:
        g = gauss[k]
        wk = w[start:start + len(g.means)].numpy()
        start += len(g.means)
        drop = interior.get(k, np.zeros(len(g.means), bool)) & (wk > max_weight)
        n += int(drop.sum())
        out[k] = subset(g, torch.from_numpy(np.nonzero(~drop)[0])) if drop.any() else g
    return out, n


def _body_gaussians(cfg: CompleteConfig, variant_dir: Path, arts, cut_cfg, rigid, interiors
                    ) -> tuple[dict[str, Gaussians], dict[str, np.ndarray]]:
    """Split the appearance model's Gaussians (``variant_dir``: ``appearance/<variant>/``) by body
    and add the interiors' (module doc, 6). Returns the bodies' Gaussians and, per body, which
    of them are interior ones."""
    g = read_gaussian_ply(variant_dir / LAYOUT["appearance"]["gaussians"])
    binding = np.load(variant_dir / LAYOUT["appearance"]["binding"])
    anchor = trimesh.load(variant_dir / LAYOUT["appearance"]["anchor_mesh"], process=False, force="mesh")
    face = binding["mesh_face"]
    if len(face) != len(g.means) or face.max(initial=-1) >= len(anchor.faces):
        raise InputError(f"{variant_dir / LAYOUT['appearance']['binding']}: does not match "
                         f"{LAYOUT['appearance']['gaussians']} / {LAYOUT['appearance']['anchor_mesh']}")
    owner_face = body_owner(np.asarray(anchor.triangles_center), list(arts), cut_cfg)
    owner = owner_face[face]
    names = [STATIC] + [p.id for p in arts]
    out = {name: subset(g, torch.from_numpy(np.nonzero(owner == k - 1)[0])) for k, name in enumerate(names)}
    for r in rigid:  # a rigid object's Gaussians: the static ones inside its solid's bounds
        lo, hi = (np.min([s.triangles()[0].min(0) for s in r.visual], 0) - 0.01,
                  np.max([s.triangles()[0].max(0) for s in r.visual], 0) + 0.01) if r.visual else (None, None)
        if lo is None:
            continue
        st = out[STATIC]
        sm = st.means.numpy()
        inside = np.all((sm >= lo) & (sm <= hi), 1)
        out[r.id] = subset(st, torch.from_numpy(np.nonzero(inside)[0]))
        out[STATIC] = subset(st, torch.from_numpy(np.nonzero(~inside)[0]))
    k = g.sh.shape[1]
    degree = int(round(np.sqrt(k))) - 1
    gc = cfg.gaussians
    interior = {k: np.zeros(len(v.means), bool) for k, v in out.items()}
    for pid, it in interiors.items():
        mine = out.get(pid)
        front_rgb = _dc_colours(mine) if mine is not None and len(mine.means) else np.full((1, 3), 0.5)
        tex = interior_colours(it, front_rgb, cfg.interiors.texture)
        walls = [box_surface_gaussians(w.box, np.asarray(tex.base.get(name, np.mean(front_rgb, 0))),
                                       gc.spacing, gc.opacity, degree, toward=np.asarray(it.free.center))
                 for w, name in zip(it.walls, it.wall_names)]
        if walls:
            w = concat(walls)
            # an interior is behind its closed front: keep what lies inside the front's rectangle
            # (3 mm in from its edges) and behind its panel, so nothing shows through gaps or
            # around the carcass while the part is closed
            part = next(p for p in arts if p.id == pid)
            f = part.front
            u, v, n = ((w.means.double().numpy() - np.asarray(f.center)) @ front_frame(f.normal, f.u)).T
            keep = (np.abs(u) < f.size[0] / 2 - 0.003) & (np.abs(v) < f.size[1] / 2 - 0.003) & (n < -cut_cfg.panel_thickness)
            out[it.body] = concat([out[it.body], subset(w, torch.from_numpy(np.nonzero(keep)[0]))])
            interior[it.body] = np.concatenate([interior[it.body], np.ones(int(keep.sum()), bool)])
    return out, interior
