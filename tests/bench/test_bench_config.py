"""The benchmark's config refuses kitchens a split does not have."""

import pytest

from drawer_lib.bench.config import BenchConfig
from drawer_lib.errors import ConfigError


def test_the_hand_split_has_eight_kitchens():
    assert BenchConfig().splits == ["train", "test"]  # the hand split is asked for, not run by default
    BenchConfig(splits=["train", "hand"], kitchens=list(range(8)))
    with pytest.raises(ConfigError, match=r"kitchens 0 \.\. 7; bench.kitchens = \[0, 8\]"):
        BenchConfig(splits=["train", "hand"], kitchens=[0, 8])
    with pytest.raises(ConfigError, match="the train split among them"):
        BenchConfig(splits=["hand"], kitchens=[0])
