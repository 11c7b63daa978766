"""Slow, obviously correct per-pixel compositing (the twin of drawer_lib.splat.rasterize)."""

import torch

ALPHA_MIN, ALPHA_MAX, T_MIN = 1.0 / 255.0, 0.999, 1e-4


def composite_reference(means2d, conics, opacities, colors, depths, radii, width, height):
    """For every pixel: all unculled Gaussians sorted by depth, the same skip / clamp /
    termination rules, written as a plain loop (autograd gives the gradients)."""
    order = [int(i) for i in torch.argsort(depths.detach(), stable=True) if radii[i] > 0]
    rows = []
    for py in range(height):
        row = []
        for px in range(width):
            x, y = px + 0.5, py + 0.5
            T = torch.ones((), dtype=means2d.dtype)
            c = torch.zeros(3, dtype=means2d.dtype)
            d = torch.zeros((), dtype=means2d.dtype)
            for g in order:
                dx, dy = means2d[g, 0] - x, means2d[g, 1] - y
                p = -0.5 * (conics[g, 0] * dx * dx + conics[g, 2] * dy * dy) - conics[g, 1] * dx * dy
                if p > 0:
                    continue
                a = torch.clamp(opacities[g] * torch.exp(p), max=ALPHA_MAX)
                if a < ALPHA_MIN:
                    continue
                nT = T * (1 - a)
                if nT <= T_MIN:
                    break
                c = c + a * T * colors[g]
                d = d + a * T * depths[g]
                T = nT
            row.append(torch.cat([c, d[None], (1 - T)[None]]))
        rows.append(torch.stack(row))
    out = torch.stack(rows)  # [H, W, 5]
    return out[..., :3], out[..., 3], out[..., 4]
