"""The built-in detector: a small fully convolutional network (a U-Net of four levels) that
labels every pixel background, front, front edge, handle or object, and the decoding of those
labels into instance masks (contour-aware segmentation: the 'edge' class keeps neighbouring
fronts apart, a watershed of it from each front's sure interior gives the masks).

It needs no download: the ``detector`` stage trains it on renders of the benchmark's train
split (:mod:`drawer_lib.detect.train`) and writes ``weights.pt`` (the state dict and the
architecture's hyper-parameters; with ``detector.members`` > 1 the state dicts of that many fits
from consecutive seeds, whose class probabilities are averaged), an output DVC hashes like any
other.
"""

import math
import struct
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from jaxtyping import Bool, Float, Int, UInt8
from scipy import ndimage
from torch import Tensor, nn

from drawer_lib.detect.config import BuiltinDetectConfig
from drawer_lib.detect.masks import Detection
from drawer_lib.devices import cuda_numerics, torch_device
from drawer_lib.errors import InputError, NonFiniteError

CLASSES = ("background", "front", "edge", "handle", "object")
BG, FRONT, EDGE, HANDLE, OBJECT = range(len(CLASSES))
MEAN = (0.5, 0.5, 0.5)
STD = (0.25, 0.25, 0.25)


DECODE_BAND = 1e-3  # a region's decision this close to its threshold (in probability) is listed as near


def _block(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, padding=1, bias=False), nn.GroupNorm(4, cout), nn.ReLU(inplace=True),
                         nn.Conv2d(cout, cout, 3, padding=1, bias=False), nn.GroupNorm(4, cout), nn.ReLU(inplace=True))


MEMORY_FORMATS = {"contiguous": torch.contiguous_format, "channels_last": torch.channels_last}


class TinyUNet(nn.Module):
    """[B, 3, H, W] normalised RGB -> [B, len(CLASSES), H, W] logits. Widths w, 2w, 4w, 4w;
    H and W need not be multiples of 8 (each coarser map is resized to its skip's size).

    ``memory_format``: how its weights and feature maps lie in memory (a key of
    :data:`MEMORY_FORMATS`). ``channels_last`` (NHWC) lets the CPU's convolutions run about
    1.4x faster (``scripts/bench_detector_device.py --memory-format``); the arithmetic is the
    same but for its order, so the logits differ from ``contiguous``'s in their last bits. The
    logits come back in that format (index them as any tensor)."""

    def __init__(self, width: int = 16, n_classes: int = len(CLASSES), memory_format: str = "contiguous"):
        super().__init__()
        if memory_format not in MEMORY_FORMATS:
            raise ValueError(f"TinyUNet: memory_format = {memory_format!r}, expected one of {sorted(MEMORY_FORMATS)}")
        w = width
        self.width = width
        self.memory_format = memory_format
        self.enc = nn.ModuleList([_block(3, w), _block(w, 2 * w), _block(2 * w, 4 * w), _block(4 * w, 4 * w)])
        self.dec = nn.ModuleList([_block(8 * w, 2 * w), _block(4 * w, w), _block(2 * w, w)])
        self.head = nn.Conv2d(w, n_classes, 1)
        self.to(memory_format=MEMORY_FORMATS[memory_format])

    def forward(self, x: Float[Tensor, "B 3 H W"]) -> Float[Tensor, "B C H W"]:
        x = x.contiguous(memory_format=MEMORY_FORMATS[self.memory_format])
        skips = []
        for k, e in enumerate(self.enc):
            x = e(x if k == 0 else F.max_pool2d(x, 2, ceil_mode=True))
            skips.append(x)
        x = skips.pop()
        for d in self.dec:
            s = skips.pop()
            x = F.interpolate(x, size=s.shape[-2:], mode="bilinear", align_corners=False)
            x = d(torch.cat([x, s], 1))
        return self.head(x)


def normalise(rgb: UInt8[np.ndarray, "H W 3"] | Tensor) -> Float[Tensor, "3 H W"]:
    t = torch.as_tensor(np.asarray(rgb)).float().div(255.0).permute(2, 0, 1)
    return (t - torch.tensor(MEAN)[:, None, None]) / torch.tensor(STD)[:, None, None]


def working_shape(H: int, W: int, size: int) -> tuple[int, int]:
    """The image's size with its long side ``size`` (aspect kept, at least 1 px)."""
    s = size / max(H, W)
    return max(1, round(H * s)), max(1, round(W * s))


