"""The built-in estimator: segments + mesh -> parts (``drawer.parts/1``), without learned models.

Per planar, vertical segment a front rectangle (:mod:`~drawer_lib.articulation.fronts`), then
for all fronts together their handles (:mod:`~drawer_lib.articulation.handles`), sliding pairs,
the type of each (:mod:`~drawer_lib.articulation.decide`) and its joint
(:mod:`~drawer_lib.articulation.joints`). Non-planar segments become ``rigid`` parts (centre and
axis-aligned bounds).
"""

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import trimesh

from drawer_lib.articulation.config import ArticulateConfig, FalseFrontsConfig
from drawer_lib.articulation.decide import decide_by_handle, decide_by_score, half_handle, pair_of_doors
from drawer_lib.articulation.fronts import (
    abutting_edges,
    coplanar_iou,
    cut_u,
    edge_moves,
    fit_front,
    plumb,
    refine_with_masks,
    sample_points,
    share_edges,
    share_inside,
)
from drawer_lib.articulation.handles import colour_handle, front_handles
from drawer_lib.articulation.interaction import Obstacles, blocked_hypotheses, front_coords, interaction_evidence
from drawer_lib.articulation.joints import make_part, slide_side, sliding_partners
from drawer_lib.articulation.probes import carcass_depth, flush_sides, rail_extent, rail_extents_moved, rail_run
from drawer_lib.articulation.gaps import border_lines, depth_step_cuts, extent_step_cuts, split_front
from drawer_lib.articulation.rectify import View, rectify_front, rectify_fronts, window_contrast
from drawer_lib.articulation.scoring import Evidence
from drawer_lib.articulation.vocab import Decision, Handle
from drawer_lib.geometry.frames import UP
from drawer_lib.io.parts import Front, Part
from drawer_lib.perception.decompose import Segment


def rigid_part(seg: Segment, mesh: trimesh.Trimesh, k: int) -> Part:
    V = np.asarray(mesh.vertices)[np.unique(np.asarray(mesh.faces)[seg.faces])]
    lo, hi = V.min(0), V.max(0)
    return Part(f"object_{k}", "rigid", center=tuple(((lo + hi) / 2).tolist()),
                bounds=(tuple(lo.tolist()), tuple(hi.tolist())), extra={"segment": seg.id, "labels": seg.labels})


