"""Where every output of the pipeline lives: the one place that spells a file or folder name.

Outputs of scene ``S`` live under ``<paths.out>/S/`` (``paths.out`` is a config key, default
``out``); :data:`LAYOUT` gives every name below that, relative to the scene folder, by stage.
``dvc.yaml`` reads it (``vars: - drawer_lib/paths.py:LAYOUT``, then ``${LAYOUT.mesh.mesh}``),
stages and tests go through :class:`ScenePaths`, and a stage writes its files through
``run.out(key)`` (:meth:`drawer_lib.runner.StageRun.out`). The names are literals so that DVC,
which parses this file without running it, can read them.

A geometry comparison variant ``v`` (the ``geometry@S-v`` stages) keeps its ``sdf/`` and
``mesh/`` under ``S/geometry/v/``; an appearance variant ``v`` writes ``S/appearance/v/``.
"""

from dataclasses import dataclass
from pathlib import Path

LAYOUT = {
    "capture": {  # the capture format (docs/formats.md#capture); every sub-folder is its own DVC output
        "dir": "capture",
        "transforms": "capture/transforms.json",
        "manifest": "capture/manifest.json",
        "images": "capture/images",
        "depth": "capture/depth",
        "mono_depth": "capture/mono_depth",
        "mono_normal": "capture/mono_normal",
        "detections": "capture/detections",
        "sparse": "capture/sparse",
        "sparse_points": "capture/sparse/points3d.ply",
        "gt": "capture/gt",
        "gt_parts": "capture/gt/parts.json",
        "gt_mesh": "capture/gt/mesh.ply",
        "gt_mesh_instances": "capture/gt/mesh_instances.npy",
        "gt_instances": "capture/gt/instances",
    },
    # what a 2D detector and a monocular estimator give each frame (the capture format's files),
    # with an index of which frame has which file (drawer_lib/io/overlay.py)
    "detect": {"dir": "detect", "index": "detect/detect.json", "detections": "detect/detections"},
    "priors": {"dir": "priors", "index": "priors/priors.json", "mono_depth": "priors/mono_depth",
               "mono_normal": "priors/mono_normal"},
    "sdf": {"dir": "sdf", "field": "sdf/field.pt"},
    "mesh": {"dir": "mesh", "mesh": "mesh/mesh.ply"},
    "geometry": {"dir": "geometry"},  # geometry/<variant>/ holds sdf/ and mesh/ as above
    "decompose": {"dir": "decompose", "segments": "decompose/segments.json",
                  "face_labels": "decompose/face_labels.npz", "mesh": "decompose/perception_mesh.ply"},
    "articulate": {"dir": "articulate", "parts": "articulate/parts.json", "decisions": "articulate/decisions.json"},
    "evaluate": {"dir": "evaluate", "matches": "evaluate/matches.json"},
    "complete": {"dir": "complete", "index": "complete/complete.json", "meshes": "complete/meshes",
                 "collision": "complete/collision", "gaussians": "complete/gaussians"},
    "robot": {"dir": "robot", "attempts": "robot/attempts.json", "dataset": "robot/dataset"},
    "simulate": {"dir": "simulate", "tracks": "simulate/tracks.npz", "motion": "simulate/motion.json"},
    "stability": {"dir": "stability", "matrix": "stability/matrix.csv", "heatmap": "stability/heatmap.png",
                  "choice": "stability/choice.json"},
    "twin": {"dir": "twin", "mjcf": "twin/scene.xml", "mjcf_assets": "twin/assets", "urdf": "twin/urdf/scene.urdf",
             "urdf_meshes": "twin/urdf/meshes", "usd": "twin/scene.usda", "index": "twin/twin.json",
             "gaussians": "twin/gaussians", "checks": "twin/checks.json", "glb": "twin/visual.glb",
             "recording": "twin/open_parts.html", "recording_viser": "twin/open_parts.viser", "renders": "twin/renders",
             "renders_index": "twin/renders/index.json", "render_scores": "twin/renders/scores.json",
             "contact_sheet": "twin/renders/contact_sheet.png"},
    "appearance": {"dir": "appearance", "model": "model", "renders": "renders",  # inside appearance/<variant>/
                   "gaussians": "model/gaussians.ply", "binding": "model/binding.npz",
                   "anchor_mesh": "model/anchor_mesh.ply", "textured_mesh": "model/textured_mesh.ply"},
    "report": {"table": "table.md", "table_json": "table.json", "plot": "curves.png",  # inside reports/<name>/
               "index": "index.html", "summary": "summary.md", "extremes": "extremes.json"},  # in reports/
    "metrics": "metrics.json",  # in every stage folder
    "curve": "curve.csv",  # in every iterative stage's folder
}

# The articulation benchmark, under ``paths.bench``: kitchen ``k`` of split ``s`` is a scene folder
# ``<s>/<kitchen_prefix><k>/`` laid out as LAYOUT (its capture, sdf, mesh, decompose and articulate
# with the prior weights); ``fit/`` the decision weights fitted on the train split; ``eval/<s>/``
# each split's kitchens articulated with them (``kitchens/``), scored, and the split's table.
BENCH = {
    "kitchen_prefix": "kitchen_",
    "fit": "fit",
    "weights": "fit/weights.json",
    "cv": "fit/cv.csv",
    "cases": "fit/cases.json",
    "eval": "eval",
    "kitchens": "kitchens",  # in eval/<split>/: each kitchen's articulation with the fitted weights
    "rows": "rows.json",  # in eval/<split>/: each kitchen's scores
    "detector": "detector",  # the built-in 2D detector trained on the train split's renders
    "detector_weights": "detector/weights.pt",
    "detector_score": "detector_score",  # the detector scored as the pipeline decodes it (detect.builtin)
    "detector_fits": "detector_fits",  # one folder per fit: <seed>/ with weights.pt, curve.csv, metrics.json
    "detector_fit_weights": "weights.pt",  # in detector_fits/<seed>/
    "detector_fit_resume": "detector_fit_resume",  # <seed>.pt: an unfinished fit's last state (no DVC output)
}

