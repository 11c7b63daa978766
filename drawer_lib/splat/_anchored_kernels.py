"""Numba kernels: the mesh-anchored parametrisation (:func:`drawer_lib.splat.anchored.anchored_gaussians`)
fused per Gaussian, forward and hand-written backward, for the clip modes whose gradient is the
identity (``ste``: clipped values, gradient passed straight through; ``free``: no clip).

Per Gaussian i on face f: position A + u xhat + v yhat + e n ((u, v) barycentric-clipped to the
face triangle, e clipped to +- elevate_coef R), scales exp(log s) capped at upper_scale (R, R,
flat_coef R), rotation q_face (x) q_tilt (x) q_spin with q_spin = (cos t/2, 0, 0, sin t/2),
q_tilt = (cos phi/2, cos a sin phi/2, sin a sin phi/2, 0), phi clipped to [0, cone], opacity
sigmoid(logit). Arithmetic in float64, outputs in the inputs' dtype: equal to the PyTorch
reference up to float rounding (tested)."""

import math
from typing import no_type_check

import numba
from numba import njit, prange

if numba.config.THREADING_LAYER == "default":
    numba.config.THREADING_LAYER = "workqueue"

# columns of the forward pass's per-Gaussian values kept for the backward pass (``aux``)
A_CS, A_SS, A_CT, A_ST, A_CA, A_SA, A_S, A_O = 0, 1, 2, 3, 4, 5, 6, 9  # A_S..A_S + 2: the unclipped scales
N_AUX = 10


@njit(parallel=True, cache=True)
@no_type_check
def anchored_forward(means_2d, elevate, log_scales, angles, opacity_logit, face, A, xhat, yhat, normal, tri2d, radius,
                     q_face, elevate_coef, upper_scale, flat_coef, cone, clip,
                     means, quats, scales, opac, pos2d, elev, tilt, aux):
    """Outputs means [N, 3], quats [N, 4] (wxyz, unit), scales [N, 3], opac [N], pos2d [N, 2],
    elev [N], tilt [N]; ``clip`` True: clipped values (ste), False: raw values (free). ``aux``
    [N, N_AUX] float64 (or [0, N_AUX]: not kept): the transcendental values the backward pass
    needs (the half-angle cosines and sines, the unclipped scales, the opacity), so that it
    does not evaluate them again."""
    keep = aux.shape[0] > 0
    for i in prange(means_2d.shape[0]):
        f = face[i]
        R = float(radius[f])
        u, v = float(means_2d[i, 0]), float(means_2d[i, 1])
        if clip:  # barycentric coordinates clipped to [0, 1], renormalised, mapped back
            ax, ay = float(tri2d[f, 0, 0]), float(tri2d[f, 0, 1])
            v0x, v0y = tri2d[f, 1, 0] - ax, tri2d[f, 1, 1] - ay
            v1x, v1y = tri2d[f, 2, 0] - ax, tri2d[f, 2, 1] - ay
            v2x, v2y = u - ax, v - ay
            d00 = v0x * v0x + v0y * v0y
            d01 = v0x * v1x + v0y * v1y
            d11 = v1x * v1x + v1y * v1y
            d20 = v2x * v0x + v2y * v0y
            d21 = v2x * v1x + v2y * v1y
            den = max(d00 * d11 - d01 * d01, 1e-30)
            l1 = (d11 * d20 - d01 * d21) / den
            l2 = (d00 * d21 - d01 * d20) / den
            l0 = min(max(1.0 - l1 - l2, 0.0), 1.0)
            l1 = min(max(l1, 0.0), 1.0)
            l2 = min(max(l2, 0.0), 1.0)
            sm = max(l0 + l1 + l2, 1e-30)
            l0, l1, l2 = l0 / sm, l1 / sm, l2 / sm
            u = l0 * tri2d[f, 0, 0] + l1 * tri2d[f, 1, 0] + l2 * tri2d[f, 2, 0]
            v = l0 * tri2d[f, 0, 1] + l1 * tri2d[f, 1, 1] + l2 * tri2d[f, 2, 1]
        e = float(elevate[i])
        if clip:
            e = max(min(e, elevate_coef * R), -elevate_coef * R)
        pos2d[i, 0] = u
        pos2d[i, 1] = v
        elev[i] = e
        for k in range(3):
            means[i, k] = A[f, k] + u * xhat[f, k] + v * yhat[f, k] + e * normal[f, k]
        for k in range(3):
            s = math.exp(float(log_scales[i, k]))
            if keep:
                aux[i, A_S + k] = s
            if clip:
                s = min(s, upper_scale * (R if k < 2 else flat_coef * R))
            scales[i, k] = s
        th, al, phi = float(angles[i, 0]), float(angles[i, 1]), float(angles[i, 2])
        if clip:
            phi = min(max(phi, 0.0), cone)
        tilt[i] = phi
        cs, ss = math.cos(0.5 * th), math.sin(0.5 * th)
        ct, st = math.cos(0.5 * phi), math.sin(0.5 * phi)
        ca, sa = math.cos(al), math.sin(al)
        # b = q_tilt (x) q_spin, q_tilt = (ct, ca st, sa st, 0), q_spin = (cs, 0, 0, ss)
        bw = ct * cs
        bx = ca * st * cs + sa * st * ss
        by = sa * st * cs - ca * st * ss
        bz = ct * ss
        aw, ax_, ay_, az = float(q_face[f, 0]), float(q_face[f, 1]), float(q_face[f, 2]), float(q_face[f, 3])
        quats[i, 0] = aw * bw - ax_ * bx - ay_ * by - az * bz
        quats[i, 1] = aw * bx + ax_ * bw + ay_ * bz - az * by
        quats[i, 2] = aw * by - ax_ * bz + ay_ * bw + az * bx
        quats[i, 3] = aw * bz + ax_ * by - ay_ * bx + az * bw
        o = 1.0 / (1.0 + math.exp(-float(opacity_logit[i])))
        opac[i] = o
        if keep:
            aux[i, A_CS] = cs
            aux[i, A_SS] = ss
            aux[i, A_CT] = ct
            aux[i, A_ST] = st
            aux[i, A_CA] = ca
            aux[i, A_SA] = sa
            aux[i, A_O] = o


