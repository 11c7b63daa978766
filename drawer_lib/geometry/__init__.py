"""Conventions shared by every module (stated once, here).

- Units: metres and radians. World frame: right-handed, +z up when known (synthetic kitchens:
  back wall in the plane y = 0, cabinets at y < 0, fronts facing -y, x to the viewer's right).
- Cameras inside the library use the **OpenCV** convention: x right, y down, z forward;
  ``w2c`` (world-to-camera, 4x4) is what projections take, ``c2w`` its rigid inverse.
  ``transforms.json`` stores **OpenGL** camera-to-world matrices (x right, y up, z backward)
  as nerfstudio does; :func:`opengl_to_opencv` / :func:`opencv_to_opengl` are the only places
  where axes are flipped, and only ``drawer_lib.io`` calls them.
- Pixels: the centre of pixel (row i, column j) is at image coordinates (j + 0.5, i + 0.5)
  (the COLMAP / nerfstudio convention: a centred principal point is cx = W / 2).
  :meth:`Intrinsics.K_opencv` gives the matrix for the OpenCV convention (centre of the
  top-left pixel at (0, 0)), i.e. cx - 0.5.
- Quaternions: (w, x, y, z), as MuJoCo, gsplat and kornia.
- Depth: z-depth, the distance along the optical axis, never the ray length.
"""

from drawer_lib.geometry.camera import (
    Intrinsics,
    check_rigid,
    invert_rigid,
    look_at_opencv,
    opencv_to_opengl,
    opengl_to_opencv,
    project_points,
)

_LAZY = {"matrix_to_quat": "rotations", "quat_to_matrix": "rotations", "rotation_angle": "rotations",
         "apply_transform": "joints", "joint_transform": "joints"}  # torch: imported on first use


def __getattr__(name: str):
    # the rotations are torch functions; importing torch eagerly cost every stage ~2 s of start-up,
    # also those that never rotate anything (evaluate, simulate, stability, the tables, report)
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"drawer_lib.geometry.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'drawer_lib.geometry' has no attribute {name!r}")


__all__ = [
    "Intrinsics",
    "apply_transform",
    "check_rigid",
    "invert_rigid",
    "joint_transform",
    "look_at_opencv",
    "matrix_to_quat",
    "opencv_to_opengl",
    "opengl_to_opencv",
    "project_points",
    "quat_to_matrix",
    "rotation_angle",
]
