"""The viewer's server side (drawer_lib/viewer/app.py, record.py, __main__.py) on the tiny twin,
without a browser: sliders move the parts' frames by their joints, simulate mode drives the
joints through the twin's own actuators, dropped balls and cups rest on what they fall on and
ride along with an opened drawer, the recording is deterministic, and the CLI names bad input."""

import sys
import time
from pathlib import Path

import numpy as np
import pytest
import viser

sys.path.insert(0, str(Path(__file__).resolve().parent))
from viewer_fixtures import write_tiny_twin  # noqa: E402
from helpers import quat_to_rot  # noqa: E402

from drawer_lib.geometry.joints import joint_transform  # noqa: E402
from drawer_lib.viewer.__main__ import main  # noqa: E402
from drawer_lib.viewer.app import TwinViewer, cup_pieces  # noqa: E402
from drawer_lib.viewer.record import RecordConfig, keyframes, record_open_each  # noqa: E402
from drawer_lib.viewer.scene import load_twin_scene  # noqa: E402


@pytest.fixture(scope="module")
def twin(tmp_path_factory) -> Path:
    return write_tiny_twin(tmp_path_factory.mktemp("viewer") / "twin")


@pytest.fixture
def viewer(twin):
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    v = TwinViewer(load_twin_scene(twin), server)
    yield v
    v.close()
    server.stop()


def _frame_matrix(f) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = quat_to_rot(f.wxyz), f.position
    return T


def test_a_slider_moves_its_part_frame_by_the_joint_and_nothing_else(viewer):
    b = viewer.scene.body("door_0")
    viewer.set_q("door_0", 1.0)
    assert viewer.q("door_0") == pytest.approx(1.0)
    np.testing.assert_allclose(_frame_matrix(viewer.frames["door_0"]),
                               joint_transform("revolute", b.joint.anchor, b.joint.axis, 1.0), atol=1e-9)
    for pid in ("drawer_0", "flap_0", "cup_0"):
        np.testing.assert_allclose(_frame_matrix(viewer.frames[pid]), np.eye(4), atol=1e-12)
    viewer.set_q("drawer_0", 7.0)  # clipped to the range
    assert viewer.sliders["drawer_0"].value == pytest.approx(0.4) and viewer.q("drawer_0") == pytest.approx(0.4)


def test_open_all_and_close_all(viewer):
    viewer.open_all()
    assert [viewer.q(p) for p in viewer.sliders] == pytest.approx([0.4, np.pi / 2, np.pi / 2])
    viewer.close_all()
    assert [viewer.q(p) for p in viewer.sliders] == pytest.approx([0.0, 0.0, 0.0])


def test_simulate_mode_drives_the_joints_to_the_sliders_targets(viewer):
    viewer.simulate(True)
    assert viewer.simulating and not viewer.ball_btn.disabled
    viewer.open_all()  # sliders are targets now: the physics thread moves the parts
    t0 = time.monotonic()
    while min(viewer.q("drawer_0") / 0.4, viewer.q("door_0") / (np.pi / 2)) < 0.95:
        assert time.monotonic() - t0 < 60, f"joints at {viewer.q('drawer_0')}, {viewer.q('door_0')} after 60 s"
        time.sleep(0.2)
    viewer.simulate(False)  # sliders take the simulated values; kinematic mode again
    assert not viewer.simulating and viewer.ball_btn.disabled
    assert viewer.sliders["drawer_0"].value == pytest.approx(viewer.q("drawer_0"), abs=1e-9)
    assert viewer.q("drawer_0") > 0.38


def test_a_dropped_ball_rests_on_the_counter(viewer):
    with viewer.lock:
        viewer.simulate(False)
    name = viewer.drop("ball", (2.3, 0.5, 1.1))  # the counter's top is at z = 0.9 (x 2.0-2.6, y 0-0.6)
    viewer.step(1.5)
    p = viewer.body_position(name)
    assert p[2] == pytest.approx(0.9 + 0.03, abs=3e-3)
    assert p[0] == pytest.approx(2.3, abs=0.05) and p[1] == pytest.approx(0.5, abs=0.05)
    np.testing.assert_allclose(viewer.dropped[0].frame.position, p, atol=1e-9)  # its node follows it
    viewer.clear_dropped()
    assert viewer.model is viewer.scene.model and not viewer.dropped


def test_a_cup_dropped_into_the_opened_drawer_rides_along_when_it_closes(viewer):
    viewer.targets["drawer_0"] = 0.4
    viewer.step(2.0)
    assert viewer.q("drawer_0") == pytest.approx(0.4, abs=0.01)
    # the drawer box spans x -0.267..0.267, y -0.4..0.05 once open; its bottom's top at z 0.033
    name = viewer.drop("cup", (0.0, -0.2, 0.12))
    viewer.step(1.5)
    p0 = viewer.body_position(name)
    assert p0[2] == pytest.approx(0.021 + 0.012, abs=0.01), p0  # resting on the drawer's bottom
    viewer.targets["drawer_0"] = 0.1
    viewer.step(3.0)
    p1 = viewer.body_position(name)
    assert viewer.q("drawer_0") == pytest.approx(0.1, abs=0.01)
    assert p1[1] - p0[1] == pytest.approx(0.3, abs=0.03) and p1[2] == pytest.approx(p0[2], abs=0.01)


def test_the_cup_is_closed_convex_pieces():
    pieces = cup_pieces(10)
    assert pieces[0][0] == "cylinder" and len(pieces) == 11
    # neighbouring walls touch: the ring has no gap a ball could pass
    (_, s, p, a), (_, _, p2, a2) = pieces[1], pieces[2]
    tangent_half = s[1]
    gap = np.linalg.norm(np.array(p2[:2]) - p[:2]) - 2 * tangent_half * np.cos((a2 - a) / 2)
    assert gap <= 1e-9


