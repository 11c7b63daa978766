import json

import numpy as np
import pytest

from drawer_lib.errors import CaptureError
from drawer_lib.io.manifest import Manifest, read_manifest, write_manifest
from drawer_lib.io.parts import parse_parts, read_parts, write_parts

DOOR = {"id": "door_0", "kind": "revolute", "axis": {"origin": [0, -0.6, 0.5], "direction": [0, 0, -1]},
        "limits": [0.0, 1.57], "front": {"center": [0.2, -0.6, 0.5], "normal": [0, -1, 0], "u": [1, 0, 0], "size": [0.4, 0.7]},
        "instance_id": 1}
CUP = {"id": "cup_0", "kind": "rigid", "center": [0.1, -0.3, 0.9], "bounds": [[0.05, -0.35, 0.86], [0.15, -0.25, 0.96]]}


def doc(*parts, **kw):
    return {"schema": "drawer.parts/1", "units": "m", "up": [0, 0, 1], "parts": list(parts), "ignore_boxes": [], **kw}


def test_parts_round_trip(tmp_path, exact_capture):
    out, _, _ = exact_capture
    p = read_parts(out / "gt" / "parts.json")
    write_parts(tmp_path / "p.json", p)
    assert read_parts(tmp_path / "p.json") == p
    raw = json.loads((out / "gt" / "parts.json").read_text())
    assert raw["schema"] == "drawer.parts/1" and raw["units"] == "m" and raw["up"] == [0, 0, 1]
    for q in raw["parts"]:  # exactly the drawer.parts/1 keys (plus a free-form family)
        keys = {"id", "kind", "instance_id", "family"} | ({"axis", "limits", "front"} if q["kind"] != "rigid" else {"center", "bounds"})
        assert set(q) == keys
    f = parse_parts(doc(DOOR, CUP)).by_id("door_0").front
    np.testing.assert_allclose(f.v, [0, 0, 1])
    np.testing.assert_allclose(f.corners()[2], [0.4, -0.6, 0.85])


@pytest.mark.parametrize("bad,msg", [
    ({**DOOR, "kind": "screw"}, "kind 'screw'"),
    ({**DOOR, "limits": [1.0, 0.0]}, "lower 1.0 must be below upper"),
    ({**DOOR, "limits": [0.5, 0.5]}, "an empty range"),
    ({**DOOR, "axis": {"origin": [0, 0, 0], "direction": [0, 0, 2]}}, "not a unit vector"),
    ({**DOOR, "axis": {"origin": [0, 0, float("nan")], "direction": [0, 0, 1]}}, "finite"),
    ({**DOOR, "front": {**DOOR["front"], "u": [0, -1, 0]}}, "not perpendicular"),
    ({k: v for k, v in DOOR.items() if k != "front"}, "missing or malformed"),
    ({**CUP, "bounds": [[1, 1, 1], [0, 0, 0]]}, "exceeds max"),
])
def test_parts_validation(bad, msg):
    with pytest.raises(CaptureError, match=msg):
        parse_parts(doc(bad))
    with pytest.raises(CaptureError, match="duplicate id"):
        parse_parts(doc(DOOR, DOOR))
    with pytest.raises(CaptureError, match="schema"):
        parse_parts({"parts": []})


def test_manifest_requirements(tmp_path):
    m = Manifest("s", "video", 10, 9, 1, 64, 48,
                 has={"rgb": True, "depth": False, "mono_depth": False, "mono_normal": False, "detections": False,
                      "sparse_points": True, "gt": False},
                 lacks={"depth": "RGB video", "mono_depth": "x", "mono_normal": "x", "detections": "x", "gt": "real"},
                 world_frame={"metric_scale": False, "gravity": True, "how": "assumed"})
    assert m.missing("rgb") is None and m.missing("sparse_points") is None
    assert "RGB video" in m.missing("depth")
    assert m.missing("gravity") is None and "assumed" in m.missing("metric_scale")
    assert "no gt" in m.missing("gt:revolute")
    assert m.first_missing("rgb", "depth", "gt") == m.missing("depth")
    with pytest.raises(KeyError):
        m.missing("lidar")
    write_manifest(tmp_path / "m.json", m)
    assert read_manifest(tmp_path / "m.json") == m
    with pytest.raises(ValueError, match="no reason"):
        Manifest("s", "synth", 1, 1, 0, 1, 1, has={k: False for k in m.has}, lacks={})


def test_manifest_gt_kinds(exact_capture):
    _, manifest, _ = exact_capture
    assert manifest.missing("gt") is None
    kinds = manifest.gt_part_kinds
    for k in ("revolute", "prismatic", "rigid"):
        assert (manifest.missing(f"gt:{k}") is None) == (kinds[k] > 0)
