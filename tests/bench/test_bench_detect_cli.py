"""scripts/bench_detect.py refuses a variant that would overwrite the default's outputs or vary a
stage it does not rerun, before it builds anything."""

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_detect.py"


@pytest.mark.parametrize("args, message", [
    (["--set", "decompose.missing_weight=0"], "--set needs a --tag"),
    (["--tag", "t", "--set", "sdf.method=tsdf"], "only decompose.* and articulate.* keys vary here"),
    (["--split", "hand", "--kitchens", "2", "8"], "the hand split has kitchens 0 .. 7"),
])
def test_bad_variants_are_refused(tmp_path, args, message):
    r = subprocess.run([sys.executable, str(SCRIPT), "--out", str(tmp_path), *args], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode != 0 and message in r.stderr
    assert not any(tmp_path.iterdir())  # nothing written
