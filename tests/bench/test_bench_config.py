"""The benchmark's config refuses kitchens a split does not have."""

import pytest

from drawer_lib.bench.config import BenchConfig
from drawer_lib.errors import ConfigError


def test_the_hand_split_has_eight_kitchens():
    assert BenchConfig().splits == ["train", "test"]  # the hand split has its own stages (below)
    BenchConfig(splits=["train", "hand"], kitchens=list(range(8)))
    with pytest.raises(ConfigError, match=r"kitchens 0 \.\. 7; bench.kitchens = \[0, 8\]"):
        BenchConfig(splits=["train", "hand"], kitchens=[0, 8])
    with pytest.raises(ConfigError, match="the train split among them"):
        BenchConfig(splits=["hand"], kitchens=[0])


def test_the_hand_kitchens_of_the_dag():
    """bench_hand@<k> and bench_eval_hand build and score bench.hand_kitchens (all eight by
    default); kitchens the hand split lacks, repeats and an empty list are refused."""
    bc = BenchConfig()
    assert bc.hand_kitchens == list(range(8))
    assert bc.split_kitchens("hand") == list(range(8)) and bc.split_kitchens("test") == bc.kitchens
    assert BenchConfig(splits=["train", "hand"], kitchens=[0, 1]).split_kitchens("hand") == [0, 1]
    for bad, msg in (([0, 8], r"bench.hand_kitchens = \[0, 8\]: the hand split has kitchens 0 \.\. 7"),
                     ([1, 1], "distinct"), ([], "distinct"), ([-1], "distinct")):
        with pytest.raises(ConfigError, match=msg):
            BenchConfig(hand_kitchens=bad)
    with pytest.raises(ConfigError, match="split 'other' is not scored"):
        bc.split_kitchens("other")


def test_the_bench_stages_refuse_a_split_or_kitchen_they_do_not_score(tmp_path):
    """Before any work: an unknown split, and a kitchen the benchmark does not list."""
    from tests.helpers import run_stage

    r = run_stage("bench_eval", tmp_path, "+bench_split=other")
    assert r.returncode != 0 and "split 'other' is not scored" in r.stderr
    r = run_stage("bench_kitchen", tmp_path, "+bench_split=hand", "+bench_kitchen=3", "bench.hand_kitchens=[0,1]")
    assert r.returncode != 0 and "kitchen 3 of the hand split is not in the benchmark ([0, 1])" in r.stderr
    assert not (tmp_path / "bench").exists()
