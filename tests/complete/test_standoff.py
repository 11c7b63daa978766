"""A handle's standoff measured in metric depth, on analytic scenes: a 0.6 x 0.7 m front panel
whose outer face is the plane y = -0.6 (facing -y), a bar handle standing out of it, depth
maps ray-cast exactly against the scene's axis-aligned boxes from views in front of it."""

import math

import numpy as np
import pytest

from drawer_lib.complete.grasp import HandleConfig, handle_box
from drawer_lib.complete.standoff import densest, measure_standoffs, standoff_summary
from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Intrinsics, look_at_opencv, pixel_dirs
from drawer_lib.io.parts import Axis, Front, Part

FRONT = Front((0.3, -0.6, 0.45), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.6, 0.7))
INTR = Intrinsics(120.0, 120.0, 40.0, 30.0, 80, 60)
PANEL = ((0.0, -0.6, 0.1), (0.6, -0.581, 0.8))


def drawer(handle: dict | None, front: Front = FRONT) -> Part:
    extra = {"family": "drawer"} | ({"handle": handle} if handle else {})
    return Part("drawer_0", "prismatic", Axis(front.center, (0.0, -1.0, 0.0)), (0.0, 0.4), front, extra=extra)


def bar(standoff: float, thick: float = 0.012) -> tuple:
    """A horizontal bar 0.2 m long, ``thick`` tall, its outer face ``standoff`` out of the front,
    at the front's middle height; from the front to that face (one solid block)."""
    return ((0.2, -0.6 - standoff, 0.45 - thick / 2), (0.4, -0.6, 0.45 + thick / 2))


