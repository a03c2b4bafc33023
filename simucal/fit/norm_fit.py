"""Norm-observation fits of one sensor triad (dong2018 section 1).

Observations are per-position mean outputs N_i (physical units), the known
input norm rho_i (1 g at rest; |w_T + w_e sin L| under outer-axis rate), and
optionally the standard deviation of each mean.

- fit_linear: the paper's method, eq. 7/8 and 11/12: regress rho^2 on the
  derived columns psi(N), then back-substitute K -> p (exact inverse).
- fit_exact: maximum likelihood with no term neglected. The unknowns are the
  parameters p and each position's input direction on the sphere of radius
  rho_i (the norm principle: the direction is not known, the norm is):
      minimise sum_i |(N_i - h(rho_i u_i, p)) / sigma_i|^2,  |u_i| = 1.
  Gauss-Newton (Levenberg-Marquardt damped) on p and a 2-D tangent step per
  direction; the directions are eliminated by a Schur complement, so each
  step solves an m x m system.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from simucal.errors import CalibrationError, NotConverged
from simucal.fit.aux_inputs import AuxInputs
from simucal.fit.distributions import chi2_sf
from simucal.fit.gauss_newton import directions, fit_batch, row_blocks, schur
from simucal.fit.results import ModelTest


@dataclass
class Observations:
    N: np.ndarray                  # (n, 3) mean outputs
    rho: np.ndarray                # (n,) known input norm
    sigma: np.ndarray | None = None  # (n, 3) std of each mean, or None (unknown)
    aux: AuxInputs = field(default_factory=AuxInputs)  # temp_c, t_s, f_x.. or w2, a user's columns: per row
    labels: list = field(default_factory=list)  # segment ids, for messages
    sigma_source: str = "each segment's scatter or the stated noise"  # where sigma came from, in words
    sigma_stated: bool = True      # whether a stated noise (meta, an option, an Allan curve) gave any sigma
    # the --noise file that gave sigma, set by turntable/observations.py; init=False: replace() and take()
    # do not carry it over
    noise_file: str | None = field(default=None, init=False, repr=False, compare=False)

    def take(self, rows) -> "Observations":
        """The observations of the given rows (indices)."""
        rows = np.asarray(rows)
        return replace(self, N=self.N[rows], rho=self.rho[rows], sigma=None if self.sigma is None else self.sigma[rows],
                       aux=self.aux.take(rows), labels=[self.labels[i] for i in rows] if self.labels else [])


@dataclass
class Fit:
    model: str
    method: str
    params: dict            # name -> value
    std: dict               # name -> standard uncertainty
    cov: np.ndarray
    residuals: np.ndarray   # (n, 3) N - model, physical units
    residual_rms: float
    chi2: float | None
    dof: int
    p_value: float | None
    iterations: int = 0
    directions: np.ndarray | None = None  # (n, 3) unit input directions (exact fit)
    undetermined: dict = field(default_factory=dict)  # parameters held by a prior: {name: how and why}

    def vector(self, names):
        return np.array([self.params[k] for k in names])

    @property
    def test(self) -> ModelTest:
        """The fit's chi-square test (p None where the noise is unknown: test_model's F decides there)."""
        return ModelTest(self.chi2, self.dof, self.p_value, "chi-square")


def _check_inputs(model, obs: Observations):
    n, m = len(obs.N), len(model.params)
    if n == 0:
        raise CalibrationError(f"no {model.sensor} positions to calibrate from")
    if not np.all(np.isfinite(obs.N)):
        raise CalibrationError(f"{model.sensor} outputs contain NaN or infinite values")
    if n < m:
        raise CalibrationError(
            f"{n} {model.sensor} positions for {m} parameters of {model.name}: the norm gives one "
            f"equation per position, so at least {m} positions are needed (where the inputs are known, as a "
            "table's commanded angles or the Ferraris poses give them, --method multiposition needs only 4)")
    check_not_coplanar(obs.N, model.sensor)


def check_not_coplanar(N, sensor, where="", axes="the output axes"):
    """Refuse outputs whose input directions all lie in one plane (a great or a small circle):
    the scale, misalignment and bias along its normal cannot be told apart by the norm. Outputs
    are an affine image of the inputs, so the plane shows in their own covariance; the fit's
    linearised stds would not show it (the solver wanders along the unseen direction)."""
    if len(N) < 4:
        return
    d = np.asarray(N, float) - np.mean(N, axis=0)
    spread, normal = np.linalg.eigh(d.T @ d / (len(d) - 1))  # the outputs' covariance (np.cov costs 20 us more)
    if spread[0] < 1e-3 * spread[-1]:
        raise CalibrationError(
            f"{where}the {len(N)} {sensor} input directions lie in one plane (coplanar: spread across it "
            f"{np.sqrt(max(spread[0], 0)):.2g} against {np.sqrt(spread[-1]):.2g} along it; normal "
            f"{np.round(normal[:, 0], 2).tolist()} in {axes}): the scale, misalignment and bias along that "
            "normal are unobservable; add positions tilted out of that plane")


def unobservable(H, names, tol=1e-10):
    """Parameter combinations H cannot see (an eigenvalue of the Jacobi-scaled
    information below tol; healthy plans give 0.05 to 0.7), as readable strings."""
    d = np.sqrt(np.clip(np.diag(H), 1e-300, None))
    Hn = H / np.outer(d, d)
    w, V = np.linalg.eigh(Hn)
    out = []
    for k in np.nonzero(w < tol * max(w.max(), 1e-300))[0]:
        v = V[:, k]
        big = np.argsort(-np.abs(v))[:3]
        out.append(" + ".join(f"{v[j]:+.2f}*{names[j]}" for j in big if abs(v[j]) > 0.1))
    return out


def _linear_K(model, obs: Observations):
    """eq. 8 / 12: least squares of rho^2 on the derived columns psi(N): (K, Psi, rho^2)."""
    Psi = model.norm_regressors(obs.N, obs.aux)
    y = obs.rho ** 2
    return np.linalg.lstsq(Psi, y, rcond=None)[0], Psi, y


def fit_linear(model, obs: Observations) -> Fit:
    """dong2018 eq. 8 / 12 and the back-substitution, for any derived model."""
    _check_inputs(model, obs)
    n, m = len(obs.N), len(model.params)
    K, Psi, y = _linear_K(model, obs)
    scale = np.linalg.norm(Psi, axis=0)
    H = (Psi / scale).T @ (Psi / scale)
    bad = unobservable(H, model.params)
    if bad:
        raise CalibrationError(f"the {model.sensor} plan leaves these parameter combinations unobservable "
                               f"by the norm (or nearly): {bad}; add positions that change them")
    r = y - Psi @ K
    dof = n - m
    s2 = float(r @ r / dof) if dof > 0 else np.nan
    cov_K = s2 * np.linalg.inv(Psi.T @ Psi)
    p = model.params_of_K(K)
    J = np.empty((m, m))
    for j in range(m):  # numerical Jacobian of the generated back-substitution
        h = 1e-7 * max(abs(K[j]), 1e-3)
        dK = np.zeros(m)
        dK[j] = h
        J[:, j] = (model.params_of_K(K + dK) - model.params_of_K(K - dK)) / (2 * h)
    cov = J @ cov_K @ J.T
    norm_err = (Psi @ K - y) / (2 * obs.rho)  # first-order norm residual, output units
    return Fit(model.name, "linear", dict(zip(model.params, p)),
               dict(zip(model.params, np.sqrt(np.abs(np.diag(cov))))), cov,
               residuals=norm_err[:, None] * np.ones((1, 3)) / np.sqrt(3),
               residual_rms=float(np.sqrt(np.mean(norm_err ** 2))), chi2=None, dof=dof, p_value=None)


def _start_cost(model, obs, p):
    try:
        u = initial_directions(model, obs, p)
    except np.linalg.LinAlgError:
        return np.inf
    r = obs.N - model.output(obs.rho[:, None] * u, p, obs.aux)
    c = float(np.sum((r / (obs.sigma if obs.sigma is not None else 1.0)) ** 2))
    return c if np.isfinite(c) else np.inf


def jacobian_blocks(model, obs, p, u, sig):
    """The exact problem's weighted residual and Jacobian at (p, directions u):
    r (n,3), dr/dp (n,3,m), dr/d(tangent step) (n,3,2), and the tangent bases E (n,3,2)."""
    return row_blocks(model, obs.N, obs.rho, sig, p, u, obs.aux)


def normal_equations(model, obs, p, u, sig):
    """The Gauss-Newton system with every direction's 2-D tangent step eliminated (Schur
    complement of its 2x2 block): H (m, m), the information of p with the directions profiled
    out (the inverse of the CRLB where sig is the true noise), and g; with the blocks the
    direction steps need: r, H, g, A^-1 (n, 2, 2), B (n, 2, m), gd (n, 2), E (n, 3, 2)."""
    return schur(*jacobian_blocks(model, obs, p, u, sig))


def dense_jacobian(model, obs, fit):
    """Dense weighted Jacobian of the exact problem at the solution, [dr/dp | dr/d(directions)]
    (3n, m + 2n), and the sigma used (n, 3; ones where the noise is unknown)."""
    n, m = len(obs.N), len(model.params)
    sig = np.broadcast_to(obs.sigma if obs.sigma is not None else 1.0, (n, 3))
    _, Jq, Jd, _ = jacobian_blocks(model, obs, fit.vector(model.params), fit.directions, sig)
    J = np.zeros((3 * n, m + 2 * n))
    J[:, :m] = Jq.reshape(3 * n, m)
    for i in range(n):
        J[3 * i:3 * i + 3, m + 2 * i:m + 2 * i + 2] = Jd[i]
    return J, sig


def full_covariance(model, obs, fit):
    """Covariance of [p, tangent steps of every direction] (m + 2n), scaled as fit.cov (so
    with the estimated noise where the data gave none). A direction's error is E_i dt_i,
    E_i = tangent_basis(fit.directions)[i]."""
    J, _ = dense_jacobian(model, obs, fit)
    cov = np.linalg.pinv(J.T @ J, hermitian=True)  # symmetric: by eigh, 4x faster than the SVD at 357 x 357
    m = len(model.params)
    scale = np.median(np.diag(fit.cov) / np.maximum(np.diag(cov)[:m], 1e-300))
    return cov * scale


def initial_directions(model, obs, p):
    return directions(model, obs.N, p, obs.aux)


_AFFINE: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # model name -> _affine_columns


def _affine_columns(model):
    """M(0), bias(0) and the columns d[vec M, bias]/dp of a model (linear in p): computed once."""
    if model.name not in _AFFINE:
        m = len(model.params)
        M0, b0 = model.matrix_and_bias(np.zeros(m))
        cols = [np.r_[(Mj - M0).ravel(), bj - b0] for Mj, bj in (model.matrix_and_bias(e) for e in np.eye(m))]
        _AFFINE[model.name] = (M0, b0, np.array(cols).T)
    return _AFFINE[model.name]


def ellipsoid_start(model, obs: Observations):
    """Closed-form start for large offsets (raw counts): the general quadric
    through the outputs, N'QN + q'N + c = 0, is the ellipsoid |M^-1 (N - b)| = rho
    of any affine model; its centre is b and M M' = k Q^-1 with M lower triangular
    is a Cholesky factor. p then follows from M(p), b(p), which are linear in p.
    Exact where the paper's regression (first order in b) is not. None if the
    quadric is not an ellipsoid."""
    N = obs.N / obs.rho[:, None]  # unit norm for every row
    x, y, z = N.T
    D = np.column_stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z, np.ones(len(N))])
    if len(N) < 9:  # nine rows fix the quadric (ten coefficients up to scale): as many as the parameters
        return None
    D = np.vstack([D, np.zeros((max(10 - len(N), 0), 10))])  # nine rows: the SVD's tenth vector is the null one
    v = np.linalg.svd(D, full_matrices=False)[2][-1]  # (N x 10): linear in N
    Q = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
    try:
        b = -np.linalg.solve(Q, v[6:9])
        k = b @ Q @ b - v[9]
        M = np.linalg.cholesky(k * np.linalg.inv(Q))
    except np.linalg.LinAlgError:
        return None
    M0, b0, A = _affine_columns(model)
    target = np.r_[(M - M0).ravel(), b - b0]
    return np.linalg.lstsq(A, target, rcond=None)[0] if np.linalg.matrix_rank(A) > 0 else None


def fit_exact(model, obs: Observations, p0=None, max_iter=200, tol=1e-12, prior=None) -> Fit:
    """Maximum-likelihood norm-observation fit, exact model (see module doc). prior: {parameter:
    (value, std)} for parameters the data do not determine, held at value by a pseudo-observation
    (the stds then say how well they are held; the chi2 excludes the prior). A fit that converged to
    a reversed column of M is turned upright (_upright)."""
    fit = _fit_exact(model, obs, p0, max_iter, tol, prior)
    p0_upright = _upright(model, fit)
    return fit if p0_upright is None else _fit_exact(model, obs, p0_upright, max_iter, tol, prior)


def _upright(model, fit: Fit):
    """The norm |M^-1 (N - b)| cannot tell M from M S, S a diagonal of signs: a column reversed (a
    reflection, which no row's norm sees). Where the fit's M has a diagonal entry of the sign opposite
    the nominal's, the start that turns those columns back (M S, the same bias; M and b are linear in
    p), else None. The same norms then come with the nominal handedness, so that a sensor wired
    reversed shows where the data say so (the gyro's moves, the triads' handedness), not in the fit's
    choice of twin: a clean hand-placed session (seed 29) converged to ay reversed and was refused as
    a wiring fault."""
    p = fit.vector(model.params)
    M, _ = model.matrix_and_bias(p)
    M0, _, A = _affine_columns(model)
    S = np.where(np.sign(np.diag(M)) == np.sign(np.diag(M0)), 1.0, -1.0)
    if np.all(S > 0) or np.asarray(M).ndim != 2:
        return None
    delta = np.linalg.lstsq(A, np.r_[(M * S - M).ravel(), np.zeros(3)], rcond=None)[0]
    return p + delta


def _fit_exact(model, obs: Observations, p0, max_iter, tol, prior) -> Fit:
    _check_inputs(model, obs)
    n, m = len(obs.N), len(model.params)
    if p0 is None and getattr(model, "effects", None):  # baseline + effects: start from the baseline's fit
        base = fit_exact(model.base, obs, max_iter=max_iter)
        p0 = np.r_[base.vector(model.base.params), np.zeros(m - len(model.base.params))]
    if p0 is None and not prior:
        fast = _fit_from_linear_start(model, obs, max_iter, tol)
        if fast is not None:
            return fast
    if p0 is None:  # the better of the paper's linear fit and the exact ellipsoid
        starts = []
        try:
            with np.errstate(invalid="ignore", divide="ignore"):  # a failed start is simply not used
                starts.append(model.params_of_K(_linear_K(model, obs)[0]))
        except (np.linalg.LinAlgError, NotImplementedError):
            pass
        ell = ellipsoid_start(model, obs)
        if ell is not None and np.all(np.isfinite(ell)):
            starts.append(ell)
        starts.append(np.zeros(m))
        p0 = min(starts, key=lambda s: _start_cost(model, obs, s))
    compiled = None if prior else _fit_compiled(model, obs, p0, max_iter, tol)
    if compiled is not None:
        return compiled
    sig = np.broadcast_to(obs.sigma if obs.sigma is not None else 1.0, (n, 3))
    p, u, cost, H, it, status = fit_batch(model, obs.N[None], obs.rho[None], sig[None], np.asarray(p0, float)[None],
                                          obs.aux, max_iter, tol, prior)
    p, u, cost, H, it, status = p[0], u[0], float(cost[0]), H[0], int(it[0]), int(status[0])
    if status == 3:
        dead = [model.params[j] for j in np.nonzero(np.diag(H) <= 1e-300)[0]]
        raise CalibrationError(f"the {model.sensor} data give no input for {dead}: these parameters are not "
                               "seen at all by these positions (leave them out, or add positions that excite them)")
    if status == 2 and not np.all(np.isfinite(H)):
        raise CalibrationError(f"the exact {model.sensor} fit diverged (its information matrix is not finite): check "
                               "the data for clipped samples, outliers, a stuck channel or a wrong unit")
    if status == 2:
        raise CalibrationError(f"the {model.sensor} plan leaves these parameter combinations unobservable: "
                               f"{unobservable(H, model.params)}; add positions that change them")
    if status == 1:
        weak = unobservable(H, model.params, tol=1e-3)
        axis_only = np.all(np.max(np.abs(u), axis=1) > np.cos(np.radians(10)))
        raise NotConverged(
            f"the exact {model.sensor} fit did not converge in {max_iter} iterations (cost {cost:.6g})"
            + (f"; the plan barely sees {weak}: add positions that change them" if weak else
               "; check the data for outliers or a wrong unit")
            + ("; all the poses point along the sensor axes (the Ferraris six-position design), from which the "
               "norm cannot see misalignments: add tilted poses" if axis_only else ""))
    dH = np.sqrt(np.diag(H))
    return _finish(model, obs, p, u, np.linalg.inv(H / np.outer(dH, dH)) / np.outer(dH, dH), H, cost, it)


def _finish(model, obs, p, u, cov, H, cost, it) -> Fit:
    """The Fit at the solution: the unobservability check, residuals, chi-square, covariance
    (scaled by cost/dof where the noise is unknown)."""
    bad = unobservable(H, model.params)
    if bad:
        raise CalibrationError(f"the {model.sensor} plan leaves these parameter combinations unobservable: {bad}; "
                               "add positions (other input directions, temperatures or times) that change them")
    n, m = len(obs.N), len(model.params)
    res_phys = (obs.N - model.output(obs.rho[:, None] * u, p, obs.aux))
    dof = n - m
    chi2 = p_value = None
    if obs.sigma is not None:
        chi2 = cost
        p_value = float(chi2_sf(chi2, dof)) if dof > 0 else None
    elif dof > 0:
        cov = cov * cost / dof
    else:
        cov = cov * np.nan
    return Fit(model.name, "exact", dict(zip(model.params, p)),
               dict(zip(model.params, np.sqrt(np.diag(cov)))), cov, res_phys,
               float(np.sqrt(np.mean(res_phys ** 2))), chi2, dof, p_value, it, u)


FAST_CHI2 = 100.0  # a fit from the linear start alone is kept where chi2 <= this times its dof


def _fit_from_linear_start(model, obs, max_iter, tol) -> Fit | None:
    """The compiled fit from the paper's linear start (computed in the same call), kept where it
    converges to a fit the noise roughly explains (chi2 <= FAST_CHI2 dof; a failing model's misfit
    gives tens). Raw outputs with a large offset can leave that start far off (or not finite, then
    the call starts from 0) and the fit at a spurious point (chi2 1e6 dof): then None, and fit_exact
    tries its other starts."""
    if obs.sigma is None:
        return None
    try:
        fit = _fit_compiled(model, obs, None, max_iter, tol)
    except CalibrationError:  # _finish found the spurious point unobservable: the other starts may not
        return None
    if fit is None or fit.chi2 is None or fit.dof <= 0 or not fit.chi2 <= FAST_CHI2 * fit.dof:
        return None
    return fit


def _fit_compiled(model, obs, p0, max_iter, tol) -> Fit | None:
    """fit_exact through the model's compiled whole fit (one call; p0 None: from the paper's linear
    start, computed in the call), or None where there is none (no compiler, or candidate effects
    added) or where it did not converge cleanly (the Python starts, or the Python loop, then go on)."""
    base = model.base if getattr(model, "effects", None) == () else model
    if getattr(base, "fit_compiled", None) is None:
        return None
    n = len(obs.N)
    sig = np.broadcast_to(obs.sigma if obs.sigma is not None else 1.0, (n, 3))
    out = base.fit_compiled(obs.N[None], obs.rho[None], sig[None], base.aux_array(obs.aux, (n,))[None],
                            None if p0 is None else np.asarray(p0, float)[None], max_iter, tol)
    if out is None or out[5][0] != 0:
        return None
    p, cov, u, cost, it, _ = (a[0] for a in out)
    return _finish(model, obs, p, u, cov, np.linalg.inv(cov), float(cost), int(it))