@njit(parallel=True, cache=True)
@no_type_check
def anchored_backward(aux, face, xhat, yhat, normal, q_face,
                      g_means, g_quats, g_scales, g_opac, g_pos2d, g_elev, g_tilt,
                      gm2, ge, gls, gang, gol):
    """VJP of anchored_forward (identity through every clip) into gm2 [N, 2] (means_2d), ge [N]
    (elevate), gls [N, 3] (log_scales), gang [N, 3] (angles), gol [N] (opacity_logit), from the
    forward pass's ``aux`` [N, N_AUX] (the same values it would recompute, so the same bits)."""
    for i in prange(aux.shape[0]):
        f = face[i]
        gx, gy, gz = float(g_means[i, 0]), float(g_means[i, 1]), float(g_means[i, 2])
        gm2[i, 0] = gx * xhat[f, 0] + gy * xhat[f, 1] + gz * xhat[f, 2] + g_pos2d[i, 0]
        gm2[i, 1] = gx * yhat[f, 0] + gy * yhat[f, 1] + gz * yhat[f, 2] + g_pos2d[i, 1]
        ge[i] = gx * normal[f, 0] + gy * normal[f, 1] + gz * normal[f, 2] + g_elev[i]
        for k in range(3):
            gls[i, k] = g_scales[i, k] * aux[i, A_S + k]  # d exp(x) / dx of the raw scale
        cs, ss = aux[i, A_CS], aux[i, A_SS]
        ct, st = aux[i, A_CT], aux[i, A_ST]
        ca, sa = aux[i, A_CA], aux[i, A_SA]
        aw, ax_, ay_, az = float(q_face[f, 0]), float(q_face[f, 1]), float(q_face[f, 2]), float(q_face[f, 3])
        qw, qx, qy, qz = float(g_quats[i, 0]), float(g_quats[i, 1]), float(g_quats[i, 2]), float(g_quats[i, 3])
        # q = a (x) b: gradient to b
        hw = qw * aw + qx * ax_ + qy * ay_ + qz * az
        hx = -qw * ax_ + qx * aw + qy * az - qz * ay_
        hy = -qw * ay_ - qx * az + qy * aw + qz * ax_
        hz = -qw * az + qx * ay_ - qy * ax_ + qz * aw
        # b = t (x) s with t = (ct, ca st, sa st, 0), s = (cs, 0, 0, ss)
        tw, tx, ty = ct, ca * st, sa * st
        # gradient to t (a = t, b = s in the product rule)
        gtw = hw * cs + hz * ss
        gtx = hx * cs - hy * ss
        gty = hx * ss + hy * cs
        # gradient to s
        gsw = hw * tw + hx * tx + hy * ty
        gsz = -hw * 0.0 + hx * ty - hy * tx + hz * tw
        gang[i, 0] = gsw * (-0.5 * ss) + gsz * (0.5 * cs)
        gang[i, 1] = (-gtx * sa + gty * ca) * st
        gang[i, 2] = gtw * (-0.5 * st) + (gtx * ca + gty * sa) * (0.5 * ct) + g_tilt[i]
        o = aux[i, A_O]
        gol[i] = g_opac[i] * o * (1.0 - o)
