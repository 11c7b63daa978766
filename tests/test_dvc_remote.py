"""A shared cache (docs/sweeps.md): one clone builds the tiny DAG and `dvc push`es outputs and
run-cache to a remote (a local folder here; S3 / SSH the same way); a second clone that `dvc
pull`s reproduces with nothing recomputed. Every output of dvc.yaml is cached (no
`cache: false`), so the run-cache restores every stage on the other machine."""

import time

import pytest
import yaml
from test_dvc_pipeline import FAST_PARAMS, make_repo

from drawer_lib.paths import ScenePaths

pytestmark = [pytest.mark.dvc, pytest.mark.slow]


def test_no_output_opts_out_of_the_cache():
    """A `cache: false` output is never pushed, so a stage holding one reruns on every clone."""
    from helpers import ROOT

    text = (ROOT / "dvc.yaml").read_text()
    assert "cache: false" not in text and "cache:false" not in text
    assert yaml.safe_load(text)["stages"]


def test_a_second_clone_pulls_and_recomputes_nothing(tmp_path_factory):
    d, run = make_repo(tmp_path_factory, FAST_PARAMS)
    remote = d.parent / "remote"
    run("dvc", "remote", "add", "--local", "-d", "shared", str(remote))  # .dvc/config.local: the tree stays clean
    run("dvc", "repro")
    t0 = time.perf_counter()
    run("dvc", "push", "--run-cache")
    push_s = time.perf_counter() - t0
    run("git", "add", "-A")
    run("git", "commit", "-qm", "built")
    # the second machine: a clone of the git repository, the same remote
    d2 = d.parent / "clone"
    run("git", "clone", "-q", str(d), str(d2))
    run("dvc", "remote", "add", "--local", "-d", "shared", str(remote), cwd=d2)
    t0 = time.perf_counter()
    run("dvc", "pull", "--run-cache", cwd=d2)
    pull_s = time.perf_counter() - t0
    r = run("dvc", "repro", cwd=d2)
    assert "Running stage" not in r.stdout, r.stdout  # nothing recomputed
    sp = ScenePaths(d2 / "out", "kitchen_tiny")
    assert sp.metrics("evaluate").is_file() and sp.file("twin", "mjcf").is_file()
    print(f"push {push_s:.1f} s, pull {pull_s:.1f} s")

