"""Scene decomposition from 2D detections (DRAWER §3.3; the official code's ``percept_stage1-6``), on the CPU.

1. Every detection mask (eroded) is lifted to the mesh faces it covers, through per-frame
   face-id maps (ray cast of the same mesh, so visibility is exact).
2. Graph: mesh-adjacent faces, weight = number of masks that hold both. A false mask, a merge or
   a ragged border happens in a frame or two; a front is seen whole in many, so edges seen in
   fewer than ``min_cooccur`` masks are dropped, and so are sharp creases.
3. Louvain communities (seeded, bounded by work) at several resolutions give overlapping candidates.
4. Each candidate is rendered back into every frame that sees it and compared with that frame's
   masks: ``score`` = median over frames of the best IoU. A merged detection lowers a frame or
   two, not the median; a frame whose masks miss the candidate altogether is no evidence
   either way (``missing_weight``), since a detector misses the same front in many views.
5. Greedy selection by score removes duplicates (the same front found at several resolutions);
   normal consistency marks planar segments (fronts) against the rest (objects). A selection
   that another machine's mesh could undo (a score near its threshold or near a rival's, an
   overlap near the duplicate bound, support one frame from its bound) is listed in the
   segment's ``near`` rows, and a candidate that nearly became a segment in ``near_missed``.

Label votes (the labels of the best-matching masks) are kept as hints for the articulate stage;
they never decide anything here.
"""

from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import trimesh

from drawer_lib.io.capture import Capture
from drawer_lib.perception.config import DecomposeConfig
from drawer_lib.perception.louvain import louvain
from drawer_lib.perception.views import MeshViews, adjacency_edges, connected_components, largest_component

HANDLE_LABELS = ("handle", "knob", "pull")
SCORE_BAND = 0.02  # back-projection IoU: a score this close to min_score or to a rival's can swap on another mesh
OVERLAP_BAND = 0.05  # share of a candidate's faces: this close to dup_overlap
SAME_FRONT_IOU = 0.5  # faces overlapping this much: the same front either way (as the metrics match fronts)


@dataclass
class MaskRecord:
    view: int  # index into MeshViews.frames
    det_id: int
    label: str
    score: float
    faces: np.ndarray  # face ids under the (eroded) mask


@dataclass
class Segment:
    id: int
    faces: np.ndarray  # face ids of the perception mesh
    score: float  # median best back-projection IoU (1.0 for geometric segments)
    support: int  # frames that scored it
    labels: dict = field(default_factory=dict)  # label votes of the best-matching masks
    planar: bool = True
    normal: np.ndarray = field(default_factory=lambda: np.zeros(3))
    area: float = 0.0
    centroid: np.ndarray = field(default_factory=lambda: np.zeros(3))
    source: str = "detections"
    source_candidate: int = -1  # index of the candidate it came from (within one run)
    matched: list = field(default_factory=list)  # [(frame stem, detection id)] of the masks it matches
    near: list = field(default_factory=list)  # selections within a band of their bounds (select_segments)

    def to_json(self) -> dict:
        return {"id": self.id, "n_faces": int(len(self.faces)), "score": round(float(self.score), 4),
                "support_frames": int(self.support), "labels": self.labels, "planar": bool(self.planar),
                "normal": [round(float(x), 5) for x in self.normal], "area_m2": round(float(self.area), 5),
                "centroid": [round(float(x), 5) for x in self.centroid], "source": self.source,
                "matched": [[str(a), int(b)] for a, b in self.matched]} | ({"near": self.near} if self.near else {})


def read_detections(cap: Capture, views: MeshViews) -> list[tuple[np.ndarray, list[dict]]]:
    """(label map [H, W], detections) of every view, read once."""
    return [cap.detections(i) for i in views.frames]


