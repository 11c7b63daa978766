"""Files between stages: captures, the scene manifest, parts files (formats: docs/formats.md)."""

from drawer_lib.errors import CaptureError
from drawer_lib.io.capture import Capture, Frame, load_capture, split_every, write_transforms
from drawer_lib.io.images import read_json, write_json
from drawer_lib.io.manifest import Manifest, read_manifest, write_manifest
from drawer_lib.io.parts import Axis, Front, IgnoreBox, Part, PartsFile, read_parts, write_parts

__all__ = [
    "Axis", "Capture", "CaptureError", "Frame", "Front", "IgnoreBox", "Manifest", "Part",
    "PartsFile", "load_capture", "read_json", "read_manifest", "read_parts", "split_every",
    "write_json", "write_manifest", "write_parts", "write_transforms",
]
