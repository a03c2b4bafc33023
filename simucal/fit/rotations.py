"""Rotation utilities shared by the field method and the simulators (the hand-placed gyro
integration is derived: derive/moves.py, generated/moves.py)."""
from __future__ import annotations

import math

import numpy as np


def skew(v):
    v = np.asarray(v, float)
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def exp_so3(v):
    """Rotation matrix exp([v x]) for rotation vectors v (..., 3), safe at 0."""
    v = np.asarray(v, float)
    s: float | np.ndarray  # sin(a) / a and (1 - cos(a)) / a^2: floats for one vector, else arrays
    c: float | np.ndarray
    if v.ndim == 1:  # one vector: Rodrigues in plain floats (array set-up would cost more than the work)
        x, y, z = map(float, v)
        a = math.sqrt(x * x + y * y + z * z)
        s, c = (1 - a * a / 6, 0.5 - a * a / 24) if a < 1e-8 else (math.sin(a) / a, (1 - math.cos(a)) / (a * a))
        return np.array([[1 - c * (y * y + z * z), -s * z + c * x * y, s * y + c * x * z],
                         [s * z + c * x * y, 1 - c * (x * x + z * z), -s * x + c * y * z],
                         [-s * y + c * x * z, s * x + c * y * z, 1 - c * (x * x + y * y)]])
    a = np.linalg.norm(v, axis=-1)[..., None, None]
    K = skew(v)
    small = a < 1e-8
    s = np.where(small, 1.0 - a ** 2 / 6, np.sin(a) / np.where(small, 1.0, a))
    c = np.where(small, 0.5 - a ** 2 / 24, (1 - np.cos(a)) / np.where(small, 1.0, a) ** 2)
    return np.eye(3) + s * K + c * (K @ K)


def log_so3(R):
    """Rotation vector phi with R = exp([phi x]), for any rotation (also near 180 deg)."""
    c = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    a = np.arccos(c)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if a < 1e-8:
        return v / 2
    if np.pi - a < 1e-6:  # sin a ~ 0: the axis is the dominant column of R + I
        B = R + np.eye(3)
        axis = B[:, np.argmax(np.linalg.norm(B, axis=0))]
        return a * axis / np.linalg.norm(axis)
    return v * a / (2 * np.sin(a))


def wahba(u_b, u_d, w):
    """The rotation C (b -> d) minimising sum w_i |u_d,i - C u_b,i|^2 (Markley 1988: from the SVD
    of B = sum w_i u_d,i u_b,i^T), for pairs (n, 3) or batches of them (..., n, 3) with weights
    (..., n)."""
    return nearest_rotation(np.ascontiguousarray((w[..., None] * u_d).swapaxes(-1, -2)) @ u_b)  # matmul's fast path


def nearest_rotation(B, max_iter=30):
    """The proper rotation nearest B (..., 3, 3) in the Frobenius norm: U diag(1, 1, det(U V^T)) V^T
    from B's SVD. Where det(B) > 0 that is B's orthogonal polar factor, which the Newton-Schulz
    iteration X <- X (3I - X^T X) / 2 reaches in a few matrix products (B scaled by sqrt(3)/|B|_F:
    every singular value in (0, sqrt(3)], and all at 1 for well-spread directions); batched 3x3
    products cost a twentieth of a batched SVD. Matrices it does not settle (near-singular B, or
    det(B) <= 0) go to the SVD."""
    B = np.asarray(B, float)
    X = B * (np.sqrt(3.0) / np.linalg.norm(B, axis=(-2, -1), keepdims=True))
    eye = np.eye(3)
    for _ in range(max_iter):
        E = np.ascontiguousarray(X.swapaxes(-1, -2)) @ X - eye  # a contiguous X^T: matmul's fast path
        err = np.abs(E).reshape(E.shape[:-2] + (9,)).max(axis=-1)
        X = X @ (eye - 0.5 * E)
        if np.all(err < 1e-13):  # quadratic: the step just taken ends at round-off
            break
    bad = ~(err < 1e-13) | ~(det3(X) > 0)
    if np.any(bad):
        U, _, Vt = np.linalg.svd(B[bad])
        D = np.broadcast_to(eye, U.shape).copy()
        D[..., 2, 2] = np.linalg.det(U @ Vt)
        X[bad] = U @ D @ Vt
    return X


def adjugate3(A):
    """Adjugates of 3x3 matrices (..., 3, 3) by cofactors, elementwise over the batch: A adj(A) =
    det(A) I. Batched LAPACK calls (inv, det) cost more per 3x3 matrix than this arithmetic."""
    a = [[A[..., i, j] for j in range(3)] for i in range(3)]
    out = np.empty(np.shape(A))
    for i in range(3):
        for j in range(3):  # adj[i, j] = cofactor of a[j, i]
            r, c = [k for k in range(3) if k != j], [k for k in range(3) if k != i]
            out[..., i, j] = (-1) ** (i + j) * (a[r[0]][c[0]] * a[r[1]][c[1]] - a[r[0]][c[1]] * a[r[1]][c[0]])
    return out


def det3(A):
    """Determinants of 3x3 matrices (..., 3, 3), from the first row's cofactors."""
    adj = adjugate3(A)
    return A[..., 0, 0] * adj[..., 0, 0] + A[..., 0, 1] * adj[..., 1, 0] + A[..., 0, 2] * adj[..., 2, 0]
