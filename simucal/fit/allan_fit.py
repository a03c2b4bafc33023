"""The IEEE 952 terms fitted to an overlapping Allan variance curve by generalised least squares
with the estimates' covariance, and kept only where the data show them.

Why GLS and not GMWM: GMWM (Guerrier et al. 2013) fits the Haar wavelet variance, which is the
Allan variance over two (nu^2(tau) = sigma^2(tau) / 2), with a weight matrix estimated from the
data; for the IEEE 952 terms that are linear in the variance, GMWM with the model's own covariance
is the same estimator as GLS on the Allan variance. The covariance of the overlapping estimates
is known in closed form for white noise, random walk and quantisation (simucal.fit.allan_cov, exact
for a finite record, its stretches and sample rate), so it needs no bootstrap and no estimate of
a 50 x 50 matrix from one record; and the command stays fast (one covariance per sensor).

The fit: sigma^2(tau) = A x, x = (Q^2, N^2, B^2, K^2, R^2), A the IEEE 952 columns (Table C.1,
simucal.fit.noise.COLUMNS); x = (A' C^-1 A)^-1 A' C^-1 v with C the covariance at the model's
current x, iterated (the weights follow the model, not the noisy points, so the fit is unbiased).

Which terms: white noise N always; then, one at a time, the term whose estimate stands furthest
above zero in units of its GLS std (in the model with it added, the covariance that of the model
without it: the test under the hypothesis that it is absent) is kept while that is more than
SEEN (3) stds, i.e. a chi-square drop of 9 on 1 dof. A term not kept is "not seen" with the 95 %
upper bound the record allows on it: sqrt(max(x, 0) + 1.645 std(x)) in the model with it added.
A term needs MIN_TAUS taus more than the model has other terms (2 dof): a record too short for
that gets none. The std of a term from that of its square: std(x) / (2 sqrt(x)).
"""
from __future__ import annotations

from typing import TypedDict

import numpy as np
from numpy.typing import NDArray

from simucal.errors import CalibrationError
from simucal.fit import allan_cov
from simucal.fit.noise import COLUMNS, TERMS

SEEN = 3.0        # a term is reported beyond this many stds of its square from zero
UPPER_95 = 1.645  # one-sided 95 % quantile of the normal: the bound of a term not seen
MIN_TAUS = 2      # the dof a model needs beyond its terms
BASE = ("N", "K")  # always in the model: every sensor has white noise and a random walk (Kalibr's pair)
TERMS_NEEDING = {"N": 1 + MIN_TAUS, "K": 2 + MIN_TAUS}
ITERATIONS = 4    # covariance from the model, refit (converged to < 1e-3 of a std in tests)


class TermSelection(TypedDict):
    """The terms one axis's Allan variance shows (select): values in the sensor's unit times s^a."""
    terms: dict[str, tuple[float, float] | None]  # each term's (value, std), None where not seen
    bounds: dict[str, float]                      # 95 % upper bound of each term tested and not seen
    needs_taus: int                               # the taus a term untested needs
    squares: dict[str, tuple[float, float]]       # the final model's squares (x, std of x), below 0 by noise
    chi2: float                                   # the GLS fit's, on dof
    dof: int                          # the taus less the terms fitted
    cov: NDArray[np.float64]                      # the Allan variance's covariance under the model (the unit^4)


def gls(v, A, cov):
    """(x, cov_x, chi2) of v = A x with cov(v) = cov, whitened by the Cholesky factor of the
    correlation (the variances span decades); refused in one line where rounding leaves that
    correlation not positive definite (allan_cov is exact, so only at extreme grids)."""
    d = np.sqrt(np.diag(cov))
    corr = cov / np.outer(d, d) + 1e-12 * np.eye(len(d))
    try:
        L = np.linalg.cholesky(corr)
    except np.linalg.LinAlgError:
        raise CalibrationError(
            f"the covariance of the Allan variance at these {len(d)} taus is not positive definite in floating "
            f"point (smallest eigenvalue of its correlation {np.linalg.eigvalsh(corr)[0]:.3g}): the taus are "
            "too strongly correlated to weight; ask for a smaller --tau-max-s") from None
    Aw = np.linalg.solve(L, A / d[:, None])
    vw = np.linalg.solve(L, v / d)
    scale = np.linalg.norm(Aw, axis=0)
    q, r = np.linalg.qr(Aw / scale)
    x = np.linalg.solve(r, q.T @ vw) / scale
    rinv = np.linalg.inv(r) / scale[:, None]
    resid = vw - Aw @ x
    return x, rinv @ rinv.T, float(resid @ resid)