def segment_fronts(mesh: trimesh.Trimesh, segs: list[Segment], cam_centers: np.ndarray, cfg: ArticulateConfig,
                   masks_of: Callable | None, parts: list[Part], report: list[dict],
                   views: list[View] | None = None) -> list[tuple[Segment, Front, dict]]:
    """The front of every planar, vertical segment of a plausible size (shared edges applied);
    non-planar segments are appended to ``parts`` as rigid parts, and every segment that gives
    no front to ``report`` with the reason. With ``cfg.split.enabled`` and ``views`` with
    images, a segment's rectangle is first cut at the gap lines of its rectified image
    (:func:`~drawer_lib.articulation.gaps.split_front`): a segment over several fronts (masks
    merged in most views) gives each of them, its info ``piece`` k ``of`` n. Then, from the mesh
    alone, each rectangle is cut where the surface steps by a sliding track's offset
    (``cfg.split.depth_steps``) and where the segment's outline steps (``extent_steps``), the
    evidence in the info's ``mesh_cuts``. A cut made or left by a margin another machine's last
    bits could cross (a gap line one cell of the rectified front from its coverage bound, a
    width one cell from ``max_width``, a depth or outline step within
    :data:`~drawer_lib.articulation.gaps.STEP_BAND` of its bounds) is listed in ``near_cuts``,
    and the segment's fronts are marked ``low_margin``; with ``cfg.types.near_segment`` so are those
    of a segment decompose selected by such a margin (its ``near`` rows, copied to the info's
    ``near_segment`` either way). A planar segment whose label votes are mostly no front
    label (:meth:`~drawer_lib.articulation.config.TypesConfig.object_share`) is a rigid part.
    Last, coplanar neighbours share their edges (:func:`~drawer_lib.articulation.fronts.share_edges`,
    on each front's own face centres); a side that moved in by more than half of
    ``shared_edge_gap`` (two rectangles that ran into each other) is in the info's ``cut_back``."""
    fc = cfg.fronts
    sin_v = np.sin(np.deg2rad(fc.vertical_deg))
    fits: list[tuple[Segment, Front, dict]] = []
    centres = np.asarray(mesh.triangles_center)
    owner = np.full(len(centres), -1, np.int64)  # the segment of each face
    for s in segs:
        owner[s.faces] = s.id
    for s in segs:
        obj = cfg.types.object_share(s.labels) if cfg.types.use_labels else 0.0
        if not s.planar or obj > 0.5:
            parts.append(rigid_part(s, mesh, sum(p.kind == "rigid" for p in parts)))
            report.append({"segment": s.id, "family": "rigid", "reason": "not planar" if not s.planar else
                           f"labelled an object by {obj:.0%} of its label votes ({', '.join(sorted(s.labels))})"})
            continue
        fitted = fit_front(mesh, s, cam_centers, fc)
        if fitted is None:
            report.append({"segment": s.id, "family": "none", "reason": "degenerate plane"})
            continue
        if abs(np.dot(fitted.normal, UP)) > sin_v:
            report.append({"segment": s.id, "family": "none", "reason": "not vertical"})
            continue
        front, used = fitted, 0
        if masks_of is not None:
            front, used = refine_with_masks(fitted, masks_of(s), fc)
        pieces, even = [front], []  # even: the parts of it cut into equal pieces (split.wide_even)
        near_cuts: list[dict] = []  # cuts made or not by a margin another machine's last bits could undo
        if cfg.split.enabled and cfg.rectify.enabled and views and any(v.image is not None for v in views):
            stems = {st for st, _ in s.matched}
            rf = rectify_front(front, views, cfg.rectify, np.array([v.stem in stems for v in views]))
            pieces = split_front(front, rf, cfg.split, cfg.rectify.min_rate, cfg.rectify.min_views, log=even,
                                 near=near_cuts)
        cuts: list[dict] = []  # the evidence of the mesh's cuts
        if cfg.split.depth_steps or cfg.split.extent_steps:
            pts, _ = sample_points(mesh, s.faces, fc.sample_per_m2, seed=0, local=fc.sampling == "local")
            if cfg.split.depth_steps:
                pieces = [q for p in pieces for q in depth_step_cuts(p, pts, tuple(cfg.joints.sliding_step),
                                                                       cfg.split.min_piece, cfg.split.depth_bin, log=cuts,
                                                                       near=near_cuts)]
            if cfg.split.extent_steps:
                pieces = [q for p in pieces for q in extent_step_cuts(p, pts, centres, owner, s.id, cfg.split.extent_min_step,
                                                                        cfg.split.min_piece, cfg.split.depth_bin, log=cuts,
                                                                        near=near_cuts)]
        wide = cfg.split.enabled and 0 < cfg.split.max_width < front.size[0]  # cut by articulate.split.max_width
        too_wide = {"too_wide": round(float(front.size[0]), 4)} if wide else {}
        for k, piece in enumerate(pieces):
            w, h = piece.size
            if min(w, h) < fc.min_size or max(w, h) > fc.max_size:
                report.append({"segment": s.id, "family": "none", "reason": f"size {w:.2f} x {h:.2f} m out of range"})
                continue
            info = ({"rect_from_masks": used} | ({"piece": k, "of": len(pieces)} if len(pieces) > 1 else {})
                    | ({"mesh_cuts": cuts} if cuts else {}) | ({"near_cuts": near_cuts} if near_cuts else {})
                    | too_wide | ({"even_pieces": even} if even else {}) | ({"near_segment": s.near} if s.near else {}))
            fits.append((s, piece, info))
    fits = drop_duplicate_pieces(fits, cfg.split.duplicate_iou, report)
    plane_tol = 0.75 * cfg.joints.sliding_step[0]  # coplanar: closer than the nearest sliding track
    if fc.repeat_inside > 0:
        fits = drop_fronts_inside(fits, fc.repeat_inside, plane_tol, fc.shared_edge_angle_deg, report)
    fronts = share_edges([f for _, f, _ in fits], fc.shared_edge_gap, plane_tol=plane_tol,
                         min_overlap=fc.shared_edge_overlap, max_angle_deg=fc.shared_edge_angle_deg,
                         max_cross=fc.shared_edge_cross, pct=fc.extent_percentile,
                         points=[piece_points(centres[s.faces], f, "piece" in info) for s, f, info in fits])
    out = []
    for (s, before, info), f in zip(fits, fronts):
        cut = {side: round(m, 4) for side, m in edge_moves(before, f).items() if m > fc.shared_edge_gap / 2}
        out.append((s, f, info | ({"cut_back": cut} if cut else {})))
    return out


