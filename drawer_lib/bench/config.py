"""Config of the articulation benchmark (conf/bench/default.yaml): which kitchens, which sensors
and geometry they are built with, and how the decision weights are fitted."""

from dataclasses import dataclass, field
from typing import Any

from drawer_lib.errors import ConfigError
from drawer_lib.synth.splits import HAND, SPLITS, missing_kitchens

GEOMETRY_KEYS = ("chamfer_l1", "fscore_1cm", "fscore_2cm")  # a kitchen's mesh against its GT (its metrics.json)


@dataclass(frozen=True)
class FitConfig:
    """The fit of the decision weights (:mod:`drawer_lib.bench.fit`): the L2 penalties tried
    (``lambdas``), ``folds`` of leave-kitchens-out cross-validation, and ``min_examples``:
    a hypothesis with fewer train fronts gets only its bias fitted (the rest: the prior).
    ``select``: ``one_se`` (the largest penalty whose CV accuracy is within one standard error
    of the best: differences the folds cannot resolve do not pick a looser model) or ``best``.
    ``centre``: what the penalty pulls the fitted weights towards, ``zero`` or the ``prior``."""

    lambdas: list[float] = field(default_factory=lambda: [1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1])
    folds: int = 5
    min_examples: int = 10
    select: str = "one_se"
    centre: str = "zero"

    def __post_init__(self):
        if not self.lambdas or any(not lam >= 0 for lam in self.lambdas):
            raise ConfigError(f"bench.fit.lambdas = {self.lambdas}: need at least one penalty >= 0")
        if self.folds < 2:
            raise ConfigError(f"bench.fit.folds = {self.folds} must be >= 2")
        if self.min_examples < 0:
            raise ConfigError(f"bench.fit.min_examples = {self.min_examples} must be >= 0")
        if self.select not in ("one_se", "best"):
            raise ConfigError(f"bench.fit.select = {self.select!r} must be one_se or best")
        if self.centre not in ("zero", "prior"):
            raise ConfigError(f"bench.fit.centre = {self.centre!r} must be zero or prior")


def _check_indices(key: str, ks: list) -> None:
    """``bench.<key>`` must be a non-empty list of distinct kitchen indices >= 0."""
    if not ks or len(set(ks)) != len(ks) or any(isinstance(k, bool) or not isinstance(k, int) or k < 0 for k in ks):
        raise ConfigError(f"bench.{key} = {ks}: need a list of distinct kitchen indices >= 0")


@dataclass(frozen=True)
class BenchConfig:
    """The benchmark: kitchen ``k`` of every split in ``splits`` for each ``k`` in ``kitchens``,
    its sensor noise and sampling drawn from ``seed`` (its own: a seed study of a scene leaves
    the benchmark and the decision weights as they are)
    (:func:`drawer_lib.synth.splits.split_synth`: the split's sizes, styles and counts over the
    scene ``base_scene``), captured with the sensors ``detections`` / ``depth``
    (conf/capture/<group>/<name>.yaml) and the geometry ``sdf`` (conf/sdf/<name>.yaml); the
    pipeline's mesh, decompose and articulate configs. dvc.yaml passes these choices to the
    ``bench_kitchen`` stage as Hydra overrides; the stage checks that it got them. ``camera``:
    keys of the synth camera block set over the split's (null: the split's own frames; smoke
    tests and the ``quick`` experiment shrink them). ``hand_kitchens``: the kitchens of the
    ``hand`` split (written by hand, never tuned on) that the ``bench_hand`` stages build the
    same way and ``bench_eval_hand`` scores (its kitchens differ in number from the procedural
    splits', so they are not a row of the ``bench_kitchen`` matrix)."""

    seed: int = 0
    kitchens: list[int] = field(default_factory=lambda: list(range(20)))
    splits: list[str] = field(default_factory=lambda: ["train", "test"])
    hand_kitchens: list[int] = field(default_factory=lambda: list(range(len(HAND))))
    base_scene: str = "kitchen_small"
    detections: str = "noisy_generic"
    depth: str = "sensor"
    sdf: str = "tsdf"
    camera: dict[str, Any] | None = None
    fit: FitConfig = field(default_factory=FitConfig)

    def __post_init__(self):
        _check_indices("kitchens", self.kitchens)
        if "train" not in self.splits or any(s not in SPLITS for s in self.splits):
            raise ConfigError(f"bench.splits = {self.splits}: splits of {SPLITS}, the train split among them "
                              "(the decision weights are fitted on it)")
        why = next((w for w in (missing_kitchens(sp, self.kitchens) for sp in self.splits) if w), None)
        if why:
            raise ConfigError(f"bench.splits: {why}; bench.kitchens = {self.kitchens}")
        _check_indices("hand_kitchens", self.hand_kitchens)
        why = missing_kitchens("hand", self.hand_kitchens)
        if why:
            raise ConfigError(f"bench.hand_kitchens = {self.hand_kitchens}: {why}")

    def split_kitchens(self, split: str) -> list[int]:
        """The kitchens the benchmark scores of ``split``: ``hand_kitchens`` for the hand split
        (unless ``splits`` lists it), ``kitchens`` for the others."""
        if split == "hand" and split not in self.splits:
            return self.hand_kitchens
        if split not in self.splits:
            raise ConfigError(f"bench: split {split!r} is not scored (bench.splits = {self.splits}, or hand)")
        return self.kitchens
