"""Stage outputs read in place of a capture's optional files (docs/formats.md#overlays).

The ``detect`` stage writes 2D detections and the ``priors`` stage monocular depth and normals,
each in the capture format's files (``detections/<stem>.png`` + ``.json``; ``mono_depth/<stem>.npy``,
``mono_normal/<stem>.npy``), inside its own folder, beside an index ``<stage>.json``::

    {"schema": "drawer.overlay/1", "stage": "detect", "model": "builtin",
     "modalities": {"detections": {"has": true, "details": {...}}},      # or {"has": false, "lacks": why}
     "frames": {"images/frame_00000.png": {"detections_path": "detections/frame_00000.png"}, ...}}

:func:`apply_overlay` returns the capture with those files in place of its own (a modality the
index marks absent is removed, so a stage never reads what the chosen model did not give), and
:func:`capture_manifest` the manifest that says so. The capture folder itself is never touched.
"""

import os
from dataclasses import replace
from pathlib import Path

from drawer_lib.errors import CaptureError
from drawer_lib.io.capture import Capture
from drawer_lib.io.images import read_json, write_json
from drawer_lib.io.manifest import Manifest, read_manifest
from drawer_lib.paths import capture_name

SCHEMA = "drawer.overlay/1"
FRAME_KEY = {"detections": "detections_path", "mono_depth": "mono_depth_file_path",
             "mono_normal": "mono_normal_file_path"}


def write_overlay(index: Path, stage: str, model: str, modalities: dict[str, dict],
                  frames: dict[str, dict[str, str]]) -> dict:
    """Write the index ``index`` (paths in ``frames`` relative to its folder); returns it.
    ``modalities``: name -> ``{"has": True, "details": {...}}`` or ``{"has": False, "lacks": why}``."""
    for name, m in modalities.items():
        if name not in FRAME_KEY:
            raise ValueError(f"overlay: unknown modality {name!r} (known: {sorted(FRAME_KEY)})")
        if not m.get("has") and not m.get("lacks"):
            raise ValueError(f"overlay: {name!r} is absent but no reason is given")
    d = {"schema": SCHEMA, "stage": stage, "model": model, "modalities": modalities, "frames": frames}
    write_json(index, d)
    return d


def read_overlay(index: Path) -> dict:
    if not index.is_file():
        stage = index.stem
        raise CaptureError(f"{index}: missing (run the {stage} stage first: dvc repro {stage}@<scene>)")
    d = read_json(index)
    if d.get("schema") != SCHEMA:
        raise CaptureError(f"{index}: not an overlay index (schema {d.get('schema')!r}, expected {SCHEMA!r})")
    for name in d.get("modalities", {}):
        if name not in FRAME_KEY:
            raise CaptureError(f"{index}: unknown modality {name!r} (known: {sorted(FRAME_KEY)})")
    return d


def apply_overlay(cap: Capture, index: Path) -> Capture:
    """``cap`` with the files listed in ``index`` in place of its own, for every modality the
    index names; a modality it marks absent is removed from every frame. Every frame of ``cap``
    must be listed for a modality that is present (else :class:`CaptureError` naming both).

    A frame's path is kept relative to the capture's root, computed between the resolved
    directories: the system resolves a ``..`` after following a symlink, so with a capture
    folder that is a link (a user's data linked into ``out/``) a path relative to the link
    itself would lead into the link target's neighbours, another scene's outputs."""
    d = read_overlay(index)
    base = index.parent.resolve()
    root = Path(cap.root).resolve()
    updates: list[dict] = [{} for _ in cap.frames]
    for name, m in d["modalities"].items():
        key = FRAME_KEY[name]
        for i, f in enumerate(cap.frames):
            if not m["has"]:
                updates[i][key] = None
                continue
            rel = d["frames"].get(f.file_path, {}).get(key)
            if rel is None:
                raise CaptureError(f"{index}: frame {f.file_path} of {cap.root} has no {key} "
                                   f"(the {d['stage']} stage ran on another capture?)")
            updates[i][key] = os.path.relpath(base / rel, root)
    frames = [replace(f, **u) for f, u in zip(cap.frames, updates)]
    return replace(cap, frames=frames, overlays=[*cap.overlays, d])


def capture_manifest(cap: Capture) -> Manifest:
    """The capture's manifest, with what its overlays give or remove (``details.<modality>.model``
    names the stage and model that gave it)."""
    m = read_manifest(cap.root / capture_name("manifest"))
    has, lacks, details = dict(m.has), dict(m.lacks), dict(m.details)
    for ov in cap.overlays:
        for name, mod in ov["modalities"].items():
            has[name] = bool(mod["has"])
            if mod["has"]:
                lacks.pop(name, None)
                details[name] = {**mod.get("details", {}), "stage": ov["stage"], "model": ov["model"]}
            else:
                lacks[name] = f"{ov['stage']}: {mod['lacks']}"
                details.pop(name, None)
    return replace(m, has=has, lacks=lacks, details=details)
