import numpy as np

from drawer_lib.io.capture import load_capture
from drawer_lib.report.contact_sheet import colorize_depth, contact_sheet


def test_contact_sheet_has_a_column_per_modality(noisy_capture):
    out, _, _ = noisy_capture
    cap = load_capture(out)
    sheet = contact_sheet(cap, [0, 5])
    W, H = cap.intrinsics.width, cap.intrinsics.height
    assert sheet.shape == (2 * H, 6 * W, 3) and sheet.dtype == np.uint8
    np.testing.assert_array_equal(sheet[:H, :W], cap.image(0))


def test_colorize_depth_marks_invalid_black():
    d = np.array([[0.0, 1.0], [np.nan, 2.0]])
    c = colorize_depth(d)
    assert (c[0, 0] == 0).all() and (c[1, 0] == 0).all() and c[0, 1].sum() > c[1, 1].sum()
    assert not colorize_depth(np.zeros((2, 2))).any()
