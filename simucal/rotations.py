"""Rotation utilities shared by the field and hand-placed gyro methods."""
from __future__ import annotations

import numpy as np


def skew(v):
    v = np.asarray(v, float)
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def exp_so3(v):
    """Rotation matrix exp([v x]) for rotation vectors v (..., 3), safe at 0."""
    v = np.asarray(v, float)
    a = np.linalg.norm(v, axis=-1)[..., None, None]
    K = skew(v)
    small = a < 1e-8
    s = np.where(small, 1.0 - a ** 2 / 6, np.sin(a) / np.where(small, 1.0, a))
    c = np.where(small, 0.5 - a ** 2 / 24, (1 - np.cos(a)) / np.where(small, 1.0, a) ** 2)
    return np.eye(3) + s * K + c * (K @ K)


def right_jacobian(v):
    """J_r(v) of SO(3): exp(v + dv) = exp(v) exp(J_r(v) dv) to first order.

    J_r = I - c1 [v x] + c2 [v x]^2 with [v x]^2 = v v' - |v|^2 I (no matrix product)."""
    v = np.asarray(v, float)
    a2 = np.sum(v * v, axis=-1)[..., None, None]
    a = np.sqrt(a2)
    small = a < 1e-3
    safe = np.where(small, 1.0, a)
    c1 = np.where(small, 0.5 - a2 / 24, (1 - np.cos(a)) / safe ** 2)
    c2 = np.where(small, 1 / 6 - a2 / 120, (a - np.sin(a)) / safe ** 3)
    K2 = v[..., :, None] * v[..., None, :] - a2 * np.eye(3)
    return np.eye(3) - c1 * skew(v) + c2 * K2


def _qmul(p, q):
    """Hamilton product of quaternions (w, x, y, z) along the last axis."""
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out[..., 0] = pw * qw - px * qx - py * qy - pz * qz
    out[..., 1] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 2] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 3] = pw * qz + px * qy - py * qx + pz * qw
    return out


def prefix_rotations(v):
    """C[..., k, :, :] = exp(v_0) exp(v_1) ... exp(v_k) for rotation vectors v (..., L, 3),
    composed as unit quaternions by a log-depth scan (cheaper than 3x3 products)."""
    a = np.linalg.norm(v, axis=-1, keepdims=True)
    half = np.where(a < 1e-8, 0.5 - a ** 2 / 48, np.sin(a / 2) / np.where(a < 1e-8, 1.0, a))
    Q = np.concatenate([np.cos(a / 2), half * v], -1)
    d = 1
    while d < Q.shape[-2]:
        Q[..., d:, :] = _qmul(Q[..., :-d, :], Q[..., d:, :])
        d *= 2
    w, x, y, z = Q[..., 0], Q[..., 1], Q[..., 2], Q[..., 3]
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)
