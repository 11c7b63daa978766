"""Monocular depth and normal priors: an interface chosen by config, with the built-in
implementation that uses what the capture provides (after the ``priors`` stage, whose output the
SDF stage reads in place of the capture's own files: Depth Anything runs there,
``priors.model=depth_anything``).

DRAWER runs Marigold (depth, normals) on every frame. Its weights cannot be fetched here, so the
named slots below raise a clear error instead of pretending to run; a user with weights
registers an implementation with :func:`register_estimator` and selects it with
``sdf.neural.priors.estimator: <name>``.
"""

from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np

from drawer_lib.errors import ConfigError
from drawer_lib.io.capture import Capture


@runtime_checkable
class MonoEstimator(Protocol):
    """Per-frame monocular priors of a capture."""

    name: str

    def depth(self, i: int) -> np.ndarray | None:
        """Relative depth [H, W] of frame i (any per-frame scale and shift), or None."""

    def normal(self, i: int) -> np.ndarray | None:
        """Unit normals [H, W, 3] in the OpenCV camera frame of frame i, or None."""


class CapturePriors:
    """The built-in estimator: the capture's ``mono_depth/`` and ``mono_normal/`` files."""

    name = "capture"

    def __init__(self, cap: Capture):
        self.cap = cap
        self.has_depth = cap.has("mono_depth_file_path")
        self.has_normal = cap.has("mono_normal_file_path")

    def depth(self, i: int) -> np.ndarray | None:
        return self.cap.mono_depth(i) if self.has_depth else None

    def normal(self, i: int) -> np.ndarray | None:
        return self.cap.mono_normal(i) if self.has_normal else None


_REGISTRY: dict[str, Callable[[Capture], MonoEstimator]] = {"capture": CapturePriors}
_SLOTS = {
    "marigold": "Marigold depth/normals (diffusion; HF GonzaloMG/marigold-e2e-ft-*)",
    "dsine": "DSINE normals",
}


def register_estimator(name: str, factory: Callable[[Capture], MonoEstimator]) -> None:
    """Make ``sdf.neural.priors.estimator: <name>`` build ``factory(capture)``."""
    _REGISTRY[name] = factory


def make_estimator(name: str, cap: Capture) -> MonoEstimator:
    if name in _REGISTRY:
        return _REGISTRY[name](cap)
    if name == "depth_anything":
        raise ConfigError("priors.estimator = 'depth_anything': Depth Anything runs in the priors stage; set "
                          "priors.model=depth_anything and keep sdf.neural.priors.estimator=capture (which reads its maps)")
    if name in _SLOTS:
        raise ConfigError(
            f"priors.estimator = {name!r}: {_SLOTS[name]} needs model weights that are not available on this "
            f"machine; use 'capture' (the priors stored with the capture) or register an implementation with "
            f"drawer_lib.sdf.priors.register_estimator")
    raise ConfigError(f"priors.estimator = {name!r} is unknown (known: {sorted(_REGISTRY) + sorted(_SLOTS)})")