def piece_points(points: np.ndarray, front: Front, piece: bool) -> np.ndarray:
    """A front's own points [P', 3] of its segment's ``points`` [P, 3]: all of them for a whole
    segment; for a ``piece`` of a cut segment those over its rectangle, so that the step between
    two pieces of one segment (:func:`~drawer_lib.articulation.joints.sliding_partners`) is
    measured on each one's own surface, not twice on the same points."""
    if not piece:
        return points
    fc = front_coords(front, points)
    return points[(np.abs(fc[:, 0]) <= front.size[0] / 2) & (np.abs(fc[:, 1]) <= front.size[1] / 2)]


def drop_duplicate_pieces(fits: list[tuple[Segment, Front, dict]], min_iou: float, report: list[dict]
                          ) -> list[tuple[Segment, Front, dict]]:
    """``fits`` without the pieces of cut segments that repeat a front already there: a merged
    segment's rectangle may span fronts the detector also saw on their own, which are segments
    of their own. A piece goes when its rectangle overlaps (:func:`coplanar_iou` >= ``min_iou``)
    the front of a segment that was not cut, or a piece kept before it (pieces of better
    supported segments first); ``report`` says which."""
    kept = [f for s, f, info in fits if "piece" not in info]
    drop = set()
    pieces = sorted((i for i, (_, _, info) in enumerate(fits) if "piece" in info), key=lambda i: -fits[i][0].support)
    for i in pieces:
        s, f, info = fits[i]
        if any(coplanar_iou(f, g) >= min_iou for g in kept):
            drop.add(i)
            report.append({"segment": s.id, "family": "none", "reason": f"piece {info['piece']} of {info['of']} "
                           "repeats a front another segment gives", "piece": info["piece"], "of": info["of"]})
        else:
            kept.append(f)
    return [x for i, x in enumerate(fits) if i not in drop]


def drop_fronts_inside(fits: list[tuple[Segment, Front, dict]], min_share: float, plane_tol: float,
                       max_angle_deg: float, report: list[dict]) -> list[tuple[Segment, Front, dict]]:
    """``fits`` without the fronts that lie inside a larger coplanar front: a rectangle with at
    least ``min_share`` of its area inside another's (:func:`share_inside`; planes within
    ``plane_tol`` m and ``max_angle_deg``, so a sliding panel on the other track is never one)
    is that front found a second time, from masks that covered part of it (a highlight, a
    half-seen edge). Two fronts cannot fill one place, so the smaller goes; larger fronts are
    kept first, and ``report`` gives each dropped one's share inside (the decision's margin is
    its distance to ``min_share``) and, for a piece of a cut segment, which piece it was."""
    order = sorted(range(len(fits)), key=lambda i: -float(np.prod(fits[i][1].size)))
    kept: list[int] = []
    for i in order:
        s, f, info = fits[i]
        shares = [(share_inside(fits[j][1], f, plane_tol, max_angle_deg), j) for j in kept]
        share, j = max(shares, default=(0.0, -1))
        if share >= min_share:
            report.append({"segment": s.id, "family": "none", "reason": f"lies {share:.0%} inside the front of segment "
                           f"{fits[j][0].id}: that front found again", "inside": round(share, 4),
                           "repeats": fits[j][0].id} | {k: info[k] for k in ("piece", "of") if k in info})
        else:
            kept.append(i)
    keep = set(kept)
    return [x for i, x in enumerate(fits) if i in keep]