class DetectorEnsemble(nn.Module):
    """Several fits of :class:`TinyUNet` as one: [B, 3, H, W] -> [B, C, H, W], the log of the
    members' mean class probabilities, so its softmax is their mean (what ``class_probs`` reads)."""

    def __init__(self, members: Sequence[TinyUNet]):
        super().__init__()
        if not members:
            raise ValueError("DetectorEnsemble: no members")
        self.members = nn.ModuleList(members)

    def forward(self, x: Float[Tensor, "B 3 H W"]) -> Float[Tensor, "B C H W"]:
        logp = torch.stack([F.log_softmax(m(x), 1) for m in self.members])
        return torch.logsumexp(logp, 0) - math.log(len(self.members))


def save_detector(path: Path, model: TinyUNet | Sequence[TinyUNet], info: dict) -> None:
    """One fit: its state dict (contiguous tensors, :func:`plain_state`), width and memory format.
    Several (an ensemble, all of one width and format): the first as one fit's, all of them
    under ``members``, so the file is the single fit's when there is one."""
    members = [model] if isinstance(model, TinyUNet) else list(model)
    if not members or len({m.width for m in members}) != 1:
        raise ValueError(f"save_detector: {len(members)} members of widths {sorted({m.width for m in members})}")
    if len({m.memory_format for m in members}) != 1:
        raise ValueError(f"save_detector: members in memory formats {sorted({m.memory_format for m in members})}")
    d = {"kind": "drawer.builtin_detector/1", "width": members[0].width, "classes": list(CLASSES),
         "memory_format": members[0].memory_format, "state_dict": plain_state(members[0]), "info": info}
    if len(members) > 1:
        d["members"] = [plain_state(m) for m in members]
    torch.save(d, path)


def plain_state(model: nn.Module) -> dict[str, Tensor]:
    """``model``'s state dict with every tensor contiguous: a weights file reads the same
    whatever memory format the network ran in."""
    return {k: v.contiguous() for k, v in model.state_dict().items()}


def weight_files(path: Path | Sequence[Path]) -> list[Path]:
    """One weights file or several, as a list."""
    return [Path(path)] if isinstance(path, (str, Path)) else [Path(p) for p in path]


def load_detector(path: Path | Sequence[Path]) -> tuple[TinyUNet | DetectorEnsemble, dict]:
    """The network of a weights file, or of several: one fit is a :class:`TinyUNet`; more fits,
    in one file (``members``) or across files, a :class:`DetectorEnsemble` of all of them in
    order. ``info`` is the first file's, with ``members`` (the count) when there are several.
    Each network runs in the memory format its file names (``contiguous`` for a file written
    before files named one), so it computes what its fit was scored with."""
    paths = weight_files(path)
    if not paths:
        raise InputError("the built-in detector: no weights file given")
    members, infos = [], []
    for p in paths:
        if not p.is_file():
            raise InputError(f"{p}: the built-in detector's weights are missing (run `dvc repro detector`)")
        d = torch.load(p, map_location="cpu", weights_only=True)
        if d.get("kind") != "drawer.builtin_detector/1" or list(d.get("classes", [])) != list(CLASSES):
            raise InputError(f"{p}: not the built-in detector's weights (kind {d.get('kind')!r})")
        for sd in d.get("members", [d["state_dict"]]):
            m = TinyUNet(int(d["width"]), memory_format=d.get("memory_format", "contiguous"))
            m.load_state_dict(sd)
            members.append(m.eval())
        infos.append(dict(d.get("info", {})))
    if len(members) == 1:
        return members[0], infos[0]
    return DetectorEnsemble(members).eval(), {**infos[0], "members": len(members)}


def network_input(rgb: UInt8[np.ndarray, "H W 3"], size: int) -> Float[Tensor, "1 3 h w"]:
    """The image as the network sees it: normalised, and resized on the CPU (bilinear,
    antialiased) so that its long side is ``size``."""
    H, W = rgb.shape[:2]
    h, w = working_shape(H, W, size)
    x = normalise(rgb)[None]
    if (h, w) != (H, W):
        x = F.interpolate(x, size=(h, w), mode="bilinear", align_corners=False, antialias=True)
    return x


