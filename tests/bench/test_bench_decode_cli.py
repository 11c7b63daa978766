"""scripts/bench_decode.py reads a decoding variant as detect.builtin keys over the configured
ones, and refuses a key that is not one before it renders anything."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from drawer_lib.detect.config import BuiltinDetectConfig

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_decode.py"


def _module():
    spec = importlib.util.spec_from_file_location("bench_decode", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_a_variant_replaces_only_its_keys():
    base = BuiltinDetectConfig()
    v = _module().parse_variant("core_handle=false merge_edge=0 erode_px=3", base)
    assert (v.core_handle, v.merge_edge, v.erode_px) == (False, 0.0, 3) and v.edge_max == base.edge_max
    assert _module().parse_variant("core_handle=True", base).core_handle is True
    assert _module().parse_variant("", base) == base
    v = _module().parse_variant("merge_edge=0.5 merge_edge_band=0.7 merge_band_limit=two_regions", base)
    assert (v.merge_edge, v.merge_edge_band, v.merge_band_limit) == (0.5, 0.7, "two_regions")
    with pytest.raises(SystemExit, match="merge_band_limit"):
        _module().parse_variant("merge_band_limit=three", base)


def test_a_bad_layout_key_is_refused_before_anything_renders():
    r = subprocess.run([sys.executable, str(SCRIPT), "--kitchens", "0", "--layout", "module_width=[0.6]"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode != 0 and "--layout 'module_width=[0.6]': not KEY=VALUE" in r.stderr


@pytest.mark.parametrize("variant", ["nope=1", "merge_edge", "merge_edge=2"])
def test_bad_variants_are_refused(variant):
    r = subprocess.run([sys.executable, str(SCRIPT), "--kitchens", "0", "--variant", variant], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode != 0 and ("not KEY=VALUE" in r.stderr or "merge_edge = 2.0" in r.stderr)
