"""LPIPS reproduces the official values on the LPIPS repository's example images."""

from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from drawer_lib.metrics.lpips import lpips

EXAMPLES = Path(__file__).resolve().parents[3] / "shared" / "data" / "lpips_examples"
LOCAL = Path(__file__).resolve().parent / "data" / "lpips_examples"


def load(name):
    d = LOCAL if (LOCAL / name).exists() else EXAMPLES
    a = np.asarray(Image.open(d / name).convert("RGB"), np.float32) / 255.0
    return torch.from_numpy(a).permute(2, 0, 1)[None]


def test_official_example_distances():
    ref, p0, p1 = load("ex_ref.png"), load("ex_p0.png"), load("ex_p1.png")
    assert lpips(ref, p0).item() == pytest.approx(0.722, abs=5e-4)
    assert lpips(ref, p1).item() == pytest.approx(0.138, abs=5e-4)
    assert lpips(ref, ref).item() == pytest.approx(0.0, abs=1e-7)
    # batched, symmetric
    d = lpips(torch.cat([ref, p0]), torch.cat([p1, ref]))
    assert d[1].item() == pytest.approx(0.722, abs=5e-4)


def test_small_images_are_refused():
    with pytest.raises(ValueError, match="32x32"):
        lpips(torch.rand(1, 3, 16, 16), torch.rand(1, 3, 16, 16))