def infer_parts(mesh: trimesh.Trimesh, segs: list[Segment], cam_centers: np.ndarray, cfg: ArticulateConfig,
                handle_hits: np.ndarray | None = None, masks_of: Callable | None = None,
                face_views: np.ndarray | None = None, weights: dict[str, dict[str, float]] | None = None,
                views: list[View] | None = None) -> tuple[list[Part], list[dict]]:
    """(parts, per-segment decisions for the report). ``cam_centers`` [C, 3]: the train cameras
    (a front's normal points toward them); ``handle_hits`` [F]: in how many views a "handle"
    mask covers each face; ``face_views`` [F]: in how many views each face is visible (needed by
    ``handles.evidence: view_rate``); ``masks_of(segment)`` -> [(bool mask [H, W], Camera)]: the
    2D masks a segment matched (they refine its rectangle); None uses the mesh alone;
    ``weights``: the score rule's {hypothesis: {feature: weight}} (None: ``cfg.types.prior``);
    ``views``: the train views with their ray-cast depth and handle masks
    (:class:`~drawer_lib.articulation.rectify.View`): with ``cfg.rectify.enabled`` the handle
    masks are read on the rectified fronts instead of the faces they cover. A front's features
    do not depend on the weights."""
    if weights is None:
        weights = cfg.types.prior
    parts: list[Part] = []
    report: list[dict] = []
    fits = segment_fronts(mesh, segs, cam_centers, cfg, masks_of, parts, report, views)
    fronts = [f for _, f, _ in fits]
    mesh_pts, pt_face = sample_points(mesh, np.arange(len(mesh.faces)), cfg.handles.sample_per_m2, seed=1,
                                      local=cfg.fronts.sampling == "local")
    pt_normal = np.asarray(mesh.face_normals)[pt_face]
    edge = float(np.sqrt(2 * np.median(mesh.area_faces)))  # mesh edge length: face centroids are this far apart
    rc = cfg.rectify
    image_cells, colour, rfs = None, None, None
    colour_near: list[dict] = [{} for _ in fronts]  # fronts whose colour blob was chosen without a margin
    if rc.enabled and views and any(v.handles is not None for v in views):
        detected = [np.isin([v.stem for v in views], [st for st, _ in s.matched]) for s, _, _ in fits]
        rfs, cells, rates = rectify_fronts(fronts, views, rc, detected)
        image_cells = (cells, rates, rc.handle_link * rc.res, rc.min_cells)
        if rc.colour_handles and any(v.image is not None for v in views):
            colour = [colour_handle(f, rf, rc, near=cn) for f, rf, cn in zip(fronts, rfs, colour_near)]
    near_handles: dict[int, dict] = {}  # fronts whose pull was chosen over a second one nearly as heavy
    handles, gave_up = front_handles(fronts, mesh_pts, pt_normal, np.asarray(mesh.triangles_center), edge,
                                     cfg.handles, cfg.types.edge_frac,
                                     max(cfg.fronts.shared_edge_gap, cfg.handles.max_gap), handle_hits, face_views,
                                     image_cells, colour, near=near_handles)
    seg_pts = [piece_points(np.asarray(mesh.triangles_center)[s.faces], f, "piece" in info) for s, f, info in fits]
    partner = sliding_partners(fronts, handles, cfg.joints, seg_pts)
    floor_z = float(np.percentile(np.asarray(mesh.vertices)[:, 2], 1.0)) if len(mesh.vertices) else 0.0
    neighbours = front_neighbours(fronts, max(cfg.fronts.shared_edge_gap, cfg.handles.max_gap),
                                  cfg.handles.stacked_plane_tol)
    obstacles = Obstacles.of(mesh_pts) if cfg.interaction.enabled and len(mesh_pts) else None
    counts: dict[str, int] = {}
    ff = cfg.false_fronts
    for k, ((s, fr, info), h) in enumerate(zip(fits, handles)):
        carcass = carcass_depth(fr, mesh_pts, pt_normal, cfg.joints)
        terms = {"near_handle": near_handles[k]} if k in near_handles else {}
        if colour_near[k] and (h is None or h.source not in ("images", "masks")):  # the colours were read
            terms["near_colour"] = colour_near[k]
        is_flanked = False
        if rfs is not None and ff.enabled and rfs[k].rgb is not None:
            border = {"lines": border_lines(fr, rfs[k], cfg.split, ff.line_slack),
                      "flush": flush_sides(fr, mesh_pts, tuple(ff.ring), ff.flush_tol, ff.min_points)}
            terms["border"] = {kk: {side: None if x is None else round(x, 3) for side, x in vv.items()}
                               for kk, vv in border.items()}
            why = world_fixed(border, h, ff, neighbours[k])
            if why is not None:
                report.append({"segment": s.id, "family": "none", "reason": why, "front": fr.to_json(), **info,
                               **terms})
                continue
            is_flanked = flanked(border, ff)
            terms["flanked"] = is_flanked
        if h is None and s.support < cfg.types.min_support:
            dec = Decision("fixed", reason=f"no handle, matched in {s.support} < {cfg.types.min_support} views")
        elif h is None and cfg.types.filler_width is not None and fr.size[0] < cfg.types.filler_width:
            dec = Decision("fixed", reason=f"no handle and {fr.size[0]:.2f} m wide < {cfg.types.filler_width} m: "
                           "a filler or a sliver")
        elif cfg.types.rule == "score":
            blocked = None
            if obstacles is not None:
                terms["interaction"] = interaction_evidence(fr, obstacles, cfg.joints, cfg.interaction, carcass)
                blocked = blocked_hypotheses(terms["interaction"], cfg.interaction)
            window = window_contrast(fr, rfs[k]) if rfs is not None else None
            if window is not None:
                terms["window"] = round(window, 4)
            ev = Evidence(handle=h, size=fr.size, z_mid=float(fr.center[2]) - floor_z, stacked=neighbours[k][0],
                          beside_left=neighbours[k][1], beside_right=neighbours[k][2], partner=k in partner,
                          rail=rail_extent(fr, mesh_pts, pt_normal, inside=cfg.joints.rail_inside), carcass=carcass,
                          labels=s.labels, support=s.support, flanked=is_flanked, window=window)
            dec, score_terms = decide_by_score(ev, cfg.types, weights, blocked)
            terms |= score_terms
            turned = near_track(ev, dec, fr, mesh_pts, pt_normal, cfg, weights, blocked)
            if turned is not None:
                terms["near_track"] = turned
        elif k in partner:
            dec = Decision("sliding", reason="a neighbouring front on another track (depth step)")
        else:
            dec = decide_by_handle(h, s.labels, cfg.types)
        pair = (pair_of_doors(h, fr.size, terms["excluded"], cfg.types)
                if "excluded" in terms and k not in partner else None)
        gave = gave_reasons(gave_up, k, [s.id for s, _, _ in fits])
        # a threshold another machine could cross: a glazed front's rule, a cut, the choice of the pull
        near = (bool(terms.get("glazed_near")) or bool(info.get("near_cuts")) or k in near_handles
                or "near_colour" in terms or "near_track" in terms
                or (cfg.types.near_segment and bool(info.get("near_segment"))))
        pair_front = (fronts[partner[k][0]], partner[k][1]) if k in partner else None
        for pfr, pdec, ph, pair_row in door_pair(fr, dec, h, pair):
            reason = pdec.reason + gave
            low = ((pdec.margin is not None and pdec.margin < cfg.types.low_margin) or near
                   or bool(pair_row and pair_row["near"]))
            row = {"segment": s.id, "family": pdec.family, "hinge": pdec.hinge, "reason": reason, "low_margin": low,
                   "handle": None if ph is None else vars(ph), "size": [round(x, 4) for x in pfr.size],
                   "front": pfr.to_json(), **info, **terms}
            if pair_row is not None:
                row["pair"] = pair_row
            report.append(row)
            if pdec.family == "fixed":
                continue
            pid = f"{pdec.family}_{counts.get(pdec.family, 0)}"
            counts[pdec.family] = counts.get(pdec.family, 0) + 1
            extra = {"family": pdec.family, "segment": s.id}
            if ph is not None:  # the twin's handle primitive and grasp frame (drawer_lib/complete/grasp.py)
                extra["handle"] = {"a_u": round(ph.a_u, 4), "a_v": round(ph.a_v, 4), "orientation": ph.orientation,
                                   "size": None if ph.size is None else list(ph.size), "source": ph.source}
            if pdec.confidence is not None:
                extra |= {"confidence": round(pdec.confidence, 4), "low_margin": low}
                if pdec.margin is not None:
                    extra["margin"] = round(pdec.margin, 4)
            elif pair_row is not None:
                extra["low_margin"] = low
            side = (slide_side(pfr, mesh_pts, ph, cfg.joints,
                               rail_run(pfr, mesh_pts, pt_normal, inside=cfg.joints.rail_inside))
                    if pdec.family == "sliding" and pair_front is None else None)
            joint_front, tilt = plumb(pfr, cfg.fronts.plumb_deg)  # the evidence above read the fitted plane
            row |= {"tilt_deg": round(tilt, 3), "plumbed": joint_front is not pfr}
            parts.append(make_part(pid, pdec, joint_front, cfg.joints, extra,
                                   carcass if pdec.family == "drawer" else None, pair_front, side))
            row["part"] = pid
    return parts, report


