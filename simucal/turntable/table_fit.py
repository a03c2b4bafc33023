"""Table errors from gravity directions: where the data can show them.

The norm method is blind to the table by design. But the accelerometer fit
recovers each static position's gravity direction in b, and the commanded
angles predict it through the exact table (generated/table.py, up_in_b): with
the mounting theta_4 always free, each table error (tilt, non-orthogonality,
zero positions) is a candidate, tested by an F test on the direction residuals,
whose noise, the random angular position errors, is estimated from the fit.
"""
from __future__ import annotations

import numpy as np

from simucal.fit.candidates import gate_candidates
from simucal.fit.distributions import f_sf
from simucal.generated import table

PARAMS = table.TABLE_FIT_PARAMS
MOUNT = [PARAMS.index(p) for p in ("theta_x4", "theta_y4", "theta_z4")]
CANDIDATES = {  # id: (parameter, meaning)
    "table.tilt.x": ("tilt_x", "outer axis tilted about x (dtheta_x0)"),
    "table.tilt.y": ("tilt_y", "outer axis tilted about y (dtheta_y0)"),
    "table.non_orthogonality.outer_middle": ("nonperp_om", "middle axis not perpendicular to the outer"),
    "table.non_orthogonality.middle_inner": ("nonperp_mi", "inner axis not perpendicular to the middle"),
    "table.zero.middle": ("d_alpha", "middle-axis zero-position error"),
    "table.zero.inner": ("d_beta", "inner-axis zero-position error"),
}


def fit_directions(u_meas, ang_rad, free, iters=20):
    """Gauss-Newton on the free table parameters; returns (x, cov, rss, dof, residuals)."""
    x = np.zeros(len(PARAMS))
    g, a, b = ang_rad.T
    for _ in range(iters):
        up, J = table.up_in_b(g, a, b, x)
        r = (u_meas - up).ravel()
        A = J[:, :, free].reshape(-1, len(free))
        dx = np.linalg.lstsq(A, r, rcond=None)[0]
        x[free] += dx
        if np.max(np.abs(dx)) < 1e-13:
            break
    up, J = table.up_in_b(g, a, b, x)
    res = u_meas - up
    rss = float(np.sum(res ** 2))
    dof = 2 * len(u_meas) - len(free)  # a unit vector has two degrees of freedom
    A = J[:, :, free].reshape(-1, len(free))
    cov = np.linalg.pinv(A.T @ A) * rss / max(dof, 1)
    return x, cov, rss, dof, res, A


def table_candidates(u_meas, ang_deg, alpha=0.01):
    """Candidate table errors ranked by an F test against the mounting-only fit."""
    ang = np.radians(np.asarray(ang_deg, float))
    x0, _, rss0, dof0, _, A0 = fit_directions(u_meas, ang, MOUNT)
    Q, _ = np.linalg.qr(A0)
    out = []
    for cid, (pname, meaning) in CANDIDATES.items():
        j = PARAMS.index(pname)
        entry = {"effect": ".".join(cid.split(".")[:2]), "axis": cid.split(".")[2], "id": cid, "parameter": pname,
                 "unit": "rad", "meaning": meaning, "test": "F on gravity directions (position errors as noise)"}
        _, J = table.up_in_b(*ang.T, x0)
        col = J[:, :, j].ravel()
        perp = col - Q @ (Q.T @ col)
        if np.linalg.norm(perp) < 1e-3 * np.linalg.norm(col):
            entry.update(separable=False, note="collinear with the mounting angles theta_4 on this plan; "
                         "to see it: positions at more outer-axis angles and both signs of the middle angle")
            out.append(entry)
            continue
        x1, cov1, rss1, dof1, res1, _ = fit_directions(u_meas, ang, MOUNT + [j])
        F = max((rss0 - rss1) / (rss1 / max(dof1, 1)), 0.0)
        p = float(f_sf(F, 1, dof1)) if dof1 > 0 else None
        entry.update(separable=True, estimate=float(x1[j]), std=float(np.sqrt(cov1[-1, -1])), statistic=float(F),
                     p_value=p, delta_aic=None, residual_rms_after=float(np.sqrt(np.mean(res1 ** 2))))
        out.append(entry)
    # an F test against the mounting-only fit: it needs no failing baseline to count
    return gate_candidates(out, True, alpha), {"mounting_rad": x0[MOUNT].tolist(), "direction_residual_rms": float(np.sqrt(rss0 / (3 * len(u_meas))))}
