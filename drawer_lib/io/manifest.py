"""The scene manifest ``capture/manifest.json``: what a capture has, and what it lacks and why.

Later stages ask the manifest before doing work (``manifest.missing("depth")`` returns the reason
depth is absent, or None), so a scene only runs what it needs and every skip has a reason.

Requirements a stage can ask for:
- a modality: ``rgb``, ``depth`` (metric sensor depth), ``mono_depth``, ``mono_normal``,
  ``detections``, ``sparse_points`` (SfM points), ``gt``;
- a world-frame property: ``metric_scale``, ``gravity``;
- a ground-truth part kind: ``gt:revolute``, ``gt:prismatic``, ``gt:rigid``.
"""

from dataclasses import dataclass, field
from pathlib import Path

from drawer_lib.errors import CaptureError
from drawer_lib.io.images import read_json, write_json
from drawer_lib.paths import capture_name

SCHEMA = "drawer.manifest/1"
MODALITIES = ("rgb", "depth", "mono_depth", "mono_normal", "detections", "sparse_points", "gt")


@dataclass(frozen=True)
class Manifest:
    scene: str
    source: str  # synth | video | dir
    n_frames: int
    n_train: int
    n_test: int
    width: int
    height: int
    has: dict[str, bool]
    lacks: dict[str, str]  # modality -> why it is absent
    details: dict[str, dict] = field(default_factory=dict)  # per-modality facts (noise model, ...)
    world_frame: dict = field(default_factory=dict)  # metric_scale, gravity (bools) and how
    gt_part_kinds: dict[str, int] | None = None  # only when gt is present

    def __post_init__(self):
        for m in MODALITIES:
            if m not in self.has:
                raise ValueError(f"manifest: modality {m!r} not stated")
            if not self.has[m] and not self.lacks.get(m):
                raise ValueError(f"manifest: {m!r} is absent but no reason is given")

    def missing(self, requirement: str) -> str | None:
        """None when ``requirement`` is met, else the reason it is not (see module doc)."""
        if requirement in MODALITIES:
            return None if self.has[requirement] else f"capture has no {requirement}: {self.lacks[requirement]}"
        if requirement in ("metric_scale", "gravity"):
            if self.world_frame.get(requirement, False):
                return None
            return f"capture frame has no {requirement}: {self.world_frame.get('how', 'unknown')}"
        if requirement.startswith("gt:"):
            if not self.has["gt"]:
                return f"capture has no gt: {self.lacks['gt']}"
            kind = requirement[3:]
            if (self.gt_part_kinds or {}).get(kind, 0) > 0:
                return None
            return f"ground truth has no {kind} parts"
        raise KeyError(f"unknown manifest requirement {requirement!r}")

    def first_missing(self, *requirements: str) -> str | None:
        for r in requirements:
            why = self.missing(r)
            if why:
                return why
        return None

    def to_json(self) -> dict:
        return {
            "schema": SCHEMA,
            "scene": self.scene,
            "source": self.source,
            "frames": {"total": self.n_frames, "train": self.n_train, "test": self.n_test},
            "image_size": [self.width, self.height],
            "has": {m: bool(self.has[m]) for m in MODALITIES},
            "lacks": {m: self.lacks[m] for m in MODALITIES if not self.has[m]},
            "details": self.details,
            "world_frame": self.world_frame,
            "gt_part_kinds": self.gt_part_kinds,
        }

    @staticmethod
    def from_json(d: dict, source: str = capture_name("manifest")) -> "Manifest":
        if d.get("schema") != SCHEMA:
            raise CaptureError(f"{source}: schema {d.get('schema')!r}, expected {SCHEMA!r}")
        try:
            return Manifest(
                scene=d["scene"], source=d["source"],
                n_frames=d["frames"]["total"], n_train=d["frames"]["train"], n_test=d["frames"]["test"],
                width=d["image_size"][0], height=d["image_size"][1],
                has=d["has"], lacks=d.get("lacks", {}), details=d.get("details", {}),
                world_frame=d.get("world_frame", {}), gt_part_kinds=d.get("gt_part_kinds"),
            )
        except (KeyError, TypeError, IndexError, ValueError) as e:
            raise CaptureError(f"{source}: malformed manifest ({e})") from e


def read_manifest(path: Path) -> Manifest:
    return Manifest.from_json(read_json(path), str(path))


def write_manifest(path: Path, m: Manifest) -> None:
    write_json(path, m.to_json())