def near_track(ev: Evidence, dec: Decision, front: Front, points: np.ndarray, normals: np.ndarray,
               cfg: ArticulateConfig, weights: dict[str, dict[str, float]], blocked: dict[str, str] | None
               ) -> dict | None:
    """Whether the track test could turn the score rule's decision ``dec`` on another machine:
    the track's length on the front moved as that machine's mesh could move it
    (:func:`~drawer_lib.articulation.probes.rail_extents_moved`), each one that differs from
    ``ev.rail`` put into the rule with the rest of the evidence as it is. The first that gives
    another kind or hinge side: ``{"rail", "other", "as"}`` (the front's length, that one, and
    what the front would have been); None when none does."""
    seen = {round(ev.rail, 6)}
    for other in rail_extents_moved(front, points, normals, inside=cfg.joints.rail_inside):
        if round(other, 6) in seen:
            continue
        seen.add(round(other, 6))
        alt, _ = decide_by_score(replace(ev, rail=other), cfg.types, weights, blocked)
        if (alt.family, alt.hinge) != (dec.family, dec.hinge):
            return {"rail": round(ev.rail, 4), "other": round(other, 4),
                    "as": alt.family + (f"_{alt.hinge}" if alt.hinge else "")}
    return None


def door_pair(front: Front, dec: Decision, h: Handle | None, pair: tuple[str, bool] | None
              ) -> list[tuple[Front, Decision, Handle | None, dict | None]]:
    """What a front becomes: [(front, decision, handle, None)] as decided, or with ``pair`` =
    (why, near) from :func:`~drawer_lib.articulation.decide.pair_of_doors` its two halves, each a
    door hinged on its outer edge with the pull if it lies on that half, and the ``pair`` record
    of ``decisions.json`` (``as_one``: what the whole front was decided)."""
    if pair is None:
        return [(front, dec, h, None)]
    why, near = pair
    as_one = dec.family + (f"_{dec.hinge}" if dec.hinge else "")
    return [(half, Decision("door", side, f"{why}; as one front: {dec.reason}"), half_handle(h, side),
             {"side": side, "pull_off_middle": round(abs(h.a_u - 0.5), 4), "width": round(front.size[0], 4),
              "near": near, "as_one": as_one})
            for side, half in zip(("left", "right"), cut_u(front, 0.5))]