def depth_maps(boxes: list[tuple], eyes: list[tuple], noise: float = 0.0, seed: int = 0) -> list:
    """Exact z-depth of the nearest of ``boxes`` (lo, hi corners) from each eye looking at the
    front's centre; 0 where no box is hit; Gaussian noise of ``noise`` m on hit pixels."""
    rng = np.random.default_rng(seed)
    out = []
    for eye in eyes:
        c2w = look_at_opencv(np.asarray(eye), np.asarray(FRONT.center), np.array([0.0, 0.0, 1.0]))
        d_cam = pixel_dirs(INTR).reshape(-1, 3)
        d = d_cam @ c2w[:3, :3].T  # world ray per unit z-depth
        o = c2w[:3, 3]
        best = np.full(len(d), np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            for lo, hi in boxes:
                t0 = (np.asarray(lo) - o) / d
                t1 = (np.asarray(hi) - o) / d
                tn = np.nanmax(np.minimum(t0, t1), axis=1)
                tf = np.nanmin(np.maximum(t0, t1), axis=1)
                hit = (tn <= tf) & (tn > 0)
                best = np.where(hit & (tn < best), tn, best)
        z = np.where(np.isfinite(best), best, 0.0)
        z = np.where(z > 0, z + noise * rng.standard_normal(z.shape), 0.0)
        out.append((z.reshape(INTR.height, INTR.width).astype(np.float32), INTR, c2w))
    return out


EYES = [(0.3 + dx, -1.3, 0.45 + dz) for dx in (-0.4, 0.0, 0.4) for dz in (-0.3, 0.3)]
HANDLE = {"a_u": 0.5, "a_v": 0.5, "orientation": "horizontal", "size": [0.2, 0.012]}


@pytest.mark.parametrize("standoff", [0.012, 0.035])
def test_a_bar_standing_out_of_the_front_is_measured_to_half_a_millimetre(standoff):
    views = depth_maps([PANEL, bar(standoff)], EYES)
    rec = measure_standoffs([drawer(HANDLE)], views)["drawer_0"]
    assert not rec["flush"] and rec["views"] == len(EYES)
    assert rec["standoff_m"] == pytest.approx(standoff, abs=0.0005)
    assert rec["surface_offset_m"] == pytest.approx(0.0, abs=1e-6)


def test_depth_noise_of_a_sensor_and_a_front_plane_a_few_millimetres_off():
    """2 mm of noise on every pixel, and the articulated front's plane 3 mm in front of the
    surface the depth sees: the ring's surface absorbs the offset."""
    off = Front((0.3, -0.603, 0.45), FRONT.normal, FRONT.u, FRONT.size)
    views = depth_maps([PANEL, bar(0.03)], EYES, noise=0.002)
    rec = measure_standoffs([drawer(HANDLE, off)], views)["drawer_0"]
    assert rec["surface_offset_m"] == pytest.approx(-0.003, abs=0.001)  # the surface 3 mm behind the plane
    assert rec["standoff_m"] == pytest.approx(0.03, abs=0.001)


def test_a_flush_handle_and_a_handle_no_view_sees():
    flush = measure_standoffs([drawer(HANDLE)], depth_maps([PANEL], EYES))["drawer_0"]
    assert flush["flush"] and flush["standoff_m"] == 0.0 and flush["box_points"] >= 20
    # every pixel invalid (0 or not finite): not measured, with the reason
    empty = [(np.where(np.arange(z.size).reshape(z.shape) % 2, 0.0, np.nan).astype(np.float32), it, c2w)
             for z, it, c2w in depth_maps([PANEL], EYES[:2])]
    rec = measure_standoffs([drawer(HANDLE)], empty)["drawer_0"]
    assert rec["standoff_m"] is None and "fewer than 20" in rec["why"]
    assert measure_standoffs([drawer(None)], depth_maps([PANEL], EYES[:1])) == {}
    s = standoff_summary({"a": flush, "b": rec, "c": {"standoff_m": 0.02, "flush": False}})
    assert s == {"handle_standoff_measured": 1, "handle_standoff_flush": 1, "handle_standoff_unmeasured": 1,
                 "handle_standoff_median_m": 0.02}
    with pytest.raises(ValueError, match="min_points"):
        measure_standoffs([drawer(HANDLE)], [], min_points=0)


def test_the_box_stands_at_the_measured_standoff_only_when_asked():
    p = drawer(HANDLE)
    rec = {"standoff_m": 0.012, "flush": False, "surface_offset_m": -0.001}
    cfg = HandleConfig()
    assert cfg.standoff == "config"

    def face_y(b):
        return b.center[1] - abs(b.rotation[1]) @ b.half

    assert face_y(handle_box(p, cfg, rec).box) == pytest.approx(-0.6 - cfg.proud)  # config: the record is ignored
    d = HandleConfig(standoff="depth")
    b = handle_box(p, d, rec).box
    assert face_y(b) == pytest.approx(-0.6 - 0.011)  # 12 mm above a surface measured 1 mm behind the plane
    assert 2 * b.half[2] == pytest.approx(0.012)  # no deeper than its standoff
    assert face_y(handle_box(p, d, {"standoff_m": None, "why": "x"}).box) == pytest.approx(-0.6 - d.proud)
    assert handle_box(p, d, {"standoff_m": 0.0, "flush": True}) is None
    with pytest.raises(ConfigError, match="standoff"):
        HandleConfig(standoff="mesh")
    with pytest.raises(ConfigError, match="min_points"):
        HandleConfig(min_points=0)
    with pytest.raises(ConfigError, match="max_views"):
        HandleConfig(max_views=0)


def test_huge_and_tiny_distances_keep_the_measurement_finite():
    """A view from 30 m away sees no handle pixel (not measured); the near views still measure."""
    far = depth_maps([PANEL, bar(0.02)], [(0.3, -30.0, 0.45)])
    rec = measure_standoffs([drawer(HANDLE)], far)["drawer_0"]
    assert rec["standoff_m"] is None or math.isfinite(rec["standoff_m"])
    near = depth_maps([PANEL, bar(0.02)], [(0.3 + dx, -0.75, 0.45) for dx in (-0.1, 0.0, 0.1)])
    rec = measure_standoffs([drawer(HANDLE)], far + near)["drawer_0"]
    assert rec["standoff_m"] == pytest.approx(0.02, abs=0.0005)


def test_the_densest_value_against_a_slow_reference():
    """The kernel density's peak against its sum written out per grid point, on a spike with a
    spread tail below it (a face and its sides), one sample, two unequal peaks; of two equal
    peaks the highest wins."""
    rng = np.random.default_rng(1)
    face = np.concatenate([0.03 + 0.001 * rng.standard_normal(300), rng.uniform(0.004, 0.03, 200)])
    for x in (face, np.array([0.012]), np.array([0.01, 0.01, 0.01, 0.02, 0.02])):
        grid = np.arange(x.min() - 0.008, x.max() + 0.0085, 0.0005)
        ref = grid[::-1][np.argmax([np.exp(-0.5 * ((x - g) / 0.002) ** 2).sum() for g in grid[::-1]])]
        assert densest(x, 0.002) == pytest.approx(ref, abs=0.0005 + 1e-12)
    assert densest(face, 0.002) == pytest.approx(0.03, abs=0.0005)
    assert densest(np.array([0.01, 0.01, 0.02, 0.02]), 0.002) == pytest.approx(0.02, abs=1e-9)
