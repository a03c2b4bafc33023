"""The pairs of directions the frames' tie is read from (turntable/unification.py): Wahba's solution's
sensitivity to the directions, each pair's misfit across the bisector, and the record of a solution.

Pairs (u_b, u_d): one physical direction seen in the accelerometer frame b and in the gyro frame d, with
du/dz (n, 3, nz), z the inputs of unification.py's module doc; C: C_b^d, u_d = C u_b when the pairs agree.
"""
from __future__ import annotations

from typing import TypedDict

import numpy as np

from simucal.fit.gauss_newton import tangent_basis
from simucal.generated import unify as eq


class PairSolution(TypedDict):
    """Wahba's solution over the pairs and its test (unification.Unifier.solve); angles in rad."""
    pairs: int                 # n
    C: np.ndarray              # C_b^d (3, 3)
    u_b: np.ndarray            # the pairs' directions (n, 3)
    u_d: np.ndarray
    J_phi: np.ndarray          # d phi / dz (3, nz)
    chi2: float                # of the misfits, on dof
    dof: int                   # 2 per pair, 3 for C
    misfit: np.ndarray         # each pair's misfit across the bisector (n, 2)
    S_inv: np.ndarray          # the inverse of each misfit's covariance (n, 2, 2)
    R_b: np.ndarray            # the misfit's derivative in u_b and phi (n, 2, 3)
    R_phi: np.ndarray
    noise_dof: float           # the misfits' noise's degrees of freedom
    residual_rms_rad: float
    rank: int                  # of u_b: 3 where the pairs span every direction


def wahba_sensitivity(u_b, D_b, u_d, D_d, w, C):
    """d phi / dz (3, nz) from du_b/dz (n, 3, nz) and du_d/dz (n, 3, nz): at Wahba's solution the weighted
    gradients in phi sum to zero, so dphi = -(sum w dg/dphi)^-1 sum w (dg/du_b du_b + dg/du_d du_d)
    (derived: generated/unify.wahba_terms)."""
    H, G_b, G_d = eq.wahba_terms(u_b, u_d, C.ravel())
    return -np.linalg.solve(np.tensordot(w, H, axes=1), np.tensordot(w, G_b @ D_b + G_d @ D_d, axes=1))


def pair_misfits(u_b, D_b, u_d, D_d, C, J_phi):
    """Each pair's misfit u_d - C u_b in the plane perpendicular to the bisector of u_d and C u_b (n, 2),
    where it lies whole, its derivative in z (n, 2, nz) and in u_b and phi (n, 2, 3) (derive/unify.py's
    pair_misfit_jacobians). In 3
    components its covariance has a third eigenvalue of the misfit's size squared times the noise's, which
    a pseudo-inverse counts as an almost noiseless direction: at MEMS noise that doubled the chi-square."""
    m = u_d + u_b @ C.T
    E = tangent_basis(m / np.linalg.norm(m, axis=1, keepdims=True))
    R_b, R_d, R_phi = eq.pair_misfit_jacobians(u_b, C.ravel(), E.reshape(len(E), 6))
    return np.einsum("nia,ni->na", E, u_d - u_b @ C.T), R_b @ D_b + R_d @ D_d + R_phi @ J_phi, R_b, R_phi
