"""Choose MuJoCo's offscreen GL backend before mujoco is imported (it reads ``MUJOCO_GL`` once,
at import). An explicit ``MUJOCO_GL`` wins; otherwise EGL if ``libEGL`` loads, else OSMesa.
Both are Mesa software rasterisers on CPU machines and give identical images."""

import ctypes
import logging
import os


def default_gl_backend() -> str:
    try:
        ctypes.CDLL("libEGL.so.1")
        return "egl"
    except OSError:
        return "osmesa"


def select_gl_backend() -> str:
    if not os.environ.get("MUJOCO_GL"):
        os.environ["MUJOCO_GL"] = default_gl_backend()
    logging.getLogger("OpenGL").setLevel(logging.WARNING)  # PyOpenGL announces optional accelerators
    return os.environ["MUJOCO_GL"]


select_gl_backend()
