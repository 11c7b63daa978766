"""The ``dir`` source: validate an existing capture folder and copy it into the standard layout."""

import shutil
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from drawer_lib.capture.config import DirSource
from drawer_lib.io.capture import Frame, load_capture, write_transforms
from drawer_lib.io.images import CaptureError
from drawer_lib.io.manifest import Manifest
from drawer_lib.io.parts import read_parts


def resolve_input(root: Path, p: str, what: str) -> Path:
    """An input path of a scene config, relative to the project root ``root``."""
    if not p:
        raise CaptureError(f"{what}: no path given")
    path = Path(p)
    path = path if path.is_absolute() else root / path
    if not path.exists():
        raise CaptureError(f"{what}: {path} does not exist")
    return path


def import_dir_capture(scene: str, src: DirSource, test_every: int, out: Path, root: Path,
                       progress: Callable = lambda it, **kw: it) -> tuple[Manifest, dict]:
    """Validate the capture at ``src.path`` and copy it to ``out`` with standard folder names
    (images/, depth/, mono_depth/, mono_normal/, detections/, gt/, sparse/). Contents are kept
    as they are; only file locations (and the paths in transforms.json) change."""
    path = resolve_input(root, src.path, f"scene {scene}: dir.path")
    cap = load_capture(path, check_files=True, default_test_every=test_every, progress=True)
    stems: dict[str, str] = {}
    for fr in cap.frames:
        if fr.stem in stems:
            raise CaptureError(f"{path / 'transforms.json'}: frames {stems[fr.stem]} and {fr.file_path} share the stem {fr.stem!r}")
        stems[fr.stem] = fr.file_path

    new_frames = []
    for fr in progress(cap.frames, desc="copy frames", total=len(cap.frames)):
        s = fr.stem
        rel = {"file_path": f"images/{s}{Path(fr.file_path).suffix.lower()}"}
        shutil.copy2(path / fr.file_path, out / rel["file_path"])
        for key, folder, ext in (("depth_file_path", "depth", ".png"), ("mono_depth_file_path", "mono_depth", ".npy"),
                                 ("mono_normal_file_path", "mono_normal", ".npy"), ("detections_path", "detections", ".png")):
            v = getattr(fr, key)
            if v is None:
                continue
            rel[key] = f"{folder}/{s}{ext}"
            shutil.copy2(path / v, out / rel[key])
            if key == "detections_path":
                shutil.copy2((path / v).with_suffix(".json"), (out / rel[key]).with_suffix(".json"))
        new_frames.append(Frame(rel["file_path"], fr.c2w_gl, rel.get("depth_file_path"), rel.get("mono_depth_file_path"),
                                rel.get("mono_normal_file_path"), rel.get("detections_path")))

    extra = dict(cap.extra)
    has_sparse = False
    if "ply_file_path" in extra:
        ply = path / extra["ply_file_path"]
        if not ply.is_file():
            raise CaptureError(f"{path / 'transforms.json'}: ply_file_path {extra['ply_file_path']!r} is missing")
        shutil.copy2(ply, out / "sparse" / "points3d.ply")
        extra["ply_file_path"] = "sparse/points3d.ply"
        has_sparse = True

    gt_kinds = None
    if (path / "gt").is_dir():
        if (path / "gt" / "parts.json").is_file():
            gt_kinds = read_parts(path / "gt" / "parts.json").kinds()
        shutil.copytree(path / "gt", out / "gt", dirs_exist_ok=True)
    has_gt = gt_kinds is not None

    new = replace(cap, root=out, frames=new_frames, extra=extra)
    write_transforms(new)

    def every(key: str) -> bool:
        return new.has(key)

    some = {k: any(getattr(f, k) is not None for f in new.frames) for k in
            ("depth_file_path", "mono_depth_file_path", "mono_normal_file_path", "detections_path")}
    for k, v in some.items():
        if v and not every(k):
            raise CaptureError(f"{path / 'transforms.json'}: some frames have {k} and some do not")
    manifest = Manifest(
        scene=scene, source="dir", n_frames=len(new.frames), n_train=len(new.train), n_test=len(new.test),
        width=new.intrinsics.width, height=new.intrinsics.height,
        has={"rgb": True, "depth": every("depth_file_path"), "mono_depth": every("mono_depth_file_path"),
             "mono_normal": every("mono_normal_file_path"), "detections": every("detections_path"),
             "sparse_points": has_sparse, "gt": has_gt},
        lacks={k: f"{path} has no {k}" for k in ("depth", "mono_depth", "mono_normal", "detections", "sparse_points")}
        | {"gt": f"{path} has no gt/parts.json"},
        details={"poses": {"kind": "given", "source": str(path)},
                 "intrinsics": {"distortion": list(new.intrinsics.dist)}},
        world_frame={"metric_scale": src.metric_scale, "gravity": src.gravity,
                     "how": f"as given by {path}; metric scale and gravity as stated in the scene config"},
        gt_part_kinds=gt_kinds,
    )
    return manifest, {"n_frames": len(new.frames), "n_train": len(new.train), "n_test": len(new.test)}
