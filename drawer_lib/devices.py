"""The torch device a config key names (``detect.device``, ``priors.device``, ``detector.device``,
``articulate.vlm.device``, gsplat's), checked before any work: a name torch does not know, or
CUDA where this torch build sees none, is a :class:`~drawer_lib.errors.ConfigError` naming the
key, not an assertion deep inside a model's ``.to()``."""

from contextlib import AbstractContextManager, nullcontext

import torch

from drawer_lib.errors import ConfigError


def torch_device(name: str, key: str, hint: str = "use cpu") -> torch.device:
    """``name`` (``cpu``, ``cuda`` or ``cuda:<index>``: the devices this project runs and tests on) as a
    :class:`torch.device` this process can use; ``key`` names the setting in the error, ``hint``
    says what to do instead.

    >>> torch_device("cpu", "detect.device")
    device(type='cpu')
    """
    try:
        dev = torch.device(name)
    except (RuntimeError, TypeError) as e:
        raise ConfigError(f"{key} = {name!r}: not a torch device (cpu, cuda, cuda:<index>)") from e
    if dev.type not in ("cpu", "cuda"):
        raise ConfigError(f"{key} = {name!r}: only cpu and cuda are supported")
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise ConfigError(f"{key} = {name!r}: this torch ({torch.__version__}) sees no CUDA device; {hint}")
        n = torch.cuda.device_count()
        if dev.index is not None and dev.index >= n:
            raise ConfigError(f"{key} = {name!r}: this machine has {n} CUDA device(s), cuda:0 to cuda:{n - 1}")
    return dev


def device_name(name: str | torch.device) -> str:
    """What a stage's metrics record of the device ``name``: ``cpu``, or CUDA's index and the
    card's name (``cuda:0 NVIDIA H200``)."""
    dev = torch.device(name)
    if dev.type != "cuda":
        return dev.type
    i = dev.index if dev.index is not None else torch.cuda.current_device()
    return f"cuda:{i} {torch.cuda.get_device_name(i)}"


def cuda_numerics(dev: torch.device) -> AbstractContextManager:
    """The numerics a network runs under on ``dev``, in its fit and when it is applied: on CUDA,
    cuDNN's deterministic convolutions in full float32 and without autotuning, so every run
    picks the same kernels. cuDNN's TF32 default rounds a convolution's inputs to a 10-bit
    mantissa (about 1e-3 relative); it moved a fit's third loss by 1.5e-4 on an H200. Its effect
    on the detector's probabilities was not measured, but it is rounding far coarser than
    float32's, whose size already moves a part in the tuning kitchens' jitter study. (In a fit,
    the bilinear upsampling's and max-pooling's backward passes still add with atomics, so two
    CUDA fits can differ in the last bits.) On the CPU nothing changes.

    >>> import contextlib; isinstance(cuda_numerics(torch.device("cpu")), contextlib.nullcontext)
    True
    """
    if dev.type != "cuda":
        return nullcontext()
    return torch.backends.cudnn.flags(enabled=True, benchmark=False, deterministic=True, allow_tf32=False)
