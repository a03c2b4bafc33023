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
    """J_r(v) of SO(3): exp(v + dv) = exp(v) exp(J_r(v) dv) to first order."""
    v = np.asarray(v, float)
    a = np.linalg.norm(v, axis=-1)[..., None, None]
    K = skew(v)
    small = a < 1e-6
    safe = np.where(small, 1.0, a)
    c1 = np.where(small, 0.5 - a ** 2 / 24, (1 - np.cos(a)) / safe ** 2)
    c2 = np.where(small, 1 / 6 - a ** 2 / 120, (a - np.sin(a)) / safe ** 3)
    return np.eye(3) - c1 * K + c2 * (K @ K)


def prefix_products(R):
    """C[..., k, :, :] = R_0 R_1 ... R_k along axis -3, by a log-depth scan."""
    C = np.array(R, float, copy=True)
    d = 1
    while d < C.shape[-3]:
        C[..., d:, :, :] = C[..., :-d, :, :] @ C[..., d:, :, :]
        d *= 2
    return C