def gave_reasons(gave_up: list[tuple[int, int, str]], k: int, seg_ids: list[int]) -> str:
    """The text front ``k``'s reason gets for the pulls it gave up (``gave_up``: (front that
    gave, front that took, why with a ``{}`` for the taker's segment id), fronts indexed as
    ``seg_ids``): "; why" per distinct why, in order (a pull given up in two moves is said once)."""
    whys = dict.fromkeys(why.format(seg_ids[hi]) for lo, hi, why in gave_up if lo == k)
    return "".join("; " + why for why in whys)


def world_fixed(border: dict, handle: Handle | None, cfg: FalseFrontsConfig,
                neighbours: tuple[int, bool, bool] = (0, False, False)) -> str | None:
    """Why a front is a world-fixed false front (:class:`~drawer_lib.articulation.config.FalseFrontsConfig`),
    or None. ``border``: {"lines": :func:`~drawer_lib.articulation.gaps.border_lines`, "flush":
    :func:`~drawer_lib.articulation.probes.flush_sides`}; ``handle``: its handle or None;
    ``neighbours``: :func:`front_neighbours`' (a front sharing an edge with other fronts is in
    a run of fronts, whose gaps the images may not resolve: kept)."""
    if handle is not None and handle.source != "colour":
        return None
    if neighbours[0] > 0 or neighbours[1] or neighbours[2]:
        return None
    lines = [x for x in border["lines"].values() if x is not None]
    if not lines or max(lines) >= cfg.line_coverage:
        return None
    flush = [side for side, x in border["flush"].items() if x is not None and x >= cfg.flush_frac]
    if len(flush) < cfg.min_flush_sides:
        return None
    return (f"a false front fixed in the world: no gap line round it (at most {max(lines):.0%} of a side), "
            f"the surface runs on flush beyond {len(flush)} sides ({', '.join(flush)})"
            + ("" if handle is None else ", its handle only read off colours"))


