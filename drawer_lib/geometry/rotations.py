"""Rotations. Quaternions are (w, x, y, z); the quaternion <-> matrix conversions take numpy
arrays or torch tensors (one implementation, in torch)."""

import numpy as np
import torch
from jaxtyping import Float
from torch import Tensor


def _as_torch(x):
    """(tensor, back): a torch view of ``x`` and the function returning results in ``x``'s kind
    (numpy arrays go through float64 tensors and come back as float64 arrays)."""
    if isinstance(x, torch.Tensor):
        return x, lambda t: t
    return torch.as_tensor(np.asarray(x, np.float64)), lambda t: t.numpy()


def quat_to_matrix(q: Float[np.ndarray, "*B 4"] | Float[Tensor, "*B 4"]) -> Float[np.ndarray, "*B 3 3"] | Float[Tensor, "*B 3 3"]:
    """Quaternions (w, x, y, z) of any norm -> rotation matrices, batched; numpy arrays or torch
    tensors (differentiable) alike.

    >>> quat_to_matrix(np.array([0.0, 0.0, 0.0, 2.0])).round(6).tolist()[0]
    [-1.0, 0.0, 0.0]
    """
    t, back = _as_torch(q)
    t = t / t.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    w, x, y, z = t.unbind(-1)
    R = torch.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)
    return back(R.reshape(t.shape[:-1] + (3, 3)))


def matrix_to_quat(R: Float[np.ndarray, "*B 3 3"] | Float[Tensor, "*B 3 3"]) -> Float[np.ndarray, "*B 4"] | Float[Tensor, "*B 4"]:
    """Rotation matrices -> unit quaternions (w, x, y, z) with w >= 0, batched (Shepperd's
    method: the branch of the largest diagonal term, stable near 180 degrees); numpy arrays or
    torch tensors alike."""
    t, back = _as_torch(R)
    shape = t.shape[:-2]
    M = t.reshape(-1, 3, 3)
    m00, m11, m22 = M[:, 0, 0], M[:, 1, 1], M[:, 2, 2]
    tr = m00 + m11 + m22
    cands = torch.stack([1 + tr, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    k = cands.argmax(-1)
    s = torch.sqrt(cands.gather(1, k[:, None])[:, 0].clamp_min(1e-12)) * 2  # 4 * |component|
    r21, r12, r02, r20, r10, r01 = M[:, 2, 1], M[:, 1, 2], M[:, 0, 2], M[:, 2, 0], M[:, 1, 0], M[:, 0, 1]
    q0 = torch.stack([s / 4, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s], -1)
    q1 = torch.stack([(r21 - r12) / s, s / 4, (r01 + r10) / s, (r02 + r20) / s], -1)
    q2 = torch.stack([(r02 - r20) / s, (r01 + r10) / s, s / 4, (r12 + r21) / s], -1)
    q3 = torch.stack([(r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, s / 4], -1)
    q = torch.where((k == 0)[:, None], q0, torch.where((k == 1)[:, None], q1, torch.where((k == 2)[:, None], q2, q3)))
    q = q / q.norm(dim=-1, keepdim=True)
    q = torch.where(q[:, :1] < 0, -q, q)
    return back(q.reshape(shape + (4,)))


def quat_mul(a: Float[Tensor, "*B 4"], b: Float[Tensor, "*B 4"]) -> Float[Tensor, "*B 4"]:
    """Hamilton product of wxyz quaternions [..., 4] (torch tensors)."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                        aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], -1)


def axis_angle_to_quat(v: Float[Tensor, "*B 3"]) -> Float[Tensor, "*B 4"]:
    """wxyz quaternions of rotation vectors [..., 3] (angle = norm, torch tensors; stable at 0)."""
    ang = v.norm(dim=-1, keepdim=True)
    half = 0.5 * ang
    k = torch.where(ang > 1e-8, torch.sin(half) / ang.clamp_min(1e-30), 0.5 - ang * ang / 48)
    return torch.cat([torch.cos(half), v * k], -1)


def rotation_angle(Ra: Float[np.ndarray, "*B 3 3"], Rb: Float[np.ndarray, "*B 3 3"]) -> Float[np.ndarray, "*B"]:
    """Geodesic angle (rad) between rotations, computed stably near 0 and pi via atan2."""
    D = np.swapaxes(Ra, -1, -2) @ Rb
    cos = (np.trace(D, axis1=-2, axis2=-1) - 1.0) / 2.0
    skew = np.stack([D[..., 2, 1] - D[..., 1, 2], D[..., 0, 2] - D[..., 2, 0], D[..., 1, 0] - D[..., 0, 1]], -1)
    sin = 0.5 * np.linalg.norm(skew, axis=-1)
    return np.asarray(np.arctan2(sin, cos))


def axis_angle_to_matrix(axis: Float[np.ndarray, "3"], angle: float) -> Float[np.ndarray, "3 3"]:
    """Rodrigues' formula; ``axis`` is normalised (ValueError if it has zero length)."""
    a = np.asarray(axis, np.float64)
    n = np.linalg.norm(a)
    if n < 1e-12:
        raise ValueError("axis_angle_to_matrix: zero-length axis")
    a = a / n
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)