@torch.inference_mode()
def class_probs(model: TinyUNet | DetectorEnsemble, rgb: UInt8[np.ndarray, "H W 3"], size: int) -> Float[np.ndarray, "C h w"]:
    """Per-class probabilities at the working size (long side ``size``), computed on the
    model's device (the image is resized on the CPU first, so only the network's numerics
    depend on it) under the fit's numerics (:func:`~drawer_lib.devices.cuda_numerics`: on
    CUDA no TF32)."""
    x = network_input(rgb, size)
    dev = model_device(model)
    with cuda_numerics(dev):
        p = torch.softmax(model(x.to(dev))[0], 0)
    if not torch.isfinite(p).all():
        raise NonFiniteError("detect: the built-in detector gave non-finite probabilities")
    return p.cpu().numpy()


@torch.inference_mode()
def float32_error(model: TinyUNet | DetectorEnsemble, rgb: UInt8[np.ndarray, "H W 3"], size: int,
                  min_prob: float = 1e-3) -> dict:
    """How far this machine's float32 network lies from the same network in float64 on one
    image, on the CPU: the log-probabilities' difference (standard deviation and largest, over
    pixels and classes with a probability above ``min_prob``) and the probabilities' largest.
    Another machine's float32 differs from this one's by about as much: the scale of
    ``detect.builtin.logit_jitter`` that matches it."""
    import copy

    x = network_input(rgb, size)
    m32 = copy.deepcopy(model).cpu().float()
    a = torch.log_softmax(m32(x)[0], 0).double()
    b = torch.log_softmax(m32.double()(x.double())[0], 0)
    sel = b.exp() > min_prob
    d = (a - b)[sel]
    return {"logp_sd": float(d.std()), "logp_max": float(d.abs().max()), "p_max": float((a.exp() - b.exp()).abs().max())}


def model_device(model: nn.Module) -> torch.device:
    """The device of ``model``'s first parameter (a network on one device)."""
    return next(model.parameters()).device


