"""Configs of the ``detect`` and ``priors`` stages (conf/detect/, conf/priors/) and of the built-in
detector's training (conf/detector/). Sizes in pixels."""

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

from drawer_lib.errors import ConfigError
from drawer_lib.hub import HubModel

DETECT_MODELS = ("auto", "capture", "none", "builtin", "owlv2_sam")
PRIORS_MODELS = ("auto", "capture", "none", "depth_anything")


@dataclass(frozen=True)
class FoundationDetectConfig:
    """The paper's open-vocabulary detection then segmentation: OWLv2 boxes for each text prompt
    (a box above ``box_threshold``; boxes of one label overlapping by more than ``nms_iou`` are
    one), then SAM's mask inside each box. ``prompts`` maps the label a detection gets to the
    prompts that find it (DRAWER: "drawer", "cabinet door", "handle")."""

    detector: HubModel = field(default_factory=lambda: HubModel("google/owlv2-base-patch16-ensemble"))
    segmenter: HubModel = field(default_factory=lambda: HubModel("facebook/sam-vit-base"))
    prompts: dict[str, list[str]] = field(default_factory=lambda: {
        "drawer": ["drawer"], "door": ["cabinet door", "cupboard door"], "handle": ["handle", "knob"],
        "object": ["cup", "bowl", "bottle", "kettle"]})
    box_threshold: float = 0.2
    nms_iou: float = 0.5
    max_per_frame: int = 40
    min_area_px: int = 30

    def __post_init__(self):
        if not self.prompts or not all(self.prompts.values()):
            raise ConfigError("detect.foundation.prompts: every label needs at least one prompt")
        if not 0 < self.nms_iou <= 1:
            raise ConfigError(f"detect.foundation.nms_iou = {self.nms_iou}: must be in (0, 1]")


@dataclass(frozen=True)
class BuiltinDetectConfig:
    """The built-in detector at inference: images scaled so their long side is ``working_size``
    (what it was trained at), instances decoded as
    :func:`~drawer_lib.detect.builtin.decode_instances` says (sizes at the working size). The
    decoding's values were chosen on train-split kitchens the fit does not use."""

    working_size: int = 256
    edge_max: float = 0.2
    core_handle: bool = True
    erode_px: int = 2
    min_seed_px: int = 15
    min_area_px: int = 40
    min_score: float = 0.6
    merge_edge: float = 0.5
    merge_edge_band: float = 0.0  # above merge_edge: boundaries up to this merge too, within merge_band_limit
    merge_band_limit: str = "one_handle"  # one_handle | two_regions: what a front merged in the band may hold
    # for stability studies only: Gaussian noise of this sigma on the network's log-probabilities
    # before decoding (what another machine's numerics might change; 0 in every real run)
    logit_jitter: float = 0.0

    def __post_init__(self):
        if not (self.logit_jitter >= 0 and math.isfinite(self.logit_jitter)):
            raise ConfigError(f"detect.builtin.logit_jitter = {self.logit_jitter}: must be a finite value >= 0")
        if self.merge_band_limit not in ("one_handle", "two_regions"):
            raise ConfigError(f"detect.builtin.merge_band_limit = {self.merge_band_limit!r}: one_handle or two_regions")
        for k in ("edge_max", "min_score", "merge_edge", "merge_edge_band"):
            if not 0 <= getattr(self, k) <= 1:
                raise ConfigError(f"detect.builtin.{k} = {getattr(self, k)}: a probability, must be in [0, 1]")


@dataclass(frozen=True)
class DetectConfig:
    """``model``: ``capture`` (the capture's own detections: a synthetic scene's simulated
    detector, or what a capture folder carries), ``none``, ``builtin`` (the detector the
    ``detector`` stage trains), ``owlv2_sam`` (``foundation``), ``auto`` (``capture`` when the
    capture has detections, else ``builtin``). Weights are never downloaded unless
    ``allow_download``. ``device``: where the built-in or foundation network runs (``cpu``,
    ``cuda``, ``cuda:<index>``; :func:`~drawer_lib.devices.torch_device` checks it first)."""

    model: str = "auto"
    allow_download: bool = False
    device: str = "cpu"
    builtin: BuiltinDetectConfig = field(default_factory=BuiltinDetectConfig)
    foundation: FoundationDetectConfig = field(default_factory=FoundationDetectConfig)

    def __post_init__(self):
        if self.model not in DETECT_MODELS:
            raise ConfigError(f"detect.model = {self.model!r}: unknown (known: {list(DETECT_MODELS)})")


