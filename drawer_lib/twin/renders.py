"""Opened-state renders of a twin and their scores (``renders/`` and opened-state NVS in docs/formats.md).

The twin's Gaussians are one set per body (``static`` and one per articulated part, world frame
at q = 0). A view of part ``pid`` opened to ``q``: the part's Gaussians moved by its joint
(:func:`drawer_lib.io.parts.joint_motion`), every other body at q = 0, all rendered
together. On a synthetic scene the same view of the scene's own model with the GT part's joint
at the same ``q`` is the reference: ``open_psnr``, ``open_ssim``, ``open_lpips`` over the whole
image and ``open_region_psnr`` inside the region the moving part covers in either image (the
twin's part alpha > 0.5, or the GT part's pixels in the GT segmentation).
"""

from dataclasses import dataclass

import numpy as np
import torch
from jaxtyping import Float
from torch import Tensor

from drawer_lib.geometry.camera import Camera
from drawer_lib.io.parts import Part, joint_motion
from drawer_lib.splat.gaussians import concat, transform
from drawer_lib.splat.render import Gaussians, render


def opened_q(part: Part, fraction: float = 0.5) -> float:
    """The joint value ``fraction`` of the way to the part's upper limit (rad or m)."""
    lo, hi = part.limits
    return float(lo + fraction * (hi - lo))


@dataclass
class OpenedView:
    rgb: Float[Tensor, "H W 3"]  # in [0, 1]
    part_alpha: Float[Tensor, "H W"]  # coverage of the moving part's Gaussians (occlusion by the rest ignored)


def render_opened(static: Gaussians, bodies: dict[str, Gaussians], parts: dict[str, Part], pid: str, q: float,
                  cams: list[Camera], sh_degree: int, background: Float[Tensor, "3"]) -> list[OpenedView]:
    """Views ``cams`` of the twin with part ``pid`` at joint value ``q`` and every other body closed."""
    R, t = joint_motion(parts[pid], q)
    moved = transform(bodies[pid], R, t)
    scene = concat([static, *(g for k, g in bodies.items() if k != pid), moved])
    out = []
    with torch.no_grad():
        for cam in cams:
            rgb = render(scene, cam, sh_degree, background).rgb.clamp(0, 1)
            alpha = render(moved, cam, sh_degree, background).alpha if len(moved.means) else torch.zeros(cam.height, cam.width)
            out.append(OpenedView(rgb, alpha))
    return out


def region_psnr(pred: Float[Tensor, "H W 3"], gt: Float[Tensor, "H W 3"], mask: Float[Tensor, "H W"] | np.ndarray) -> float | None:
    """PSNR (data range 1) over the pixels of ``mask``; None for an empty mask."""
    m = torch.as_tensor(np.asarray(mask), dtype=torch.bool)
    if not bool(m.any()):
        return None
    mse = ((pred - gt) ** 2)[m].mean().clamp_min(1e-10)
    return float(-10.0 * torch.log10(mse))
