"""``python -m drawer_lib.viewer TWIN_DIR [--port N] [--host H] [--collision] [--simulate]
[--record OUT.html]``: serve a twin folder in the browser (stop with Ctrl-C), or write its
"open every part in turn" recording and exit."""

import argparse
import signal
import sys
import threading
import time
from pathlib import Path

from drawer_lib.errors import InputError


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m drawer_lib.viewer", description=__doc__.split("\n\n")[0])
    ap.add_argument("twin", type=Path, help="a twin folder (out/<scene>/twin: twin.json, scene.xml, gaussians/)")
    ap.add_argument("--port", type=int, default=8080, help="port to serve on; the next free one if taken (default 8080)")
    ap.add_argument("--host", default="127.0.0.1", help="interface (default 127.0.0.1; 0.0.0.0 to serve a network)")
    ap.add_argument("--collision", action="store_true", help="show the collision hulls at start")
    ap.add_argument("--simulate", action="store_true", help="start in simulate mode (MuJoCo steps the twin)")
    ap.add_argument("--min-scale", type=float, default=1e-3,
                    help="smallest Gaussian scale sent to the browser, m (its covariances are float16; default 1e-3)")
    ap.add_argument("--record", type=Path, metavar="OUT.html",
                    help="write the open-every-part recording (OUT.html and OUT.viser) and exit")
    a = ap.parse_args(argv)
    if not 0 <= a.port < 65536:
        ap.error(f"--port {a.port}: not a port")
    if not a.min_scale > 0:
        ap.error(f"--min-scale {a.min_scale}: must be > 0")
    return a


def main(argv: list[str] | None = None) -> int:
    a = parse(argv)
    import viser

    from drawer_lib.viewer.app import TwinViewer
    from drawer_lib.viewer.record import record_open_each
    from drawer_lib.viewer.scene import load_twin_scene

    t0 = time.perf_counter()
    try:
        scene = load_twin_scene(a.twin, min_scale=a.min_scale)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    t_load = time.perf_counter() - t0
    server = viser.ViserServer(host=a.host, port=a.port, label=f"DRAWER twin: {a.twin}", verbose=False)
    try:
        viewer = TwinViewer(scene, server, show_collision=a.collision)
        print(f"{a.twin}: {scene.n_gaussians:,} Gaussians ({scene.n_clamped:,} with scales clamped to "
              f"[{a.min_scale:g}, 10] m), {len(scene.bodies)} bodies; "
              f"read in {t_load:.2f} s, sent to the scene in {viewer.build_s:.2f} s", flush=True)
        if a.record:
            html = a.record.with_suffix(".html")
            r = record_open_each(viewer, html, html.with_suffix(".viser"))
            print(f"wrote {html} ({r['html_bytes'] / 1e6:.1f} MB) and {html.with_suffix('.viser')} "
                  f"({r['viser_bytes'] / 1e6:.1f} MB): {r['seconds']} s, {r['frames']} frames", flush=True)
            return 0
        if a.simulate:
            viewer.simulate(True)
        host = "localhost" if a.host in ("127.0.0.1", "0.0.0.0") else a.host
        print(f"viewer at http://{host}:{server.get_port()}  (Ctrl-C stops it)", flush=True)
        done = threading.Event()
        # explicit handlers: a process started in the background inherits SIGINT ignored, and
        # then Python raises no KeyboardInterrupt
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: done.set())
        while not done.wait(0.5):
            pass
        print("stopping", flush=True)
        viewer.close()
        return 0
    finally:
        server.stop()


if __name__ == "__main__":
    sys.exit(main())