class AllanFit:
    """One axis: the Allan variance v at tau (s), the covariance basis of its grid (allan_cov.basis)."""

    def __init__(self, tau, v, mats):
        self.tau, self.v, self.mats = np.asarray(tau, float), np.asarray(v, float), mats
        self.A = np.column_stack([COLUMNS[k](self.tau) for k in TERMS])

    def cov(self, x: dict) -> np.ndarray:
        """The covariance of v under the model x (its Q, N and K; allan_cov's module doc)."""
        return allan_cov.covariance(self.mats, x)

    def solve(self, terms, cov):
        """{term: (x, std of x)}, chi2 of the model with `terms` under the covariance cov."""
        idx = [TERMS.index(t) for t in terms]
        x, cx, chi2 = gls(self.v, self.A[:, idx], cov)
        return {t: (float(x[i]), float(np.sqrt(cx[i, i]))) for i, t in enumerate(terms)}, chi2

    def iterate(self, terms, x0: dict):
        """GLS with the covariance of the model it fits, refitted ITERATIONS times."""
        x = dict(x0)
        for _ in range(ITERATIONS):
            cov = self.cov(x)
            sol, chi2 = self.solve(terms, cov)
            x = {t: v for t, (v, _) in sol.items()}
        return sol, chi2, cov


def start(tau, v) -> dict[str, float]:
    """A white-noise level to start from: N^2 = v tau at the shortest tau (it dominates there)."""
    return {"N": float(v[0] * tau[0])}


def select(tau, v, mats) -> TermSelection:
    """The terms the curve shows (module doc): {"terms": {t: (value, std) or None},
    "bounds": {t: 95 % bound} (a term in neither is one the grid is too short to test: it needs
    "needs_taus"), "squares": {t: (x, std)} of the final model's terms, seen or not, "chi2", "dof",
    "cov" (of the Allan variance under the model)}."""
    fit = AllanFit(tau, v, mats)
    terms = [t for t in BASE if len(tau) >= TERMS_NEEDING[t]]
    sol, chi2, cov = fit.iterate(terms, start(tau, v))
    while True:
        room = [t for t in TERMS if t not in terms and len(tau) >= len(terms) + 1 + MIN_TAUS]
        trials = {t: fit.solve(terms + [t], cov)[0][t] for t in room}
        z = {t: x / s for t, (x, s) in trials.items() if s > 0}
        best = max(z, key=z.__getitem__, default=None)
        if best is None or z[best] <= SEEN:
            break
        sol, chi2, cov = fit.iterate(terms + [best], {t: x for t, (x, _) in sol.items()} | {best: trials[best][0]})
        if sol[best][0] <= SEEN * sol[best][1]:  # gone once the covariance follows the model with it
            sol, chi2, cov = fit.iterate(terms, {t: x for t, (x, _) in sol.items() if t != best})
            break
        terms.append(best)
    bounds = {t: float(np.sqrt(max(x, 0.0) + UPPER_95 * s)) for t, (x, s) in trials.items() if t not in terms}
    out: dict[str, tuple[float, float] | None] = {}
    for t in TERMS:
        x, s = sol.get(t, (0.0, 0.0))
        if t in terms and (t == "N" or x > SEEN * s) and x > 0:
            out[t] = (float(np.sqrt(x)), s / (2 * float(np.sqrt(x))))
        else:
            out[t] = None
            if t in terms:
                bounds[t] = float(np.sqrt(max(x, 0.0) + UPPER_95 * s))
    return {"terms": out, "bounds": bounds, "needs_taus": len(terms) + 1 + MIN_TAUS, "squares": sol,
            "chi2": chi2, "dof": len(tau) - len(terms), "cov": cov}
