"""The ``capture`` stage's work: dispatch on the scene's source, write the standard layout."""

from collections.abc import Callable
from pathlib import Path

import numpy as np

from drawer_lib.capture.config import CaptureConfig, SceneConfig
from drawer_lib.capture.dirsource import import_dir_capture
from drawer_lib.io.manifest import Manifest, write_manifest
from drawer_lib.paths import CAPTURE_DIRS, capture_name


def build_capture(scene: str, cfg: SceneConfig, cap: CaptureConfig, out: Path, rng: np.random.Generator,
                  root: Path, progress: Callable = lambda it, **kw: it) -> tuple[Manifest, dict]:
    """Write the capture of ``scene`` into the empty folder ``out``; return (manifest, metrics).

    ``root`` is the project root that input paths of ``video`` / ``dir`` scenes are relative to.
    Raises CaptureError / ConfigError (naming the file, frame or key) on bad input.
    """
    # every capture folder has all sub-folders (possibly empty: manifest.json says what exists),
    # so the DVC stage declares each as its own output and later stages depend only on what they read
    for d in CAPTURE_DIRS:
        (out / capture_name(d)).mkdir(parents=True, exist_ok=True)
    test_every = cap.split.test_every
    if cfg.source == "synth":
        from drawer_lib.synth.capture import Sensors, render_synth_capture

        sensors = Sensors(cap.depth, cap.mono, cap.detections, cap.render)
        manifest, metrics = render_synth_capture(scene, cfg.synth, sensors, test_every, out, rng, progress)
    elif cfg.source == "video":
        from drawer_lib.capture.videosource import import_video_capture

        seed = int(rng.integers(2**31 - 1))  # COLMAP's RANSAC seed
        manifest, metrics = import_video_capture(scene, cfg.video, cap.video, test_every, out, root, seed, progress)
    else:
        manifest, metrics = import_dir_capture(scene, cfg.dir, test_every, out, root, progress)
    write_manifest(out / capture_name("manifest"), manifest)
    return manifest, metrics
