"""The viewer in a real browser: Debian's Chromium, headless, WebGL in software (SwiftShader),
driven over the DevTools protocol (drawer_lib/viewer/browser.py). The page loads the tiny twin,
a key press on the drawer's slider in the page moves it to its upper limit, and the browser's
own renders before and after differ inside the drawer's projected region (closed or open) and
nowhere else. Screenshots are kept under $DRAWER_TEST_ARTIFACTS (default test-artifacts/viewer)."""

import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import viser
from PIL import Image
from scipy.ndimage import binary_dilation
from scipy.spatial import ConvexHull
from skimage.draw import polygon

sys.path.insert(0, str(Path(__file__).resolve().parent))
from viewer_fixtures import write_tiny_twin  # noqa: E402

from drawer_lib.geometry.joints import joint_transform  # noqa: E402
from drawer_lib.geometry.rotations import matrix_to_quat  # noqa: E402
from drawer_lib.viewer.app import TwinViewer  # noqa: E402
from drawer_lib.viewer.browser import HeadlessChromium, chromium_binary  # noqa: E402
from drawer_lib.viewer.scene import load_twin_scene  # noqa: E402

pytestmark = pytest.mark.skipif(chromium_binary() is None, reason="no chromium on PATH (make setup installs Debian's)")
ARTIFACTS = Path(os.environ.get("DRAWER_TEST_ARTIFACTS", Path(__file__).resolve().parents[2] / "test-artifacts")) / "viewer"
H, W, FOV = 240, 320, np.deg2rad(60.0)
EYE, LOOK = np.array([0.9, -1.7, 0.9]), np.array([0.0, 0.0, 0.15])


def look_at_rotation(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """R_world_camera of an OpenCV camera (x right, y down, z forward) at ``eye`` looking at
    ``target`` with +z up."""
    f = (target - eye) / np.linalg.norm(target - eye)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    return np.stack([r, np.cross(f, r), f], 1)


def project(points: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Pixel (u, v) of world points in the render camera (vertical field of view FOV, H x W)."""
    c = (points - EYE) @ R
    fy = (H / 2) / np.tan(FOV / 2)
    return np.stack([fy * c[:, 0] / c[:, 2] + W / 2, fy * c[:, 1] / c[:, 2] + H / 2], 1)


def region(points_sets: list[np.ndarray], R: np.ndarray, grow: int) -> np.ndarray:
    """Union of the projected convex hulls of each point set, grown by ``grow`` px."""
    mask = np.zeros((H, W), bool)
    for pts in points_sets:
        uv = project(pts, R)
        hull = uv[ConvexHull(uv).vertices]
        rr, cc = polygon(hull[:, 1], hull[:, 0], (H, W))
        mask[rr, cc] = True
    return binary_dilation(mask, iterations=grow)


def settled(render, what: str, timeout: float = 120.0) -> np.ndarray:
    """The first render equal to the one before it (no pixel moved by more than 40 in RGB sum).
    The page loads, sorts and fades the splats in asynchronously, and a render for a new camera
    can use the previous camera's sort, so a fixed sleep is not enough on a loaded machine."""
    t0, prev = time.monotonic(), render()
    while True:
        img = render()
        if not (np.abs(img - prev).sum(-1) > 40).any():
            return img
        if time.monotonic() - t0 > timeout:
            raise TimeoutError(f"{what} still changed between renders after {timeout} s")
        prev = img


def test_moving_a_slider_in_the_page_changes_the_image_inside_the_part_only(tmp_path):
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    scene = load_twin_scene(write_tiny_twin(tmp_path / "twin"))
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        viewer = TwinViewer(scene, server, show_axes=False)  # the image is the Gaussians alone
        R = look_at_rotation(EYE, LOOK)
        wxyz = matrix_to_quat(R)
        with HeadlessChromium(f"http://127.0.0.1:{server.get_port()}", size=(960, 600)) as page:
            page.wait_until(lambda: len(server.get_clients()) > 0, 60, "the page to connect to the viewer")
            client = next(iter(server.get_clients().values()))
            render = lambda: client.get_render(H, W, wxyz=wxyz, position=EYE, fov=FOV, transport_format="png",  # noqa: E731
                                               timeout=120)[..., :3].astype(np.int16)
            before = settled(render, "the closed drawer's render")
            page.screenshot(ARTIFACTS / "page_closed.png")
            # the user's action: focus the drawer's slider (the first) and press End
            assert page.evaluate("document.querySelectorAll('[role=slider]').length") == 3
            page.evaluate("document.querySelectorAll('[role=slider]')[0].focus()")
            page.press("End", 35)
            # the slider's value arrives before its callback has moved the part: wait for both
            page.wait_until(lambda: viewer.sliders["drawer_0"].value == pytest.approx(0.4)
                            and viewer.q("drawer_0") == pytest.approx(0.4), 30,
                            "the page's slider to reach the viewer and move the drawer")
            assert viewer.q("door_0") == 0.0
            after = settled(render, "the open drawer's render")
            page.screenshot(ARTIFACTS / "page_open.png")
    finally:
        server.stop()
    Image.fromarray(before.astype(np.uint8)).save(ARTIFACTS / "render_closed.png")
    Image.fromarray(after.astype(np.uint8)).save(ARTIFACTS / "render_open.png")

    b = scene.body("drawer_0")
    rest = np.concatenate([b.splats.centers, *[h[0] for h in b.hulls]]).astype(np.float64)
    T = joint_transform("prismatic", b.joint.anchor, b.joint.axis, 0.4)
    inside = region([rest, rest @ T[:3, :3].T + T[:3, 3]], R, grow=6)
    changed = np.abs(after - before).sum(-1) > 40
    Image.fromarray((np.stack([changed, inside, np.zeros_like(inside)], -1) * 255).astype(np.uint8)).save(
        ARTIFACTS / "changed_vs_region.png")
    n_in, n_out = int(changed[inside].sum()), int(changed[~inside].sum())
    assert n_in > 500, f"only {n_in} px changed in the drawer's region"
    assert n_out <= 0.0005 * (~inside).sum(), f"{n_out} px changed outside the drawer's region ({n_in} inside)"


def test_the_shared_recording_plays_offline_from_a_file(tmp_path):
    """open_parts.html as a user opens it: from disk, with every non-local request refused."""
    from drawer_lib.viewer.config import RecordConfig
    from drawer_lib.viewer.record import record_twin

    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    html = tmp_path / "open_parts.html"
    record_twin(write_tiny_twin(tmp_path / "twin"), html, cfg=RecordConfig(seconds=0.3, hold=0.1))
    with HeadlessChromium(html.as_uri(), size=(640, 400), extra_flags=["--proxy-server=127.0.0.1:9"]) as page:
        drawn = lambda: (page.screenshot().astype(int).sum(-1) < 3 * 235).mean()  # noqa: E731  non-white share
        page.wait_until(lambda: drawn() > 0.05, 90, "the recording's scene to be drawn")
        page.screenshot(ARTIFACTS / "recording.png")
