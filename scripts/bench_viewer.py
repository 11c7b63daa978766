"""How long the browser viewer takes to show a twin: read the folder, send the scene, and the
first frame a real (headless, software-GL) Chromium renders, for the twin as it is and with its
static Gaussians replicated K times (jittered by 1 mm) to reach 100k+ Gaussians.

    python scripts/bench_viewer.py out/kitchen_small/twin --replicate 1 3
    python scripts/bench_viewer.py out/kitchen_small/twin --replicate 1 --screenshot docs/figures/viewer_kitchen_small.png --open all

Timings are wall seconds on this machine (2 cores, SwiftShader: the browser renders on the CPU);
with a GPU browser the client side is far shorter. Also the real-time factor of simulate mode
(MuJoCo stepping the twin and streaming poses, "open all" driving every joint). Prints a
markdown table.
"""

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import drawer_lib  # noqa: F401  (before torch: the library's OpenMP wait policy, as the viewer runs)
import torch
import viser
from drawer_lib.report.markdown import md_table
from drawer_lib.splat.gaussians import concat
from drawer_lib.splat.ply import read_gaussian_ply, write_gaussian_ply
from drawer_lib.viewer.app import TwinViewer
from drawer_lib.viewer.browser import HeadlessChromium
from drawer_lib.viewer.scene import load_twin_scene


def replicated(twin: Path, k: int, tmp: Path) -> Path:
    """A copy of ``twin`` whose static Gaussians are ``k`` jittered copies of its own."""
    if k == 1:
        return twin
    out = tmp / f"x{k}"
    shutil.copytree(twin, out, ignore=shutil.ignore_patterns("renders", "urdf", "*.usda", "*.html", "*.viser"))
    g = read_gaussian_ply(twin / "gaussians" / "static.ply")
    gen = torch.Generator().manual_seed(0)
    copies = [g] + [type(g)(g.means + 1e-3 * torch.randn(g.means.shape, generator=gen), g.quats, g.scales, g.opacities, g.sh)
                    for _ in range(k - 1)]
    write_gaussian_ply(out / "gaussians" / "static.ply", concat(copies))
    return out


def measure(folder: Path, size=(160, 120), screenshot: Path | None = None, open_parts=()) -> dict:
    t0 = time.perf_counter()
    scene = load_twin_scene(folder)
    t_read = time.perf_counter() - t0
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        t0 = time.perf_counter()
        viewer = TwinViewer(scene, server)
        t_build = time.perf_counter() - t0
        t0 = time.perf_counter()
        with HeadlessChromium(f"http://127.0.0.1:{server.get_port()}", size=(1280, 720)) as page:
            t_connect = page.wait_until(lambda: len(server.get_clients()) > 0, 300, "the page to connect")
            client = next(iter(server.get_clients().values()))
            cam = client.camera
            client.get_render(size[1], size[0], wxyz=cam.wxyz, position=cam.position, fov=cam.fov, timeout=600)
            t_first = time.perf_counter() - t0
            # simulate mode with the page connected: how fast the physics thread runs against real time
            viewer.simulate(True)
            viewer.open_all()
            time.sleep(6)
            rt = viewer.rt_factor
            viewer.simulate(False)
            viewer.close_all()
            t1 = time.perf_counter()
            viewer.step(2.0)  # unpaced: simulated seconds per wall second, poses sent included
            headroom = 2.0 / (time.perf_counter() - t1)
            if screenshot:
                for pid in (viewer.sliders if open_parts == ["all"] else open_parts):
                    viewer.set_q(pid, 0.7 * viewer.sliders[pid].max)
                time.sleep(10)
                page.evaluate("document.querySelectorAll('button[aria-label=\"Close\"], .mantine-Notification-closeButton')"
                              ".forEach(b => b.click())")
                time.sleep(2)
                page.screenshot(screenshot)
    finally:
        server.stop()
    return {"n": scene.n_gaussians, "read": t_read, "build": t_build, "connect": t_connect, "first": t_first, "rt": rt,
            "headroom": headroom}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("twin", type=Path)
    ap.add_argument("--replicate", type=int, nargs="+", default=[1, 3])
    ap.add_argument("--screenshot", type=Path)
    ap.add_argument("--open", default="", help="parts to open to 70 %% before the screenshot, comma-separated, or 'all'")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in a.replicate:
            r = measure(replicated(a.twin, k, Path(tmp)))
            rows.append((k, r))
            print(f"x{k}: {r}", flush=True)
        if a.screenshot:
            measure(a.twin, screenshot=a.screenshot, open_parts=[p for p in a.open.split(",") if p])
            print(f"wrote {a.screenshot}")
    print()
    print(md_table(["twin", "Gaussians", "read folder (s)", "send to scene (s)", "page connects (s)",
                    "first frame rendered (s)", "simulate mode, x real time", "unpaced physics, x real time"],
                   ([a.twin.parent.name + ("" if k == 1 else f", static x{k}"), f"{r['n']:,}", f"{r['read']:.2f}",
                     f"{r['build']:.2f}", f"{r['connect']:.2f}", f"{r['first']:.2f}", f"{r['rt']:.2f}",
                     f"{r['headroom']:.1f}"] for k, r in rows), align="-rrrrrrr"), end="")


if __name__ == "__main__":
    main()
