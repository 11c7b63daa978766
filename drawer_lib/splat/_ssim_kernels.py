"""Numba kernels: SSIM of a rendered image against a target with precomputed statistics
(:func:`drawer_lib.metrics.image.ssim` with ``y_stats``: 11x11 separable Gaussian window, valid
region, mean over channels and window positions), forward and hand-written backward in float64.

x, y: [C, H, W]; stats: [2C, h, w] (mu_y, sigma_yy), h = H - size + 1, w = W - size + 1.
"""

from typing import no_type_check

import numba
import numpy as np
from numba import njit, prange

if numba.config.THREADING_LAYER == "default":
    numba.config.THREADING_LAYER = "workqueue"

C1 = 0.01**2
C2 = 0.03**2


@njit(parallel=True, cache=True)
@no_type_check
def ssim_forward(x, y, stats, win, smap_parts):
    """Returns mean SSIM; fills smap_parts [C, 3, h, w] with dS/d(mu_x, E[x^2], E[xy]) per
    window position (for the backward pass)."""
    C, H, W = x.shape
    k = win.shape[0]
    h, w = H - k + 1, W - k + 1
    tot = np.zeros(C)
    for c in prange(C):
        hb = np.zeros((3, H, w))  # horizontal pass of x, x^2, x y
        for i in range(H):
            for j in range(w):
                s0 = 0.0
                s1 = 0.0
                s2 = 0.0
                for t in range(k):
                    xv = float(x[c, i, j + t])
                    gt = win[t]
                    s0 += gt * xv
                    s1 += gt * xv * xv
                    s2 += gt * xv * float(y[c, i, j + t])
                hb[0, i, j] = s0
                hb[1, i, j] = s1
                hb[2, i, j] = s2
        acc = 0.0
        for i in range(h):
            for j in range(w):
                mx = 0.0
                exx = 0.0
                exy = 0.0
                for t in range(k):
                    gt = win[t]
                    mx += gt * hb[0, i + t, j]
                    exx += gt * hb[1, i + t, j]
                    exy += gt * hb[2, i + t, j]
                my = float(stats[c, i, j])
                syy = float(stats[C + c, i, j])
                sxx = exx - mx * mx
                sxy = exy - mx * my
                A1 = 2.0 * mx * my + C1
                A2 = 2.0 * sxy + C2
                B1 = mx * mx + my * my + C1
                B2 = sxx + syy + C2
                s = (A1 * A2) / (B1 * B2)
                acc += s
                d_exx = -s / B2
                d_exy = 2.0 * A1 / (B1 * B2)
                d_mx = 2.0 * my * A2 / (B1 * B2) - 2.0 * mx * s / B1 - 2.0 * mx * d_exx - my * d_exy
                smap_parts[c, 0, i, j] = d_mx
                smap_parts[c, 1, i, j] = d_exx
                smap_parts[c, 2, i, j] = d_exy
        tot[c] = acc
    return tot.sum() / (C * h * w)


@njit(parallel=True, cache=True)
@no_type_check
def ssim_backward(x, y, win, smap_parts, scale, gx):
    """gx [C, H, W] = scale * d(sum of SSIM map)/dx (scale = dL/dmean / (C h w))."""
    C, H, W = x.shape
    k = win.shape[0]
    h, w = H - k + 1, W - k + 1
    for c in prange(C):
        vb = np.zeros((3, H, w))  # transposed vertical pass
        for i in range(h):
            for t in range(k):
                gt = win[t]
                for j in range(w):
                    vb[0, i + t, j] += gt * smap_parts[c, 0, i, j]
                    vb[1, i + t, j] += gt * smap_parts[c, 1, i, j]
                    vb[2, i + t, j] += gt * smap_parts[c, 2, i, j]
        row = np.empty((3, W))
        for i in range(H):
            row[:] = 0.0
            for j in range(w):  # transposed horizontal pass
                for t in range(k):
                    gt = win[t]
                    row[0, j + t] += gt * vb[0, i, j]
                    row[1, j + t] += gt * vb[1, i, j]
                    row[2, j + t] += gt * vb[2, i, j]
            for j in range(W):
                xv = float(x[c, i, j])
                gx[c, i, j] = scale * (row[0, j] + 2.0 * xv * row[1, j] + float(y[c, i, j]) * row[2, j])
