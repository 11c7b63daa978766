"""Numba kernels of the multi-resolution grid encoding (forward and table gradient).

Same arithmetic as the PyTorch reference in :mod:`drawer_lib.sdf.encoding` (tested against it):
per point and level, the 8 corners of the enclosing cell are looked up (dense index or spatial
hash), features are trilinearly weighted and, optionally, so are the weights' derivatives with
respect to x. The forward pass runs in parallel over points; the backward pass scatters into the
table in parallel over levels (levels own disjoint table rows, so there are no races).
"""

from typing import no_type_check

import numba
import numpy as np
from numba import njit, prange

if numba.config.THREADING_LAYER == "default":
    # the machine's TBB is too old for numba (it warns and falls back); say what we use
    numba.config.THREADING_LAYER = "workqueue"

P1 = np.int64(2654435761)
P2 = np.int64(805459861)


@njit(cache=True, inline="always")
@no_type_check  # keep the test-suite type-check hook away from numba
def _cell(u, r):
    p = u * r
    i = int(np.floor(p))
    if i > r - 1:
        i = r - 1
    if i < 0:
        i = 0
    return i, p - i


@njit(cache=True, inline="always")
@no_type_check  # keep the test-suite type-check hook away from numba
def _index(cx, cy, cz, ry, rz, size, hashed, offset):
    if hashed:
        h = (np.int64(cx)) ^ (np.int64(cy) * P1) ^ (np.int64(cz) * P2)  # >= 0 (cells and primes are)
        if size & (size - 1) == 0:  # a power-of-two table (always, from MultiResGrid): a mask, no division
            return offset + (h & (size - 1))
        return offset + h % size
    return offset + (np.int64(cx) * (ry + 1) + cy) * (rz + 1) + cz


@njit(parallel=True, cache=True)
@no_type_check  # keep the test-suite type-check hook away from numba
def encode_forward(x, lo, ext, res, sizes, offsets, hashed, table, with_grad, feat, dfeat):
    N = x.shape[0]
    L = res.shape[0]
    F = table.shape[1]
    for n in prange(N):
        ux = min(max((x[n, 0] - lo[0]) / ext[0], 0.0), 1.0)
        uy = min(max((x[n, 1] - lo[1]) / ext[1], 0.0), 1.0)
        uz = min(max((x[n, 2] - lo[2]) / ext[2], 0.0), 1.0)
        for l in range(L):
            rx, ry, rz = res[l, 0], res[l, 1], res[l, 2]
            ix, tx = _cell(ux, rx)
            iy, ty = _cell(uy, ry)
            iz, tz = _cell(uz, rz)
            sx, sy, sz = rx / ext[0], ry / ext[1], rz / ext[2]
            for c in range(8):
                dx, dy, dz = (c >> 2) & 1, (c >> 1) & 1, c & 1
                idx = _index(ix + dx, iy + dy, iz + dz, ry, rz, sizes[l], hashed[l], offsets[l])
                wx = tx if dx else 1.0 - tx
                wy = ty if dy else 1.0 - ty
                wz = tz if dz else 1.0 - tz
                w = wx * wy * wz
                for f in range(F):
                    v = table[idx, f]
                    feat[n, l * F + f] += w * v
                    if with_grad:
                        dfeat[n, l * F + f, 0] += (1.0 if dx else -1.0) * wy * wz * sx * v
                        dfeat[n, l * F + f, 1] += (1.0 if dy else -1.0) * wx * wz * sy * v
                        dfeat[n, l * F + f, 2] += (1.0 if dz else -1.0) * wx * wy * sz * v


@njit(parallel=True, cache=True)
@no_type_check  # keep the test-suite type-check hook away from numba
def encode_backward(x, lo, ext, res, sizes, offsets, hashed, gfeat, gdfeat, with_grad, gtable):
    N = x.shape[0]
    L = res.shape[0]
    F = gtable.shape[1]
    for l in prange(L):
        rx, ry, rz = res[l, 0], res[l, 1], res[l, 2]
        sx, sy, sz = rx / ext[0], ry / ext[1], rz / ext[2]
        for n in range(N):
            ux = min(max((x[n, 0] - lo[0]) / ext[0], 0.0), 1.0)
            uy = min(max((x[n, 1] - lo[1]) / ext[1], 0.0), 1.0)
            uz = min(max((x[n, 2] - lo[2]) / ext[2], 0.0), 1.0)
            ix, tx = _cell(ux, rx)
            iy, ty = _cell(uy, ry)
            iz, tz = _cell(uz, rz)
            for c in range(8):
                dx, dy, dz = (c >> 2) & 1, (c >> 1) & 1, c & 1
                idx = _index(ix + dx, iy + dy, iz + dz, ry, rz, sizes[l], hashed[l], offsets[l])
                wx = tx if dx else 1.0 - tx
                wy = ty if dy else 1.0 - ty
                wz = tz if dz else 1.0 - tz
                w = wx * wy * wz
                for f in range(F):
                    g = w * gfeat[n, l * F + f]
                    if with_grad:
                        g += (1.0 if dx else -1.0) * wy * wz * sx * gdfeat[n, l * F + f, 0]
                        g += (1.0 if dy else -1.0) * wx * wz * sy * gdfeat[n, l * F + f, 1]
                        g += (1.0 if dz else -1.0) * wx * wy * sz * gdfeat[n, l * F + f, 2]
                    gtable[idx, f] += g