def absorb_handles(lab: np.ndarray, dets: list[dict], ring_px: int = 2, min_contact: float = 0.3) -> np.ndarray:
    """The label map ``lab`` [H, W] with every handle mask given to the front it sits on.

    A detector that segments handles separately leaves a hole where the handle is in the mask of
    its drawer or door; on a drawer a dozen pixels tall, a bar handle cuts that mask into thin
    strips whose faces the co-occurrence graph then barely holds together. The front that owns a
    handle is the non-handle mask holding most of the ring of ``ring_px`` pixels around it, if
    that is at least ``min_contact`` of the ring; the handle's pixels and the unlabelled pixels of
    its ring (the gap a ragged mask leaves) take that front's id. Returns a new map; ``lab`` is
    not modified; handles without such a front keep their own id."""
    from scipy import ndimage

    handles = [int(d["id"]) for d in dets if str(d.get("label", "")).strip().lower() in HANDLE_LABELS]
    if not handles:
        return lab
    is_front = np.zeros(int(lab.max()) + 1, bool)
    for d in dets:
        if int(d["id"]) not in handles and int(d["id"]) <= int(lab.max()):
            is_front[int(d["id"])] = True
    out = lab.copy()
    for h in handles:
        m = lab == h
        if not m.any():
            continue
        ys, xs = np.nonzero(m)
        y0, y1 = max(ys.min() - ring_px, 0), min(ys.max() + ring_px + 1, lab.shape[0])
        x0, x1 = max(xs.min() - ring_px, 0), min(xs.max() + ring_px + 1, lab.shape[1])
        mc, lc = m[y0:y1, x0:x1], lab[y0:y1, x0:x1]
        ring = ndimage.binary_dilation(mc, iterations=ring_px) & ~mc
        ids = lc[ring]
        cnt = np.bincount(ids, minlength=len(is_front))[:len(is_front)] * is_front
        if not ring.any() or cnt.max() < min_contact * ring.sum():
            continue
        owner = int(cnt.argmax())
        oc = out[y0:y1, x0:x1]
        oc[mc | (ring & (lc == 0))] = owner
    return out


def lift_masks(detections: list[tuple[np.ndarray, list[dict]]], views: MeshViews, erode_px: int,
               front_maps: list[np.ndarray] | None = None) -> tuple[list[MaskRecord], np.ndarray]:
    """The detections of every view as face sets; also [F] per-face count of "handle" mask hits.
    ``front_maps``: label maps to take the non-handle masks from (default: the detections' own;
    :func:`absorb_handles` gives maps whose fronts include their handles)."""
    from scipy import ndimage

    recs: list[MaskRecord] = []
    handle_hits = np.zeros(views.n_faces, np.int64)
    for t, (lab, dets) in enumerate(detections):
        flab = front_maps[t] if front_maps is not None else lab
        for d in dets:
            label = str(d.get("label", "")).strip().lower()
            is_handle = label in HANDLE_LABELS
            m = (lab if is_handle else flab) == int(d["id"])
            if erode_px > 0:  # not when that would take most of a small mask away
                e = ndimage.binary_erosion(m, iterations=erode_px)
                m = e if e.sum() >= 0.5 * m.sum() else m
            f = views.faces_under(t, m)
            if len(f) == 0:
                continue
            if is_handle:
                handle_hits[f] += 1
                continue
            recs.append(MaskRecord(t, int(d["id"]), label, float(d.get("score", 1.0)), f))
    return recs, handle_hits


