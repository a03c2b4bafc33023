"""Every parameter of a sensor model as a polynomial in temperature (a thermal calibration).

One unit calibrated at K temperature plateaus gives, per parameter, K estimates p_k with
stds s_k at the plateaus' mean temperatures T_k. Each parameter is fitted as

    p(T) = c_0 + c_1 (T - T_ref) + ... + c_d (T - T_ref)^d

by weighted least squares (weights 1 / s_k^2), as PX4's and ArduPilot's thermal calibrations
fit their third-order polynomials per parameter (IEEE 1293 writes the same model). The degree
is chosen by the data: starting from a constant, a degree is added while it lowers chi^2
significantly (chi^2 drop above its 1 % tail of chi^2(1), the coefficient's t-test with known
stds), at most K - 1 and MAX_DEGREE; `degree` forces one. c_0 is the parameter at T_ref, so a
calibration file's params, M and bias are the unit's at T_ref, and apply evaluates p(T) at
each row's temp_c.
"""
from __future__ import annotations

import numpy as np

from simucal.fit.distributions import chi2_sf

MAX_DEGREE = 3
ALPHA = 0.01


def _wls(dT, y, s, d):
    """Coefficients c_0..c_d, their covariance and chi^2 of a weighted polynomial fit."""
    A = np.vander(dT, d + 1, increasing=True) / s[:, None]
    b = y / s
    cov = np.linalg.pinv(A.T @ A)
    c = cov @ A.T @ b
    return c, cov, float(np.sum((A @ c - b) ** 2))


def fit_polynomial(T_c, values, std, t_ref_c: float, degree: int | None = None) -> dict:
    """One parameter's polynomial in (T - t_ref_c): {degree, coefficients, std, chi2, dof, p_value}.
    degree None: chosen by the sequential chi^2 test (module doc)."""
    dT = np.asarray(T_c, float) - t_ref_c
    y, s = np.asarray(values, float), np.maximum(np.asarray(std, float), 1e-300)
    top = min(MAX_DEGREE, len(dT) - 1)
    if degree is None:
        d, (c, cov, chi2) = 0, _wls(dT, y, s, 0)
        while d < top:
            c1, cov1, chi2_1 = _wls(dT, y, s, d + 1)
            if chi2_sf(max(chi2 - chi2_1, 0.0), 1) >= ALPHA:
                break
            d, c, cov, chi2 = d + 1, c1, cov1, chi2_1
    else:
        d = degree
        c, cov, chi2 = _wls(dT, y, s, d)
    dof = len(dT) - d - 1
    return {"degree": d, "degree_from": "the data" if degree is None else "--thermal-degree",
            "coefficients": c.tolist(), "std": np.sqrt(np.diag(cov)).tolist(), "chi2": chi2,
            "dof": dof, "p_value": float(chi2_sf(chi2, dof)) if dof > 0 else None}


def evaluate(coefficients, dT) -> np.ndarray:
    """p(T) at dT = T - T_ref (any shape)."""
    return np.polynomial.polynomial.polyval(np.asarray(dT, float), np.asarray(coefficients, float))


def params_at(thermal: dict, names, temp_c) -> np.ndarray:
    """(n, m): the parameters `names` at each temperature temp_c (n,), from a block's `thermal`
    section (its t_ref_c and per-parameter coefficients)."""
    dT = np.asarray(temp_c, float) - thermal["t_ref_c"]
    return np.stack([evaluate(thermal["parameters"][k]["coefficients"], dT) for k in names], axis=-1)