def decode_instances(prob: Float[np.ndarray, "C h w"], cfg: BuiltinDetectConfig, near: list[dict] | None = None
                     ) -> list[Detection]:
    """Instance masks (at the probabilities' size) from per-pixel class probabilities.

    Fronts: markers are the connected regions of sure front pixels (P(front) > 0.5 and
    P(edge) < ``edge_max``; with ``core_handle`` P(front) + P(handle) > 0.5, so a bar or knob
    across a small front does not cut its interior in two), eroded by ``erode_px`` (a thin
    bridge where an edge was only half seen breaks) and of at least ``min_seed_px``; a
    watershed of P(edge) from them floods the front, edge and handle pixels, so neighbouring
    fronts meet on their edge. Two regions whose shared boundary has a mean P(edge) below
    ``merge_edge`` (the pair's higher value at each boundary pixel pair) are one front: no
    edge was seen between them (:func:`merge_weak_boundaries`); below ``merge_edge_band`` too,
    while the merged front holds at most one handle (``merge_band_limit: one_handle``; the
    handles as below, each counted in the region holding most of its pixels) or at most two
    regions (``two_regions``). A front keeps its pixels but
    its handle's, has at least ``min_area_px`` and a mean P(front) + P(edge) of at least
    ``min_score``. Handles and objects: connected regions of their class (at least a
    quarter of ``min_area_px`` and ``min_area_px``). Scores are mean probabilities.

    ``near``: when given, every decision about a whole region whose value lies within
    :data:`DECODE_BAND` of its threshold is appended to it, as ``{"step": "merge" | "merge_band"
    | "score", "margin": value - threshold}`` (``"label"`` too for a score): a boundary's mean
    P(edge) against ``merge_edge`` (or ``merge_edge_band``), a region's score against
    ``min_score``, kept or not. Another machine's numerics could take such a decision the other
    way. (The per-pixel thresholds move a mask by a pixel where they flip, and are not listed.)"""
    from skimage.segmentation import watershed

    cls = prob.argmax(0)
    dets: list[Detection] = []
    interior = prob[FRONT] + prob[HANDLE] if cfg.core_handle else prob[FRONT]
    core = (interior > 0.5) & (prob[EDGE] < cfg.edge_max)
    if cfg.erode_px > 0:
        core = ndimage.binary_erosion(core, iterations=cfg.erode_px)
    markers, n = ndimage.label(core)
    if n:
        areas = np.bincount(markers.ravel(), minlength=n + 1)
        small = areas < cfg.min_seed_px
        small[0] = False
        markers[small[markers]] = 0
    if markers.any():
        lab = watershed(prob[EDGE], markers=markers, mask=np.isin(cls, (FRONT, EDGE, HANDLE)))
        if cfg.merge_edge > 0 or cfg.merge_edge_band > 0:
            carried, limit = None, 1
            if cfg.merge_edge_band > cfg.merge_edge and cfg.merge_band_limit == "one_handle":
                carried = handles_per_region(lab, cls == HANDLE, max(1, cfg.min_area_px // 4))
            elif cfg.merge_edge_band > cfg.merge_edge:  # two_regions
                carried, limit = np.ones(int(lab.max()) + 1, np.int64), 2
            lab = merge_weak_boundaries(lab, prob[EDGE], cfg.merge_edge, band_max=cfg.merge_edge_band,
                                        carried=carried, limit=limit, near=near)
        lab[cls == HANDLE] = 0  # a front's mask leaves its handle out, as a detector's does
        pf = prob[FRONT] + prob[EDGE]
        areas = np.bincount(lab.ravel())
        for i in np.nonzero(areas >= cfg.min_area_px)[0]:
            if i == 0:
                continue
            m = lab == i
            score = float(pf[m].mean())
            _note_near(near, "score", score, cfg.min_score, label="front")
            if score >= cfg.min_score:
                dets.append(Detection(m, "front", score))
    for c, label, min_area in ((HANDLE, "handle", max(1, cfg.min_area_px // 4)), (OBJECT, "object", cfg.min_area_px)):
        comp, k = ndimage.label(cls == c)
        if not k:
            continue
        areas = np.bincount(comp.ravel(), minlength=k + 1)
        for i in np.nonzero(areas >= min_area)[0]:
            if i == 0:
                continue
            m = comp == i
            score = float(prob[c][m].mean())
            _note_near(near, "score", score, cfg.min_score, label=label)
            if score >= cfg.min_score:
                dets.append(Detection(m, label, score))
    return dets


def _note_near(near: list[dict] | None, step: str, value: float, threshold: float, **extra) -> None:
    """Append ``step``'s decision to ``near`` when ``value`` lies within :data:`DECODE_BAND` of ``threshold``."""
    if near is not None and abs(value - threshold) < DECODE_BAND:
        near.append({"step": step, "margin": round(value - threshold, 6), **extra})


def merge_weak_boundaries(lab: Int[np.ndarray, "h w"], p_edge: Float[np.ndarray, "h w"], max_mean: float, *,
                          band_max: float = 0.0, carried: Int[np.ndarray, "n"] | None = None, limit: int = 1,
                          near: list[dict] | None = None) -> Int[np.ndarray, "h w"]:
    """``lab`` (0 background, regions 1..n) with every two 4-adjacent regions whose shared
    boundary has a mean edge probability below ``max_mean`` relabelled as one (transitively;
    the merged region keeps the smaller label). A boundary pixel pair's value is the higher of
    its two ``p_edge``: a watershed boundary runs along the ridge of ``p_edge``.

    With ``carried`` (a count per label 0..max(lab)) and ``band_max`` above ``max_mean``, a
    boundary whose mean lies between the two also merges, but only while the two regions
    together carry at most ``limit``: pairs are taken from the weakest boundary up and a merged
    region carries the sum, so no chain of merges gathers more. The decoding counts handles
    (limit 1: two doors side by side have a handle each, a front cut down its middle one or
    none) or regions (limit 2: a front is cut in two at most, a run of three doors is not one).

    >>> lab = np.array([[1, 1, 2, 2, 3]]); pe = np.array([[0, 0.1, 0.2, 0.9, 0.9]])
    >>> merge_weak_boundaries(lab, pe, 0.5).tolist()
    [[1, 1, 1, 1, 3]]
    """
    n = int(lab.max()) + 1
    keys, vals = [], []
    for a, b, ea, eb in ((lab[:, :-1], lab[:, 1:], p_edge[:, :-1], p_edge[:, 1:]),
                         (lab[:-1], lab[1:], p_edge[:-1], p_edge[1:])):
        m = (a != b) & (a > 0) & (b > 0)
        keys.append(np.minimum(a[m], b[m]).astype(np.int64) * n + np.maximum(a[m], b[m]))
        vals.append(np.maximum(ea[m], eb[m]))
    key = np.concatenate(keys)
    if not len(key):
        return lab
    pairs, inv = np.unique(key, return_inverse=True)
    mean = np.bincount(inv, weights=np.concatenate(vals)) / np.bincount(inv)
    band = band_max if carried is not None else max_mean  # no counts: the plain threshold
    for v in mean:
        _note_near(near, "merge", float(v), max_mean)
        if band > max_mean:
            _note_near(near, "merge_band", float(v), band)
    if carried is not None and len(carried) != n:
        raise ValueError(f"merge_weak_boundaries: carried has {len(carried)} entries, labels 0..{n - 1}")
    # union-find over the few region pairs (tens), weakest boundary first (ties by pair key); a
    # root is always its component's smallest label
    parent = list(range(n))
    load = [0] * n if carried is None else [int(c) for c in carried]

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for k in np.lexsort((pairs, mean)):
        if mean[k] >= max(max_mean, band):
            break
        ra, rb = root(int(pairs[k] // n)), root(int(pairs[k] % n))
        if ra == rb or (mean[k] >= max_mean and load[ra] + load[rb] > limit):
            continue
        lo, hi = min(ra, rb), max(ra, rb)
        parent[hi] = lo
        load[lo] += load[hi]
    return np.array([root(i) for i in range(n)])[lab]


def handles_per_region(lab: Int[np.ndarray, "h w"], handle: Bool[np.ndarray, "h w"], min_px: int) -> Int[np.ndarray, "n"]:
    """How many handles each region of ``lab`` carries (per label 0..max(lab); 0 for the
    background): the connected regions of ``handle`` of at least ``min_px`` pixels, each counted
    in the label holding most of its pixels (ties: the smaller label), none where that is the
    background.

    >>> lab = np.array([[1, 1, 1, 2, 2, 2]]); h = np.array([[0, 1, 0, 0, 1, 1]], bool)
    >>> handles_per_region(lab, h, 1).tolist()
    [0, 1, 1]
    """
    n = int(lab.max()) + 1
    comp, k = ndimage.label(handle)
    out = np.zeros(n, np.int64)
    if not k:
        return out
    votes = np.bincount(comp.ravel() * n + lab.ravel(), minlength=(k + 1) * n).reshape(k + 1, n)[1:]
    big = votes.sum(1) >= min_px
    owner = votes.argmax(1)[big]
    np.add.at(out, owner[owner > 0], 1)
    return out


def resize_mask(m: np.ndarray, H: int, W: int) -> np.ndarray:
    """A mask at another size, nearest neighbour (pixel centres)."""
    h, w = m.shape
    if (h, w) == (H, W):
        return m
    ii = np.minimum(((np.arange(H) + 0.5) * h / H).astype(int), h - 1)
    jj = np.minimum(((np.arange(W) + 0.5) * w / W).astype(int), w - 1)
    return m[ii[:, None], jj[None, :]]


def jitter_logits(prob: Float[np.ndarray, "C h w"], sigma: float, seed: int) -> Float[np.ndarray, "C h w"]:
    """``prob`` with Gaussian noise of ``sigma`` added to its log-probabilities and normalised
    again (a probability p_c moves by p_c (dz_c - sum_k p_k dz_k) for small noise dz: below
    sigma / 2 in standard deviation): what another machine's numerics might change, for
    stability studies (``detect.builtin.logit_jitter``)."""
    rng = np.random.default_rng(seed)
    logit = np.log(np.clip(prob, 1e-30, None)).astype(np.float64) + rng.normal(0.0, sigma, prob.shape)
    logit -= logit.max(0, keepdims=True)
    e = np.exp(logit)
    return (e / e.sum(0, keepdims=True)).astype(prob.dtype)


class BuiltinDetector:
    """The trained network with its decoding, as the ``detect`` stage runs it."""

    def __init__(self, weights: Path | Sequence[Path], cfg: BuiltinDetectConfig, device: torch.device | str = "cpu"):
        self.model, self.info = load_detector(weights)
        self.model.to(torch_device(str(device), "detect.device"))
        self.cfg = cfg
        files = [str(w) for w in weight_files(weights)]
        self.sources = {"weights": files[0] if len(files) == 1 else files}

    def __call__(self, rgb: np.ndarray, near: list[dict] | None = None) -> list[Detection]:
        """The detections of one image; ``near``: :func:`decode_instances`'s."""
        H, W = rgb.shape[:2]
        prob = class_probs(self.model, rgb, self.cfg.working_size)
        if self.cfg.logit_jitter > 0:  # seeded by the image and sigma: a view is jittered alike in every run
            seed = zlib.crc32(struct.pack("<d", self.cfg.logit_jitter), zlib.crc32(np.ascontiguousarray(rgb).tobytes()))
            prob = jitter_logits(prob, self.cfg.logit_jitter, seed)
        dets = decode_instances(prob, self.cfg, near)
        return [Detection(resize_mask(d.mask, H, W), d.label, d.score) for d in dets]
