"""Motion EMD (drawer_lib.metrics.motion, docs/formats.md#motion-emd): zero for the GT against itself, the
closed form for a sliding panel whose axis is turned by a small angle in the image plane, the
assignment against a brute force, interpolation of recorded tracks."""

import itertools
import math

import numpy as np
import pytest

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import Camera, Intrinsics
from drawer_lib.io.parts import Axis, Front, Part
from drawer_lib.metrics.motion import (STEPS, front_grid, interpolate_tracks, kinematic_motion_emd, kinematic_tracks,
                                       motion_emd,
                                       opening_amount, step_values, track_emd)

W, H, F = 200, 150, 160.0
CAM = Camera(Intrinsics(F, F, W / 2, H / 2, W, H), np.eye(4))  # OpenCV at the origin, looking down +z
Z = 2.0
FRONT = Front((0.0, 0.0, Z), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), (0.5, 0.7))


def _slider(direction, upper=0.4, pid="sliding_0") -> Part:
    return Part(pid, "prismatic", Axis((0.0, 0.0, Z), tuple(direction)), (0.0, upper), FRONT)


def _door(origin_x=-0.25, upper=math.radians(100), pid="door_0") -> Part:
    return Part(pid, "revolute", Axis((origin_x, 0.0, Z), (0.0, 1.0, 0.0)), (0.0, upper), FRONT)


def _recorded(part: Part, k: int = 200) -> dict:
    """What the simulate stage records for a perfect simulation of ``part``."""
    q = np.linspace(part.limits[0], part.limits[1], k + 1)[1:]
    pts = front_grid(part.front)
    return {f"{part.id}/q": q, f"{part.id}/points": kinematic_tracks(part, pts, q), f"{part.id}/front_points": pts}


@pytest.mark.parametrize("part", [_slider((1.0, 0.0, 0.0)), _door()], ids=["prismatic", "revolute"])
def test_the_gt_against_itself_is_zero(part):
    summary, rows = motion_emd([part], [part], [(0, 0)], _recorded(part), CAM)
    assert summary["emd"] < 1e-12 and summary["n_emd"] == 1 and rows[0]["amount"] == opening_amount(part, part)


@pytest.mark.parametrize("alpha_deg", [0.5, 2.0, 10.0])
def test_a_turned_sliding_axis_gives_the_closed_form(alpha_deg):
    """The panel slides parallel to the image plane, so the projection is affine: the image
    error at step t is (f / Z) s_t (cos a - 1, sin a) for a displacement s_t; the identity
    assignment is optimal (the cross term sums to 0 over any permutation), so
    EMD = [(f / (Z W))^2 (cos a - 1)^2 + (f / (Z H))^2 sin^2 a] x mean_t s_t^2."""
    a = math.radians(alpha_deg)
    gt, pred = _slider((1.0, 0.0, 0.0), 0.4), _slider((math.cos(a), math.sin(a), 0.0), 0.5)
    amount = 0.4  # the smaller upper limit
    mean_s2 = amount ** 2 * (STEPS + 1) * (2 * STEPS + 1) / (6 * STEPS ** 2)
    expected = ((F / (Z * W)) ** 2 * (math.cos(a) - 1) ** 2 + (F / (Z * H)) ** 2 * math.sin(a) ** 2) * mean_s2
    summary, _ = motion_emd([pred], [gt], [(0, 0)], _recorded(pred), CAM)
    assert summary["emd"] == pytest.approx(expected, rel=1e-9)


def test_track_emd_is_the_optimal_assignment():
    rng = np.random.default_rng(0)
    a, b = rng.random((5, 6, 2)), rng.random((5, 6, 2))
    brute = min(np.mean([((a[:, k] - b[:, p[k]]) ** 2).sum(-1).mean() for k in range(6)])
                for p in itertools.permutations(range(6)))
    assert track_emd(a, b) == pytest.approx(brute, rel=1e-12)
    assert track_emd(a, a[:, ::-1]) == pytest.approx(0.0, abs=1e-15)  # the order of the tracks is free
    with pytest.raises(InputError):
        track_emd(a, b[:, :5])


def test_a_part_that_stopped_stays_where_it_stopped():
    """Recorded only up to half its range: the EMD compares the stuck pose with the GT moving on."""
    part = _slider((1.0, 0.0, 0.0))
    rec = _recorded(part)
    half = rec[f"{part.id}/q"] <= 0.2
    stuck = {k: (v[half] if k != f"{part.id}/front_points" else v) for k, v in rec.items()}
    qs = step_values(0.4)
    tr = interpolate_tracks(stuck[f"{part.id}/q"], stuck[f"{part.id}/points"], qs, 0.0, rec[f"{part.id}/front_points"])
    np.testing.assert_allclose(tr[-1], kinematic_tracks(part, rec[f"{part.id}/front_points"], np.array([0.2]))[0], atol=1e-12)
    e, _ = motion_emd([part], [part], [(0, 0)], stuck, CAM)
    assert e["emd"] > 1e-4
    with pytest.raises(InputError, match="no simulated track"):
        motion_emd([part], [part], [(0, 0)], {}, CAM)


def test_tracks_behind_the_camera_are_not_scored():
    behind = Front((0.0, 0.0, -1.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.5, 0.7))
    part = Part("d", "prismatic", Axis((0.0, 0.0, -1.0), (1.0, 0.0, 0.0)), (0.0, 0.3), behind)
    summary, rows = motion_emd([part], [part], [(0, 0)], _recorded(part), CAM)
    assert summary == {} and "behind the camera" in rows[0]["skipped"]


def test_kinematic_emd_matches_a_perfect_simulation():
    """The benchmark's EMD (prediction moved by its own joint) equals the simulated one when the
    simulation follows the joint exactly; a door hinged on the wrong side scores far worse."""
    gt, right = _door(), _door(origin_x=0.25)
    wrong = Part("door_1", "revolute", Axis((0.25, 0.0, Z), (0.0, -1.0, 0.0)), gt.limits, FRONT)
    sim, _ = motion_emd([wrong], [gt], [(0, 0)], _recorded(wrong), CAM)
    kin, _ = kinematic_motion_emd([wrong], [gt], [(0, 0)], CAM)
    assert kin["emd"] == pytest.approx(sim["emd"], rel=1e-6) and kin["emd"] > 1e-3
    same, _ = kinematic_motion_emd([gt], [gt], [(0, 0)], CAM)
    assert same["emd"] < 1e-12
    assert right.axis.origin[0] > 0  # the mirrored axis used above
