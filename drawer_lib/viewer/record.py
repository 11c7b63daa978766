"""A shareable recording of a twin: every part opened and closed in turn, as one self-contained
HTML page (viser's player with the scene embedded; no server, no network) and as a ``.viser``
file (the same recording for viser's player served over HTTP, ``index.html?playbackPath=...``).

A recording holds scene messages only (viser drops the GUI from recordings), so the joints'
motion is baked in: for each articulated part in ``twin.json`` order, q goes from 0 to the upper
limit in ``seconds`` (smooth-step easing), stays open for ``hold`` seconds and closes again.
Its time line is counted in recorded seconds (``insert_sleep``), never in wall time, so the same
twin gives the same bytes.
"""

import time
from pathlib import Path

import viser

from drawer_lib.io.atomic import atomic_write_bytes
from drawer_lib.viewer.app import TwinViewer
from drawer_lib.viewer.config import RecordConfig
from drawer_lib.viewer.scene import load_twin_scene


def _smoothstep(t: float) -> float:
    return t * t * (3.0 - 2.0 * t)


def keyframes(lo: float, hi: float, cfg: RecordConfig) -> list[float]:
    """Joint values of one part's open-hold-close clip, one per frame (starts and ends closed)."""
    n = max(1, round(cfg.seconds * cfg.fps))
    closed = min(max(0.0, lo), hi)
    up = [closed + (hi - closed) * _smoothstep(k / n) for k in range(n + 1)]
    return up + [hi] * round(cfg.hold * cfg.fps) + up[::-1]


def record_open_each(viewer: TwinViewer, html: Path, viser_file: Path | None = None,
                     cfg: RecordConfig | None = None) -> dict:
    """Record ``viewer``'s twin opening each part in turn into ``html`` (and ``viser_file``);
    returns ``{"frames", "seconds", "html_bytes"[, "viser_bytes"]}``. The viewer ends with every
    part closed."""
    cfg = cfg or RecordConfig()
    viewer.simulate(False)
    viewer.close_all()
    server = viewer.server
    sers = [server.get_scene_serializer() for _ in range(2 if viser_file else 1)]
    dt, frames = 1.0 / cfg.fps, 0
    for pid, s in viewer.sliders.items():
        for q in keyframes(s.min, s.max, cfg):
            viewer.set_q(pid, q)
            for r in sers:
                r.insert_sleep(dt)
            frames += 1
    page = sers[0].as_html().encode()
    atomic_write_bytes(Path(html), page)
    out = {"frames": frames, "seconds": round(frames * dt, 3), "html_bytes": len(page)}
    if viser_file:
        data = sers[1].serialize()
        atomic_write_bytes(Path(viser_file), data)
        out["viser_bytes"] = len(data)
    return out


def record_twin(folder: Path, html: Path, viser_file: Path | None = None, cfg: RecordConfig | None = None) -> dict:
    """:func:`record_open_each` of the twin in ``folder``, on a private server (localhost, a free
    port) that is stopped afterwards; adds ``n_gaussians`` and the ``wall_s`` it took."""
    cfg = cfg or RecordConfig()
    t0 = time.perf_counter()
    scene = load_twin_scene(folder, min_scale=cfg.min_scale)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        out = record_open_each(TwinViewer(scene, server), html, viser_file, cfg)
    finally:
        server.stop()
    return {**out, "n_gaussians": scene.n_gaussians, "wall_s": round(time.perf_counter() - t0, 3)}