def test_keyframes_open_hold_and_close():
    k = keyframes(0.0, 0.4, RecordConfig(seconds=1.0, hold=0.5, fps=10))
    assert k[0] == 0.0 and k[-1] == 0.0 and max(k) == 0.4 and len(k) == 11 + 5 + 11
    assert np.all(np.diff(k[:11]) >= 0)
    with pytest.raises(ValueError, match="fps = 0"):
        RecordConfig(fps=0)


def test_the_recording_is_self_contained_and_deterministic(twin, tmp_path):
    outs = []
    for k in range(2):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
        try:
            v = TwinViewer(load_twin_scene(twin), server)
            r = record_open_each(v, tmp_path / f"{k}/rec.html", tmp_path / f"{k}/rec.viser", RecordConfig(seconds=0.2, hold=0.1))
        finally:
            server.stop()
        outs.append(((tmp_path / f"{k}/rec.html").read_bytes(), (tmp_path / f"{k}/rec.viser").read_bytes()))
    assert r["frames"] == 3 * (7 + 3 + 7)
    html, data = outs[0]
    assert b"window.__VISER_EMBED_DATA__=" in html and b"http://" not in html.split(b"__VISER_EMBED_DATA__")[1][:200]
    assert outs[0] == outs[1]


def test_the_cli_names_a_bad_folder(tmp_path, capsys):
    assert main([str(tmp_path / "nope")]) == 2
    assert "nope: no such folder" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([str(tmp_path), "--port", "70000"])


def test_the_cli_records(twin, tmp_path, capsys):
    assert main([str(twin), "--port", "0", "--record", str(tmp_path / "r.html")]) == 0
    assert (tmp_path / "r.html").stat().st_size > 500_000 and (tmp_path / "r.viser").is_file()
    assert "wrote" in capsys.readouterr().out


def test_aim_drops_above_what_the_camera_looks_at(viewer):
    p = viewer.aim(np.array([2.3, -1.0, 1.6]), np.array([2.3, 0.3, 0.9]))  # looking down at the counter's top
    assert 0.9 < p[2] < 1.1 and 0.0 < p[1] < 0.3
    far = viewer.aim(np.array([0.0, 0.0, 5.0]), np.array([0.0, 0.0, 6.0]))  # at the sky: 1.5 m ahead
    np.testing.assert_allclose(far, [0.0, 0.0, 6.55])


def test_the_cli_serves_prints_its_url_and_stops_cleanly_on_ctrl_c(twin):
    import signal
    import subprocess
    import urllib.request

    root = Path(__file__).resolve().parents[2]
    p = subprocess.Popen([sys.executable, "-m", "drawer_lib.viewer", str(twin), "--port", "0"], cwd=root,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        url, lines = None, []
        t0 = time.monotonic()
        while url is None:
            line = p.stdout.readline()
            assert line and time.monotonic() - t0 < 120, "".join(lines)
            lines.append(line)
            if line.startswith("viewer at "):
                url = line.split()[2]
        page = urllib.request.urlopen(url, timeout=10).read()
        assert b"<html" in page.lower()[:2000]
        p.send_signal(signal.SIGINT)
        assert p.wait(30) == 0
    finally:
        if p.poll() is None:
            p.kill()
    assert "Gaussians" in "".join(lines)


def test_a_diverged_simulation_is_reset_to_rest_and_said(viewer):
    with viewer.lock:
        viewer.data.qvel[:] = np.nan
    with pytest.raises(FloatingPointError, match="diverged at t = "):
        viewer.step(0.1)
    viewer.simulate(True)  # the thread: resets and goes on, the panel says why
    with viewer.lock:
        viewer.data.qvel[:] = np.inf
    t0 = time.monotonic()
    while "reset to rest" not in viewer.info.content:
        assert time.monotonic() - t0 < 30
        time.sleep(0.1)
    with viewer.lock:
        assert np.isfinite(viewer.data.qpos).all()
    viewer.simulate(False)
    assert all(np.isfinite(viewer.q(p)) for p in viewer.sliders)


def test_a_low_margin_part_is_marked(twin, tmp_path):
    """twin.json's low_margin (from parts.json) marks the part: its slider's label and hint, its
    axis colour and the info line; the others stay unmarked."""
    import json
    import shutil

    from drawer_lib.viewer.app import LOW_MARGIN_COLOR, LOW_MARGIN_MARK

    marked = tmp_path / "twin"
    shutil.copytree(twin, marked)
    tj = json.loads((marked / "twin.json").read_text())
    for p in tj["parts"]:
        if p["id"] == "door_0":
            p["confidence"], p["low_margin"] = 0.55, True
    (marked / "twin.json").write_text(json.dumps(tj))
    scene = load_twin_scene(marked)
    assert scene.body("door_0").low_margin and scene.body("door_0").confidence == pytest.approx(0.55)
    assert not scene.body("drawer_0").low_margin and scene.body("drawer_0").confidence is None
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    v = TwinViewer(scene, server, show_axes=True)
    try:
        assert v.sliders["door_0"].label == LOW_MARGIN_MARK + "door_0" and "low margin" in v.sliders["door_0"].hint
        assert "confidence 0.55" in v.sliders["door_0"].hint
        assert v.sliders["drawer_0"].label == "drawer_0"
        assert "low-margin: door_0" in v._info_text()
        colours = {tuple(np.asarray(a.colors).reshape(-1, 3)[0].tolist()) for a in v.axes}
        assert tuple(LOW_MARGIN_COLOR) in colours
    finally:
        v.close()
        server.stop()
