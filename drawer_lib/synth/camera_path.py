"""A hand-held-like camera path in front of a kitchen.

The camera sweeps along the run ``passes`` times (left to right and back), its distance to the
fronts and its height drift smoothly, its gaze moves from the base cabinets (first sweep) to the
wall cabinets (last sweep) and wanders sideways, and a smooth hand shake (position and
rotation, including roll) is added. Everything is a smooth function of the path parameter, so
consecutive frames overlap strongly, as in a video.
"""

import numpy as np

from drawer_lib.geometry.camera import look_at_opencv
from drawer_lib.geometry.rotations import axis_angle_to_matrix
from drawer_lib.synth.config import CameraPathConfig
from drawer_lib.synth.layout import KitchenLayout


def _smooth_noise(rng: np.random.Generator, s: np.ndarray, dims: int, cycles=(1.5, 5.0), terms: int = 3) -> np.ndarray:
    """Sum of random sinusoids over s in [0, 1], [len(s), dims], unit RMS per dimension."""
    out = np.zeros((len(s), dims))
    for d in range(dims):
        for _ in range(terms):
            f = rng.uniform(*cycles)
            out[:, d] += np.sin(2 * np.pi * f * s + rng.uniform(0, 2 * np.pi))
    return out / np.sqrt(terms / 2.0)


def camera_path(layout: KitchenLayout, cfg: CameraPathConfig, rng: np.random.Generator) -> np.ndarray:
    """OpenCV camera-to-world matrices [C, 4, 4] of a capture of ``layout`` (the path is laid
    out in the kitchen's own frame, then moved by ``layout.pose``)."""
    n = cfg.n_frames
    s = np.linspace(0.0, 1.0, n)
    x_lo, x_hi = layout.run_x
    xc, half = (x_lo + x_hi) / 2, (x_hi - x_lo) / 2 + cfg.margin
    # keep the eye away from the side walls
    half = max(min(half, (layout.room_hi[0] - layout.room_lo[0]) / 2 - 0.4), 0.05)
    phase = np.pi * cfg.passes * s
    x = xc - half * np.cos(phase)
    d0, d1 = cfg.distance
    dist = d0 + (d1 - d0) * (0.5 + 0.5 * np.sin(2 * np.pi * 1.3 * s + rng.uniform(0, 2 * np.pi)))
    h0, h1 = cfg.eye_height
    eye_z = h0 + (h1 - h0) * (0.5 - 0.5 * np.cos(np.pi * s)) + 0.03 * np.sin(2 * np.pi * 3 * s + rng.uniform(0, 6))
    eye_z = np.clip(eye_z, h0, h1)
    eye = np.stack([x, layout.front_y - dist, eye_z], -1)

    z_lo = 0.7  # upper half of the base cabinets
    z_hi = 1.45  # lower edge of the wall cabinets
    tgt_z = z_lo + (z_hi - z_lo) * (0.5 - 0.5 * np.cos(np.pi * s))
    tgt_x = x + 0.3 * np.sin(2 * np.pi * 0.8 * cfg.passes * s + rng.uniform(0, 2 * np.pi))
    tgt_x = np.clip(tgt_x, x_lo + 0.4, x_hi - 0.4) if x_hi - x_lo > 0.8 else np.full(n, xc)
    tgt = np.stack([tgt_x, np.full(n, layout.front_y + 0.2), tgt_z], -1)

    eye = eye + cfg.jitter_pos_m * _smooth_noise(rng, s, 3, cycles=(3.0, 9.0))
    rot_noise = np.deg2rad(cfg.jitter_rot_deg) * _smooth_noise(rng, s, 3, cycles=(2.0, 8.0))

    up = np.array([0.0, 0.0, 1.0])
    poses = np.empty((n, 4, 4))
    for k in range(n):
        T = look_at_opencv(eye[k], tgt[k], up)
        w = rot_noise[k]
        ang = np.linalg.norm(w)
        if ang > 0:
            T[:3, :3] = T[:3, :3] @ axis_angle_to_matrix(w / ang, ang)  # shake in the camera frame
        poses[k] = T
    return np.einsum("ij,njk->nik", layout.pose, poses)  # kitchen frame -> world