def flanked(border: dict, cfg: FalseFrontsConfig) -> bool:
    """Whether a front is flanked (:class:`~drawer_lib.articulation.config.FalseFrontsConfig`):
    the surface runs on flush beyond both its left and right sides (``flanked_flush`` of the
    points there) while a gap line runs along ``flanked_line`` of fewer than
    ``flanked_min_lines`` of its sides. Such a front may be a door in a run whose gaps the
    images do not resolve, or a patch of wall between the counter and the wall cabinets that a
    detector took for a front; without a handle nothing says which, so it is not a lone
    push-to-open door. ``border`` as for :func:`world_fixed`; an unseen side (None) is neither
    flush nor a line."""
    if cfg.flanked_min_lines == 0:
        return False
    fl = border["flush"]
    if not all(fl.get(side) is not None and fl[side] >= cfg.flanked_flush for side in ("left", "right")):
        return False
    lines = sum(1 for x in border["lines"].values() if x is not None and x >= cfg.flanked_line)
    return lines < cfg.flanked_min_lines


def front_neighbours(fronts: list[Front], max_gap: float, plane_tol: float) -> list[tuple[int, bool, bool]]:
    """Per front (coplanar fronts sharing its top or bottom edge, one shares its left edge, one
    shares its right edge) (:func:`~drawer_lib.articulation.fronts.abutting_edges`)."""
    out = []
    for a, fa in enumerate(fronts):
        stacked, left, right = 0, False, False
        for b, fb in enumerate(fronts):
            if a == b:
                continue
            for ax, side, _ in abutting_edges(fa, fb, max_gap, plane_tol):
                if ax == 1:
                    stacked += 1
                elif side < 0:
                    left = True
                else:
                    right = True
        out.append((stacked, left, right))
    return out
