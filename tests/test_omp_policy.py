"""drawer_lib's OpenMP wait policy (``drawer_lib/__init__.py``): passive unless the environment
chose, set only while torch is not loaded yet, and every stage imports drawer_lib before torch."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _run(code: str, drop: tuple[str, ...] = ("OMP_WAIT_POLICY",), **env) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter, with the variables ``drop`` removed from this environment
    and ``env`` added."""
    full = {k: v for k, v in os.environ.items() if k not in drop} | env
    full["PYTHONPATH"] = str(ROOT)
    r = subprocess.run([sys.executable, "-c", code], env=full, capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    return r


NO_POLICY_NO_THREADS = ("OMP_WAIT_POLICY", "OMP_NUM_THREADS")
REPORT = "import os, drawer_lib; print(os.environ.get('OMP_WAIT_POLICY'), drawer_lib.omp_wait_policy())"


def test_passive_when_the_environment_does_not_choose():
    assert _run(REPORT).stdout.strip() == "PASSIVE PASSIVE"


@pytest.mark.parametrize("value", ["ACTIVE", "passive"])
def test_an_explicit_choice_is_kept(value):
    assert _run(REPORT, OMP_WAIT_POLICY=value).stdout.strip() == f"{value} {value}"


def test_torch_loaded_first_is_left_alone_reported_as_default_and_warned_about():
    # libgomp read its settings when torch loaded: setting the variable then would claim an effect it has not
    r = _run("import torch; " + REPORT, drop=NO_POLICY_NO_THREADS, OMP_NUM_THREADS="2")
    assert r.stdout.strip() == "None default"
    assert "RuntimeWarning" in r.stderr and "import drawer_lib first" in r.stderr


@pytest.mark.parametrize("env", [{"OMP_NUM_THREADS": "1"}, {"OMP_NUM_THREADS": "2", "OMP_WAIT_POLICY": "ACTIVE"}])
def test_no_warning_with_one_thread_or_an_explicit_policy(env):
    r = _run("import torch; " + REPORT, drop=NO_POLICY_NO_THREADS, **env)
    assert "RuntimeWarning" not in r.stderr, r.stderr


def _imports_before_drawer_lib(path: Path) -> list[str] | None:
    """Top-level modules a stage script imports before its first drawer_lib import (None: none)."""
    mods = []
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Import):
            mods += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            mods.append(node.module or "")
    for i, m in enumerate(mods):
        if m.split(".")[0] == "drawer_lib":
            return mods[:i]
    return None


def test_every_stage_imports_drawer_lib_before_anything_that_loads_torch():
    before: set[str] = set()
    for path in sorted((ROOT / "stages").glob("*.py")):
        if path.name == "__init__.py":
            continue
        mods = _imports_before_drawer_lib(path)
        assert mods is not None, f"{path.name}: does not import drawer_lib"
        before.update(mods)
    assert before, "expected the stages' hydra / omegaconf imports"
    # the modules the stages import first must not load torch (if one did, the policy would not apply)
    code = f"import sys; import {', '.join(sorted(before))}; print('torch' in sys.modules)"
    assert _run(code).stdout.strip() == "False"
