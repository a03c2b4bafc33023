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

from simucal.fit.distributions import f_sf
from simucal.fit.ranking import Trial, rank
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


class DirectionsProblem:
    """The static positions' gravity directions against the table with its mounting free, as a ranking
    Problem (fit/ranking.py): each table error's column is its Jacobian, its test an F test against the
    mounting-only fit (the position errors, unknown, as noise)."""
    span = "the mounting angles theta_4"

    def __init__(self, u_meas, ang_rad):
        self.u_meas, self.ang = u_meas, ang_rad
        self.x0, _, self.rss0, self.dof0, self.res0, A0 = fit_directions(u_meas, ang_rad, MOUNT)
        self.J = table.up_in_b(*ang_rad.T, self.x0)[1]
        self.Q = np.linalg.qr(A0)[0]

    def info(self, cid):
        return CANDIDATES[cid][0], "rad", CANDIDATES[cid][1]

    def basis(self):
        return self.Q

    def residual(self):
        return self.res0.ravel(), self.rss0 / max(self.dof0, 1)

    def column(self, cid):
        return self.J[:, :, PARAMS.index(CANDIDATES[cid][0])].ravel()

    def to_see(self, cid):
        return "positions at more outer-axis angles and both signs of the middle angle"

    def to_separate(self, cid, twin):
        return self.to_see(cid)

    def fit_with(self, cid):
        j = PARAMS.index(CANDIDATES[cid][0])
        x1, cov1, rss1, dof1, res1, _ = fit_directions(self.u_meas, self.ang, MOUNT + [j])
        F = max((self.rss0 - rss1) / (rss1 / max(dof1, 1)), 0.0)
        return Trial(float(x1[j]), float(np.sqrt(cov1[-1, -1])), float(F),
                     float(f_sf(F, 1, dof1)) if dof1 > 0 else None, None, float(np.sqrt(np.mean(res1 ** 2))))


def table_candidates(u_meas, ang_deg):
    """Candidate table errors ranked by an F test against the mounting-only fit (fit/ranking.rank)."""
    problem = DirectionsProblem(u_meas, np.radians(np.asarray(ang_deg, float)))
    # an F test against the mounting-only fit: it needs no failing baseline to count
    cands = rank(problem, CANDIDATES, True, "table candidates",
                 test="F on gravity directions (position errors as noise)")
    return [c.to_dict() for c in cands], {"mounting_rad": problem.x0[MOUNT].tolist(),
                                          "direction_residual_rms": float(np.sqrt(problem.rss0 / (3 * len(u_meas))))}
