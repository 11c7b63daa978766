"""Property tests (hypothesis) of the small exact operations everything else relies on."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from drawer_lib.config.typed import to_tree, to_typed
from drawer_lib.geometry.camera import invert_rigid, opencv_to_opengl, opengl_to_opencv
from drawer_lib.geometry.rotations import quat_to_matrix
from drawer_lib.io.images import read_depth, write_depth
from drawer_lib.synth.config import CameraPathConfig, DetectionsConfig

depths = arrays(np.float64, (5, 7), elements=st.floats(0.0, 60.0, allow_nan=False))


@settings(max_examples=40, deadline=None)
@given(d=depths, scale=st.sampled_from([0.001, 0.0001, 0.0005]))
def test_depth_png_quantisation(tmp_path_factory, d, scale):
    p = tmp_path_factory.mktemp("d") / "d.png"
    write_depth(p, d, scale)
    back = read_depth(p, scale).astype(np.float64)
    fits = (d / scale < 65535.5) & (np.round(d / scale) > 0)
    assert np.all(np.abs(back[fits] - d[fits]) <= scale / 2 + 1e-7 * d[fits])
    assert np.all(back[~fits] == 0)  # too far or too close to store: invalid, never wrapped


quats = arrays(np.float64, (4,), elements=st.floats(-1, 1)).filter(lambda q: np.linalg.norm(q) > 0.1)
vecs = arrays(np.float64, (3,), elements=st.floats(-1e3, 1e3))


@settings(max_examples=60, deadline=None)
@given(q=quats, t=vecs)
def test_rigid_conventions_round_trip(q, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = quat_to_matrix(q), t
    np.testing.assert_allclose(opencv_to_opengl(opengl_to_opencv(T)), T, atol=1e-12)
    np.testing.assert_allclose(invert_rigid(invert_rigid(T)), T, atol=1e-9 * (1 + np.abs(t).max()))


@settings(max_examples=30, deadline=None)
@given(n=st.integers(4, 500), w=st.integers(16, 640), p=st.floats(0.0, 1.0), labels=st.sampled_from(["typed", "generic"]))
def test_typed_configs_round_trip(n, w, p, labels):
    cam = CameraPathConfig(n_frames=n, width=w)
    assert to_typed(CameraPathConfig, to_tree(cam), "camera") == cam
    det = DetectionsConfig(p_miss=p, labels=labels)
    assert to_typed(DetectionsConfig, to_tree(det), "det") == det
