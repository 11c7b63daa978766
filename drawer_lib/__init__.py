"""drawer_lib: the library behind the DRAWER pipeline (all logic; no CLI code).

Subpackages follow the data flow of the paper: ``io`` (captures, manifests, parts files),
``geometry`` (conventions and pure camera/rotation ops), ``synth`` (procedural kitchens with
ground truth), ``sfm`` (video -> posed frames), ``metrics`` (scoring against ground truth),
``config`` (typed configs and the params.yaml composition), ``runner`` (the stage runner).

Threads: the heavy kernels here (compositor, projection, SH, SDF grid encoding, SSIM) are numba
``prange`` loops between small torch ops. torch's OpenMP workers (GNU libgomp) spin-wait after
each parallel op, by default for ~300k spins (milliseconds), and so keep the other cores busy
while the numba kernel that follows wants them: on 2 cores a training step of the paper's method
took 64-70 ms with both threads, about what one thread gives (74 ms), and 44-50 ms once the
workers wait passively (docs/speed.md, section *Threads*). Importing drawer_lib
therefore sets ``OMP_WAIT_POLICY=PASSIVE`` unless the environment already sets it (libgomp reads
it once, when torch loads, so this only takes effect if drawer_lib is imported before torch;
``omp_wait_policy()`` says which one this process got). Results do not depend on it: only when
the waiting threads burn cycles. ``OMP_WAIT_POLICY=ACTIVE`` (or any value) in the environment
keeps that choice.
"""

import os
import sys

__version__ = "0.1.0"

if "torch" not in sys.modules:  # else libgomp has read its settings already
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
elif "OMP_WAIT_POLICY" not in os.environ and sys.modules["torch"].get_num_threads() > 1:
    import warnings

    warnings.warn("torch was imported before drawer_lib, so its OpenMP workers keep libgomp's spin-waiting, which "
                  "takes the cores from drawer_lib's numba kernels (a 2-thread training step ~1.4x slower): import "
                  "drawer_lib first, or set OMP_WAIT_POLICY=PASSIVE (or ACTIVE to keep spinning and silence this)",
                  RuntimeWarning, stacklevel=2)
_WAIT_POLICY = os.environ.get("OMP_WAIT_POLICY", "default")


def omp_wait_policy() -> str:
    """The OpenMP wait policy torch's thread pool got in this process (as far as drawer_lib can
    tell, at its import): ``OMP_WAIT_POLICY``'s value, or ``"default"`` (libgomp's spin, then
    sleep) when it was unset, e.g. because torch was imported before drawer_lib."""
    return _WAIT_POLICY