def cooccurrence_graph(n_faces: int, edges: np.ndarray, dihedral: np.ndarray, masks: list[MaskRecord],
                       visible: np.ndarray, min_cooccur: int, min_rate: float, max_dihedral: float,
                       separation: bool = False, missing_weight: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(edges [E', 2], weights [E']): adjacent face pairs held together by >= ``min_cooccur``
    masks and in >= ``min_rate`` of the frames that see both (``visible`` [F]: frames seeing each
    face), with a dihedral angle <= ``max_dihedral`` deg. Weight = that rate.

    ``missing_weight``: how much a frame that sees both faces but holds neither in any mask
    counts in the rate's denominator. 1 counts it as a frame that keeps them apart; 0 as no
    evidence either way (the detector missed the front there): a front detected in a quarter
    of the views is then held together as firmly as one detected in all, while a border is
    still cut by the frames whose masks stop at it.

    ``separation``: the rate at which the two faces lie in *different* masks of one frame is
    subtracted from the rate before the threshold. Along the border of a thin front (a drawer
    a dozen pixels tall) the neighbour's ragged masks hold both sides now and then, often enough
    to pass ``min_rate``, while the front's own masks keep the sides apart in most frames; the
    difference cuts that border and leaves the inside of a front (separated only by a false or
    merged mask) as it was. Each frame's masks are disjoint (one label map), so a face is in at
    most one mask per frame."""
    w = np.zeros(len(edges), np.int64)
    sep = np.zeros(len(edges), np.int64)
    covered = np.zeros(len(edges), np.int64)  # frames with a mask on either face
    by_view: dict[int, list[MaskRecord]] = {}
    for r in masks:
        by_view.setdefault(r.view, []).append(r)
    owner = np.full(n_faces, -1, np.int64)
    for recs in by_view.values():
        for k, r in enumerate(recs):
            owner[r.faces] = k
        a, b = owner[edges[:, 0]], owner[edges[:, 1]]
        w += (a >= 0) & (a == b)
        sep += (a >= 0) & (b >= 0) & (a != b)
        covered += (a >= 0) | (b >= 0)
        for r in recs:
            owner[r.faces] = -1
    both = np.minimum(visible[edges[:, 0]], visible[edges[:, 1]])
    denom = np.maximum(both - (1.0 - missing_weight) * np.maximum(both - covered, 0), 1)
    rate = (w - sep * separation) / denom
    keep = (w >= min_cooccur) & (rate >= min_rate) & (dihedral <= max_dihedral)
    return edges[keep], rate[keep]


def louvain_candidates(n_faces: int, edges: np.ndarray, weights: np.ndarray, resolutions, min_faces: int,
                       seed: int, max_sweeps: int = 64, report: dict | None = None,
                       component_rates=()) -> list[np.ndarray]:
    """Communities (face-id arrays, each its largest connected component) over all resolutions,
    exact duplicates removed. Each Louvain run is bounded by work
    (:func:`~drawer_lib.perception.louvain.louvain`, at most ``max_sweeps`` sweeps per level);
    ``report`` (if given) receives ``louvain_capped``: the levels that hit that bound.

    ``component_rates``: also the connected components of the graph cut to the edges of weight
    >= each rate. On a mesh graph modularity splits a large uniform front (a tall door of 1.3k
    faces) at every resolution that keeps it apart from its neighbours, since a cut across it
    is cheap against the product of its halves' degrees; a weight threshold keeps it whole
    when the masks hold its inside together more often than its border."""
    out, seen = [], set()

    def add(f: np.ndarray) -> None:
        if len(f) < min_faces:
            return
        key = np.sort(f).tobytes()
        if key not in seen:
            seen.add(key)
            out.append(np.sort(f))

    # the connected components of the graph (the coarsest split) and of the graph cut at each
    # rate, then Louvain at each resolution
    for ek in [edges, *(edges[weights >= rate] for rate in component_rates)]:
        lab = connected_components(n_faces, ek)
        deg = np.bincount(ek.ravel(), minlength=n_faces) if len(ek) else np.zeros(n_faces, np.int64)
        ids, cnt = np.unique(lab[deg > 0], return_counts=True)
        for c in ids[cnt >= min_faces]:
            add(np.nonzero((lab == c) & (deg > 0))[0])
    capped = 0
    for r in resolutions:
        lab, rep = louvain(n_faces, edges, weights, float(r), seed, max_sweeps=max_sweeps)
        capped += rep["capped"]
        order = np.argsort(lab, kind="stable")
        ids, starts, counts = np.unique(lab[order], return_index=True, return_counts=True)
        for s0, cnt in zip(starts, counts):
            if cnt >= min_faces:
                add(largest_component(order[s0:s0 + cnt], n_faces, edges))
    if report is not None:
        report.update(louvain_capped=capped)
    return out


def tolerant_ious(sil: np.ndarray, lab: np.ndarray, sizes: np.ndarray, band_px: int) -> np.ndarray:
    """IoU [K] of the silhouette ``sil`` [H, W] with every mask id of the label map ``lab``
    [H, W] (``sizes`` [K]: pixels per id), not counting the pixels within ``band_px`` of the
    silhouette's border either way: intersection = mask pixels inside the eroded silhouette,
    union = eroded silhouette + mask pixels outside the dilated one. A ragged mask border or a
    mesh edge off by a pixel then costs nothing, which matters for a front a dozen pixels tall.
    ``band_px`` 0 (or a silhouette the erosion would empty) gives the plain IoU."""
    from scipy import ndimage

    K = len(sizes)
    if band_px > 0:
        ys, xs = np.nonzero(sil)
        pad = band_px + 1
        y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, sil.shape[0])
        x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, sil.shape[1])
        crop, lc = sil[y0:y1, x0:x1], lab[y0:y1, x0:x1]
        sq = np.ones((3, 3), bool)  # the band is in the Chebyshev (8-neighbour) distance
        inner = ndimage.binary_erosion(crop, sq, iterations=band_px, border_value=0)
        if inner.any():
            outer = ndimage.binary_dilation(crop, sq, iterations=band_px)
            inter = np.bincount(lc[inner], minlength=K)
            in_outer = np.bincount(lc[outer], minlength=K)
            return inter / np.maximum(int(inner.sum()) + sizes - in_outer, 1)
    inter = np.bincount(lab[sil], minlength=K)
    return inter / np.maximum(int(sil.sum()) + sizes - inter, 1)


def weighted_median(x: np.ndarray, w: np.ndarray) -> float:
    """The weighted median of ``x`` [N] with weights ``w`` [N] >= 0: the smallest value whose
    cumulative weight reaches half the total, or the mean of it and the next when it reaches
    exactly half (so equal weights give ``np.median``). NaN when the weights sum to 0."""
    x, w = np.asarray(x, float), np.asarray(w, float)
    if not len(x) or w.sum() <= 0:
        return float("nan")
    o = np.argsort(x, kind="stable")
    xs, cw = x[o], np.cumsum(w[o])
    half = 0.5 * cw[-1]
    i = int(np.searchsorted(cw, half))
    if cw[i] == half and i + 1 < len(xs):
        return float(0.5 * (xs[i] + xs[i + 1 + int(np.searchsorted(cw[i + 1:], half, side="right"))]))
    return float(xs[i])


def backprojection_scores(cands: list[np.ndarray], views: MeshViews, label_maps: list[np.ndarray],
                          masks: list[MaskRecord], min_px: int, band_px: int = 0,
                          progress=lambda it, **kw: it, missing_weight: float = 1.0, missing_cover: float = 0.1
                          ) -> list[tuple[float, int, Counter, list[tuple[int, int]], int]]:
    """Per candidate: (score, frames that scored it, label votes, [(view, mask id)] of the masks
    it matches with IoU >= 0.5, frames that see it). Score: the weighted median over the frames
    that see it of the best mask IoU (:func:`tolerant_ious`); a frame in which masks cover less
    than ``missing_cover`` of the silhouette (the detector found nothing there) counts with
    weight ``missing_weight``, every other frame with weight 1. ``missing_weight`` 1 is the plain
    median over all frames; 0 leaves the missed frames out (and out of the count of frames that
    scored it)."""
    by_view: dict[int, list[MaskRecord]] = {}
    for r in masks:
        by_view.setdefault(r.view, []).append(r)
    labs = [lb.astype(np.int64) for lb in label_maps]
    label_of = {(r.view, r.det_id): r.label for r in masks}
    F = views.n_faces
    sizes = [np.bincount(lb.ravel(), minlength=int(lb.max()) + 1) for lb in labs]
    res = []
    for f in progress(cands, desc="back-projection", total=len(cands)):
        member = np.zeros(F, bool)
        member[f] = True
        ious, wts, votes, matched = [], [], Counter(), []
        for t in range(len(views.frames)):
            sil = views.silhouette(t, member)
            n_sil = int(sil.sum())
            if n_sil < min_px:
                continue
            ids = np.array([r.det_id for r in by_view.get(t, [])], np.int64)
            if not len(ids):
                ious.append(0.0)
                wts.append(missing_weight)
                continue
            cover = np.bincount(labs[t][sil], minlength=len(sizes[t]))[ids].sum() / n_sil
            iou = tolerant_ious(sil, labs[t], sizes[t], band_px)[ids]
            j = int(iou.argmax())
            best = float(iou[j])
            ious.append(best)
            wts.append(missing_weight if cover < missing_cover else 1.0)
            if best >= 0.5:
                votes[label_of[(t, int(ids[j]))]] += 1
                matched.append((t, int(ids[j])))
        w = np.asarray(wts)
        score = weighted_median(np.asarray(ious), w) if w.sum() > 0 else 0.0
        res.append((score, int((w > 0).sum()), votes, matched, len(ious)))
    return res


def face_geometry(mesh: trimesh.Trimesh, faces: np.ndarray, planar_deg: float) -> tuple[np.ndarray, float, np.ndarray, float]:
    """(area-weighted mean unit normal, area m^2, area-weighted centroid, fraction of the area
    within ``planar_deg`` of the mean normal)."""
    a = np.asarray(mesh.area_faces)[faces]
    n = np.asarray(mesh.face_normals)[faces]
    c = np.asarray(mesh.triangles_center)[faces]
    area = float(a.sum())
    if area <= 0:
        return np.zeros(3), 0.0, c.mean(0) if len(c) else np.zeros(3), 0.0
    mn = (a[:, None] * n).sum(0)
    norm = np.linalg.norm(mn)
    mn = mn / norm if norm > 1e-12 else np.zeros(3)
    frac = float(a[(n @ mn) >= np.cos(np.deg2rad(planar_deg))].sum() / area) if norm > 1e-12 else 0.0
    return mn, area, (a[:, None] * c).sum(0) / area, frac


def face_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two sorted arrays of unique face ids."""
    inter = len(np.intersect1d(a, b, assume_unique=True))
    return inter / max(len(a) + len(b) - inter, 1)


def select_segments(cands: list[np.ndarray], scores: list[tuple], mesh: trimesh.Trimesh,
                    cfg: DecomposeConfig, near_missed: list[dict] | None = None) -> list[Segment]:
    """Greedy by score (then size) over the candidates scored (:func:`backprojection_scores`) at
    least ``min_score`` in at least ``min_frames`` frames and ``min_detected`` of the frames that
    see them: a candidate of which more than ``dup_overlap`` is already taken by better segments
    is a duplicate; otherwise it is accepted without the taken faces.

    Margins (another machine's mesh moves a score by a few pixels of IoU): each segment's
    ``near`` lists the selections it passed by less than a band, as ``{"step", "margin"}``:
    ``score`` (within :data:`SCORE_BAND` of ``min_score``), ``support`` (one frame fewer
    fails), ``overlap`` (its share already taken lies within :data:`OVERLAP_BAND` under
    ``dup_overlap``) and ``rival`` (a candidate scored within :data:`SCORE_BAND` under it was
    dropped as its duplicate, though their faces overlap less than :data:`SAME_FRONT_IOU`: the
    other order gives a segment on another front). ``near_missed`` (if given) receives the candidates
    that failed one selection by less than its band and passed the others (``candidate``,
    ``step``, ``margin``, ``n_faces``): a segment on another machine."""
    order = sorted(range(len(cands)), key=lambda k: (-scores[k][0], -len(cands[k])))
    taken = np.full(len(mesh.faces), -1, np.int64)
    segs: list[Segment] = []
    for k in order:
        s, support, votes, _, seen = scores[k]
        f = cands[k]
        owners = taken[f]
        n_taken = int((owners >= 0).sum())
        share = n_taken / max(len(f), 1)
        need = max(cfg.min_frames, cfg.min_detected * seen)
        # each selection's clearance over its bound and its band; which of them failed
        checks = {"score": (s - cfg.min_score, SCORE_BAND), "support": (support - need, 1.0),
                  "overlap": (cfg.dup_overlap - share, OVERLAP_BAND if n_taken else 0.0)}
        bad = {"score": s < cfg.min_score, "support": support < cfg.min_frames or support < cfg.min_detected * seen,
               "overlap": n_taken > cfg.dup_overlap * len(f)}
        failed = [st for st in checks if bad[st]]
        free = int((owners < 0).sum())
        if failed or free < cfg.min_faces:
            if failed == ["overlap"]:  # a duplicate: of which segment, how close in score
                seg = segs[int(np.bincount(owners[owners >= 0]).argmax())]
                gap = seg.score - s
                if gap < SCORE_BAND and face_iou(cands[seg.source_candidate], f) < SAME_FRONT_IOU:
                    seg.near.append({"step": "rival", "margin": round(float(gap), 4), "candidate": int(k)})
            if near_missed is not None and free >= cfg.min_faces and len(failed) == 1:
                m, band = checks[failed[0]]
                if -m < band:  # failed by less than its band
                    near_missed.append({"candidate": int(k), "step": failed[0], "margin": round(float(m), 4),
                                        "n_faces": int(len(f))})
            continue
        near = [{"step": st, "margin": round(float(m), 4)} for st, (m, band) in checks.items() if m < band]  # passed by less
        f = f[owners < 0]
        n, area, c, frac = face_geometry(mesh, f, cfg.planar_deg)
        seg = Segment(len(segs), f, s, support, dict(votes.most_common()), frac >= cfg.planar_frac, n, area, c,
                      source_candidate=k, near=near)
        taken[f] = seg.id
        segs.append(seg)
    return segs


def near_summary(segs: list[Segment], near_missed: list[dict]) -> dict:
    """What decompose's metrics record of the selections near their bounds
    (:func:`select_segments`): the bands, the segments with a ``near`` row, the rows per step,
    and the candidates that nearly became segments.

    >>> near_summary([Segment(0, np.arange(3), 0.56, 5, near=[{"step": "score", "margin": 0.01}])], [])["near_steps"]
    {'score': 1, 'support': 0, 'overlap': 0, 'rival': 0}
    """
    rows = [r for s in segs for r in s.near]
    return {"near_band": {"score": SCORE_BAND, "overlap": OVERLAP_BAND, "same_front_iou": SAME_FRONT_IOU},
            "near_segments": sum(bool(s.near) for s in segs),
            "near_steps": {k: sum(r["step"] == k for r in rows) for k in ("score", "support", "overlap", "rival")},
            "near_missed": len(near_missed),
            "near_missed_steps": {k: sum(r["step"] == k for r in near_missed) for k in ("score", "support", "overlap")}}


def grow_segments(segs: list[Segment], matched: list[list[tuple[int, int]]], views: MeshViews,
                  label_maps: list[np.ndarray], edges: np.ndarray, cfg: DecomposeConfig) -> None:
    """Complete each segment from the (un-eroded) masks it matched: a face joins when it lies
    under the segment's mask in >= half of the matched frames that see it (>= 2 of them), its
    normal agrees with a planar segment's, and it connects to the segment. A face two segments
    claim goes to the higher rate. Edits ``segs`` in place (faces, area, centroid, normal)."""
    F = views.n_faces
    normals = np.asarray(views.mesh.face_normals)
    best_rate = np.zeros(F)
    owner = np.full(F, -1, np.int64)
    grown: list[np.ndarray] = []
    for s, mt in zip(segs, matched):
        votes = np.zeros(F, np.int64)
        seen = np.zeros(F, np.int64)
        for t, d in mt:
            seen[views.face_px[t] >= 0] += 1
            votes[views.faces_under(t, label_maps[t] == d)] += 1
        rate = votes / np.maximum(seen, 1)
        ok = (rate >= 0.5) & (votes >= 2)
        if s.planar:
            ok &= normals @ s.normal >= np.cos(np.deg2rad(cfg.planar_deg))
        ok[s.faces] = True
        lab = connected_components(F, edges, ok)
        core = np.unique(lab[s.faces])
        f = np.nonzero(np.isin(lab, core[core >= 0]))[0]
        grown.append(f)
        better = rate[f] > best_rate[f]
        best_rate[f[better]] = rate[f[better]]
        owner[f[better]] = s.id
    for s, f in zip(segs, grown):
        f = f[(owner[f] == s.id) | np.isin(f, s.faces)]
        n, area, c, _ = face_geometry(views.mesh, f, cfg.planar_deg)
        s.faces, s.area, s.centroid = f, area, c
        if s.planar:
            s.normal = n


def face_labels(n_faces: int, segs: list[Segment]) -> np.ndarray:
    lab = np.full(n_faces, -1, np.int32)
    for s in segs:
        lab[s.faces] = s.id
    return lab


def decompose_from_detections(cap: Capture, views: MeshViews, cfg: DecomposeConfig,
                              progress=lambda it, **kw: it) -> tuple[list[Segment], np.ndarray, dict]:
    """(segments, [F] handle-mask hits per face, counts)."""
    detections = read_detections(cap, views)
    label_maps = [absorb_handles(lab, dets) if cfg.absorb_handles else lab for lab, dets in detections]
    masks, handle_hits = lift_masks(detections, views, cfg.erode_px, label_maps)
    edges, dih = adjacency_edges(views.mesh)
    visible = views.face_frames()
    ge, gw = cooccurrence_graph(views.n_faces, edges, dih, masks, visible, cfg.min_cooccur, cfg.min_rate,
                                cfg.max_dihedral, cfg.separation, cfg.missing_weight)
    lv: dict = {}
    cands = louvain_candidates(views.n_faces, ge, gw, cfg.resolutions, cfg.min_faces, cfg.seed, cfg.louvain_max_sweeps, lv,
                               cfg.component_rates)
    min_px = max(4, int(round(cfg.min_px_frac * cap.intrinsics.width * cap.intrinsics.height)))
    scores = backprojection_scores(cands, views, label_maps, masks, min_px, cfg.band_px, progress,
                                   cfg.missing_weight, cfg.missing_cover)
    near_missed: list[dict] = []
    segs = select_segments(cands, scores, views.mesh, cfg, near_missed)
    for sg in segs:
        sg.matched = [(cap.frames[views.frames[t]].stem, d) for t, d in scores[sg.source_candidate][3]]
    if cfg.grow:
        grow_segments(segs, [scores[s.source_candidate][3] for s in segs], views, label_maps, edges, cfg)
    info = {"masks": len(masks), "graph_edges": int(len(ge)), "candidates": len(cands), "segments": len(segs),
            "planar_segments": sum(s.planar for s in segs), "handle_faces": int((handle_hits > 0).sum()), **lv,
            **near_summary(segs, near_missed), "near_missed_rows": near_missed}
    return segs, handle_hits, info
