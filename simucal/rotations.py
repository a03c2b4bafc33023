"""Rotation utilities shared by the field method and the simulators (the hand-placed gyro
integration is derived: derive/moves.py, generated/moves.py)."""
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