CAPTURE_DIRS = ("images", "depth", "mono_depth", "mono_normal", "detections", "gt", "sparse")


def bench_name(key: str) -> str:
    """A benchmark file's name inside its folder: ``bench_name("weights")`` -> ``weights.json``."""
    return BENCH[key].rsplit("/", 1)[-1]


def capture_name(key: str) -> str:
    """A name inside the capture folder, e.g. ``capture_name("gt_mesh")`` -> ``gt/mesh.ply``."""
    return LAYOUT["capture"][key].split("/", 1)[1]


def stage_name(stage: str, key: str) -> str:
    """The name of output ``key`` inside its stage folder: ``stage_name("sdf", "field")`` ->
    ``field.pt``; ``metrics`` and ``curve`` for any stage."""
    if key in ("metrics", "curve"):
        return LAYOUT[key]
    rel = LAYOUT[stage][key]
    head = LAYOUT[stage]["dir"] + "/"
    return rel[len(head):] if rel.startswith(head) else rel


@dataclass(frozen=True)
class ScenePaths:
    """Absolute paths of one scene's outputs under ``out`` (the ``paths.out`` root). With
    ``geometry_variant`` the ``sdf`` and ``mesh`` stages live under ``geometry/<variant>/``;
    everything else (the capture first) is the scene's own."""

    out: Path
    scene: str
    geometry_variant: str | None = None

    @property
    def root(self) -> Path:
        return Path(self.out) / self.scene

    def stage_dir(self, stage: str) -> Path:
        if self.geometry_variant is not None and stage in ("sdf", "mesh"):
            return self.root / LAYOUT["geometry"]["dir"] / self.geometry_variant / LAYOUT[stage]["dir"]
        return self.root / LAYOUT[stage]["dir"]

    def file(self, stage: str, key: str) -> Path:
        return self.stage_dir(stage) / stage_name(stage, key)

    def metrics(self, stage: str) -> Path:
        return self.stage_dir(stage) / LAYOUT["metrics"]

    def appearance_dir(self, variant: str) -> Path:
        return self.root / LAYOUT["appearance"]["dir"] / variant

    # the files later stages read
    @property
    def capture(self) -> Path:
        return self.stage_dir("capture")

    @property
    def field(self) -> Path:
        return self.file("sdf", "field")

    @property
    def mesh(self) -> Path:
        return self.file("mesh", "mesh")

    @property
    def detect(self) -> Path:
        return self.stage_dir("detect")

    @property
    def priors(self) -> Path:
        return self.stage_dir("priors")

    @property
    def decompose(self) -> Path:
        return self.stage_dir("decompose")

    @property
    def parts(self) -> Path:
        return self.file("articulate", "parts")


@dataclass(frozen=True)
class BenchPaths:
    """Absolute paths of the articulation benchmark under ``root`` (the ``paths.bench`` root)."""

    root: Path

    def kitchen(self, split: str, k: int) -> ScenePaths:
        """Kitchen ``k`` of ``split`` as a scene: ``<root>/<split>/kitchen_<k>/<stage>/...``."""
        return ScenePaths(Path(self.root) / split, f"{BENCH['kitchen_prefix']}{int(k)}")

    def split(self, split: str) -> Path:
        """The folder of a split's kitchens (what the fit and the evaluation depend on)."""
        return Path(self.root) / split

    @property
    def fit(self) -> Path:
        return Path(self.root) / BENCH["fit"]

    @property
    def weights(self) -> Path:
        return Path(self.root) / BENCH["weights"]

    @property
    def detector(self) -> Path:
        return Path(self.root) / BENCH["detector"]

    @property
    def detector_weights(self) -> Path:
        return Path(self.root) / BENCH["detector_weights"]

    @property
    def detector_score(self) -> Path:
        return Path(self.root) / BENCH["detector_score"]

    def detector_fit(self, seed: int) -> Path:
        """One fit of the built-in detector: ``detector_fits/<seed>/`` (its ``weights.pt``,
        ``curve.csv``, ``metrics.json``); the ``detector`` stage averages the listed seeds' fits."""
        return Path(self.root) / BENCH["detector_fits"] / str(int(seed))

    def detector_fit_resume(self, seed: int) -> Path:
        """An unfinished fit's last state, ``detector_fit_resume/<seed>.pt``: the
        ``detector_fit@<seed>`` stage goes on from it and removes it when the fit is done. Outside
        the stage's output, which a rerun replaces, and outside every stage's dependencies."""
        return Path(self.root) / BENCH["detector_fit_resume"] / f"{int(seed)}.pt"

    def eval(self, split: str) -> Path:
        """The evaluation of ``split``: ``eval/<split>/`` (its table, ``metrics.json``, rows and
        under ``kitchens/`` each kitchen's articulation with the fitted weights, as a scene
        folder)."""
        return Path(self.root) / BENCH["eval"] / split