@dataclass(frozen=True)
class PriorsConfig:
    """``model``: ``capture`` (the capture's own monocular maps), ``none``, ``auto`` (``capture``
    when the capture has them, else ``none``: a foundation model is chosen, not assumed),
    ``depth_anything``
    (relative depth from Depth Anything through ``transformers``, at ``working_size`` on the
    long side; normals read off that depth). A relative model's inverse depth d is stored as
    depth 1 / (d / d_99 + ``inverse_shift``) (d_99: its 99th percentile), which is affine in the
    true depth only where the model's shift is small; a metric model's depth is stored as is."""

    model: str = "auto"
    allow_download: bool = False
    device: str = "cpu"
    depth_model: HubModel = field(default_factory=lambda: HubModel("depth-anything/Depth-Anything-V2-Small-hf"))
    working_size: int = 518
    inverse_shift: float = 0.05
    normals: bool = True

    def __post_init__(self):
        if self.model not in PRIORS_MODELS:
            raise ConfigError(f"priors.model = {self.model!r}: unknown (known: {list(PRIORS_MODELS)})")
        if self.inverse_shift <= 0:
            raise ConfigError(f"priors.inverse_shift = {self.inverse_shift}: must be > 0")


@dataclass(frozen=True)
class DetectorTrainConfig:
    """The built-in detector's fit (conf/detector/): every ``frame_every``-th view of the train
    split's kitchens ``kitchens`` rendered at ``working_size`` on the long side, labelled from the
    renderer's segmentation (background, front, a front's ``edge_px`` border, handle, object);
    ``steps`` of Adam at ``lr`` on random ``crop`` crops, ``batch`` at a time (colour and scale
    jittered by ``color_jitter`` and ``scale_jitter``: :func:`drawer_lib.detect.train._crop_batch`);
    scored on the test split's kitchens ``eval_kitchens`` (never trained or tuned on). ``layout``:
    keys of the kitchens' ``layout`` block (:class:`~drawer_lib.synth.config.LayoutConfig`)
    merged over each fit kitchen's, never over the kitchens it is scored on: domain
    randomisation, the fit drawing sizes and handle rates the train split does not (its keys
    are checked when a stage starts, :func:`drawer_lib.detect.train.check_layouts`).
    ``layout_beside``: keys of a layout block merged over each fit kitchen's (after ``layout``)
    for a second rendering of it that the fit trains on beside the first, its crops drawn from
    both (empty: none; the kitchens as drawn stay in the fit whole).
    ``seeds``: one fit from each seed (the ``detector_fit@<seed>`` stage each, cached apart, so
    adding a seed fits only that one), averaged as one ensemble whose class probabilities are
    their mean (the ``detector`` stage); a fit reads only its own seed, never this list.
    ``average_steps`` > 0: the ``detector`` stage trains each fit on for that many steps more
    (Adam afresh, its rate raised linearly to ``average_lr`` over ``average_warmup`` steps, then
    held) and takes the mean of its weights over every step after the warm-up (stochastic
    weight averaging: :func:`drawer_lib.detect.train.average_fit`); 0: each fit as it is.
    ``average_layout``: keys of a layout block merged over each fit kitchen's (after ``layout``)
    for a second rendering of it that only the averaging trains on, beside the first: the
    averaging draws its crops from both (domain randomisation after the fit, which stays as it
    is; empty: none, the averaging sees what the fit saw). ``checkpoint_every`` > 0: a fit keeps
    its state (weights, optimiser, schedule, random streams, curve) every that many steps and
    when it is interrupted, and a rerun with the same settings and views goes on from there to
    the same weights as an uninterrupted fit (:func:`drawer_lib.detect.train.fit_detector`; a
    job past its time limit on a cluster loses at most that many steps), and so does the
    ``detector`` stage's averaging (:func:`drawer_lib.detect.train.average_fit`); 0: never. ``device``:
    where the fit, the averaging and the scoring run the network (``cpu``, ``cuda``,
    ``cuda:<index>``): the same initial weights and crops on every device, different last bits
    (so a fit parameter: changing it refits), the weights written for the CPU. ``memory_format``:
    how the network lays out its weights and feature maps while it is fitted, averaged and run
    (:class:`~drawer_lib.detect.builtin.TinyUNet`; recorded in the weights file, which later
    stages run it with): ``channels_last`` (NHWC) trains about 1.4x faster on a CPU than
    ``contiguous``, the same arithmetic in another order, so its last bits differ (a fit
    parameter: changing it refits); ``contiguous`` is the default: the two channels-last fits
    scored found fewer parts on the hand-written tuning kitchens than the three contiguous ones
    (docs/perception.md)."""

    # keys only the ``detector`` stage reads, never a fit: changing them must not refit
    NOT_FIT_KEYS: ClassVar[frozenset[str]] = frozenset({"seeds", "average_steps", "average_lr", "average_warmup",
                                                     "average_layout", "checkpoint_every"})

    kitchens: list[int] = field(default_factory=lambda: list(range(16)) + list(range(32, 80)))
    eval_kitchens: list[int] = field(default_factory=lambda: list(range(6)))
    frame_every: int = 2
    working_size: int = 256
    edge_px: int = 2
    width: int = 24
    steps: int = 5000
    batch: int = 12
    crop: int = 128
    lr: float = 3e-3
    color_jitter: float = 0.0
    scale_jitter: float = 1.0
    log_every: int = 100
    iou_match: float = 0.5
    layout: dict[str, Any] = field(default_factory=dict)
    layout_beside: dict[str, Any] = field(default_factory=dict)
    seeds: list[int] = field(default_factory=lambda: [0])
    average_steps: int = 1000
    average_lr: float = 1e-3
    average_warmup: int = 100
    average_layout: dict[str, Any] = field(default_factory=dict)
    checkpoint_every: int = 250
    device: str = "cpu"
    memory_format: str = "contiguous"

    def __post_init__(self):
        if not self.kitchens:
            raise ConfigError("detector.kitchens: at least one train kitchen is needed")
        seeds = list(self.seeds)
        if not 1 <= len(seeds) <= 8 or len(set(seeds)) != len(seeds) or min(seeds, default=0) < 0:
            raise ConfigError(f"detector.seeds = {seeds}: 1 to 8 distinct seeds >= 0 are needed (each is a fit of its own)")
        if not 0 <= self.color_jitter < 2:
            raise ConfigError(f"detector.color_jitter = {self.color_jitter}: must be in [0, 2)")
        if not 1 <= self.scale_jitter <= 4:
            raise ConfigError(f"detector.scale_jitter = {self.scale_jitter}: must be in [1, 4]")
        if self.average_steps < 0 or self.average_warmup < 0 or 0 < self.average_steps <= self.average_warmup:
            raise ConfigError(f"detector.average_steps = {self.average_steps}, average_warmup = {self.average_warmup}: "
                              "need steps >= 0 and 0 <= warmup < steps (steps 0: no averaging)")
        if self.average_layout and not self.average_steps:
            raise ConfigError(f"detector.average_layout = {dict(self.average_layout)} needs detector.average_steps > 0 "
                              "(only the averaging trains on it)")
        if self.checkpoint_every < 0:
            raise ConfigError(f"detector.checkpoint_every = {self.checkpoint_every}: must be >= 0 (0: never)")
        if not self.average_lr > 0:
            raise ConfigError(f"detector.average_lr = {self.average_lr}: must be > 0")
        if self.memory_format not in ("contiguous", "channels_last"):
            raise ConfigError(f"detector.memory_format = {self.memory_format!r}: must be contiguous or channels_last")
        if self.crop > self.working_size:
            raise ConfigError(f"detector.crop = {self.crop} exceeds detector.working_size = {self.working_size}")
