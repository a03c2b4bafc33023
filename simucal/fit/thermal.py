"""Every parameter of a sensor model as a polynomial in temperature (a thermal calibration):

    p(T) = c_0 + c_1 (T - T_ref) + ... + c_d (T - T_ref)^d

(IEEE 1293's thermal model; PX4 and ArduPilot fit third-order polynomials per parameter the same
way). c_0 is the parameter at T_ref, so a calibration file's params, M and bias are the unit's at
T_ref, and apply evaluates p(T) at each row's temp_c (params_at).

- ThermalModel: the polynomials inside the model, every row at its own temperature: a turntable
  unit's rows over plateaus or a ramp fitted at once (thermal_select.py chooses the degrees).
- fit_polynomial: one parameter's polynomial through per-plateau estimates p_k +- s_k at their
  temperatures by weighted least squares, its degree added while the chi^2 drop is beyond its 1 %
  tail of chi^2(1) (for methods without a row-level fit: a stream's plateaus).
Degrees never exceed MAX_DEGREE nor the distinct temperatures (clusters within SPREAD_C) less one.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from simucal.errors import CalibrationError
from simucal.fit.distributions import chi2_sf
from simucal.io import records

MAX_DEGREE = 3
SPREAD_C = 2.0  # temperatures within this of each other are one temperature (a plateau's wander)
# an IMU's widest rated range (military grade), degC: beyond it a temp_c column is in another unit (kelvin
# always; degF where a plateau is above 51.7 degC, 125 degF, as a hot plateau is) or broken
PLAUSIBLE_C = (-55.0, 125.0)
# each parameter's degree (one plateau fit per temperature) by up to MAX_DEGREE sequential chi-square drops: a
# model choice, not the model test (results.ALPHA), where a real term left out biases every temperature's value
DEGREE_ALPHA = 0.01


def check_temp_c(ms) -> np.ndarray:
    """A set's temp_c (degC), refused where the recording says it is in degF or kelvin, or where it runs outside
    PLAUSIBLE_C; every thermal path (plateaus, a ramp, a warm-up) reads it through here."""
    from simucal.io import units
    units.refuse_temperature_unit(ms.meta, ms.samples, ms.path, CalibrationError)
    T = np.asarray(ms.samples["temp_c"], float)
    if T.min() < PLAUSIBLE_C[0] or T.max() > PLAUSIBLE_C[1]:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: temp_c runs {T.min():.4g} to {T.max():.4g}, outside an "
                               f"IMU's rated {PLAUSIBLE_C[0]:g}..{PLAUSIBLE_C[1]:g} degC: is the column in kelvin "
                               "(subtract 273.15) or degF (C = (F - 32) / 1.8)? temp_c is degC")
    return T


RATE_WINDOW_S = 10.0  # dT/dt's smoothing: a thermistor's noise and 0.01 degC steps average out, a die's lag does not


def temperature_rate(t_s, temp_c, at_s=None, window_s=RATE_WINDOW_S) -> np.ndarray:
    """dT/dt (degC/s) of a logged temperature at the times at_s (default t_s): at each, the slope of the
    least-squares line through the rows within window_s / 2 of it (window_s a number, or one per time: a
    block's or a segment's span), and never fewer than the nearest row on each side, so that rows sparser
    than the window (a turntable's one row per position) give the central difference of their
    neighbours. A smoothed derivative: the 0.01 degC steps and noise of a thermistor differenced sample to
    sample are far larger than its rate, and over RATE_WINDOW_S the slope's error is sigma_T sqrt(12 /
    (n window_s^2)) for n rows. Any spacing, gaps; the rows' sums window by window where the times are few
    (blocks, segments: no pass over the whole log), by cumulative sums where they are many (every row)."""
    t, T = np.asarray(t_s, float), np.asarray(temp_c, float)
    if np.any(t[1:] < t[:-1]):
        order = np.argsort(t, kind="stable")
        t, T = t[order], T[order]
    at = t if at_s is None else np.asarray(at_s, float)
    n = len(t)
    if n < 2:
        return np.zeros(len(at))
    half = np.broadcast_to(np.asarray(window_s, float) / 2, at.shape)
    # the neighbours: last before, first after
    before, after = np.searchsorted(t, at) - 1, np.searchsorted(t, at, "right")
    lo = np.maximum(np.minimum(np.searchsorted(t, at - half), before), 0)
    hi = np.minimum(np.maximum(np.searchsorted(t, at + half, "right"), after + 1), n)
    if 64 * len(at) < n:
        return np.array([_slope(t[a:b], T[a:b]) for a, b in zip(lo, hi)])
    t0, T0 = t[n // 2], T[n // 2]  # centred: the sums of squares keep their digits over a long log
    tc, Tc = t - t0, T - T0
    sums = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones(n), tc, Tc, tc * tc, tc * Tc)]
    m, a, b, aa, ab = (s[hi] - s[lo] for s in sums)
    den = m * aa - a * a
    return np.where(den > 0, (m * ab - a * b) / np.where(den > 0, den, 1.0), 0.0)


def _slope(t, T) -> float:
    """The least-squares slope of T over t (0 where t does not vary)."""
    d = t - t.mean()
    dd = float(d @ d)
    return float(d @ (T - T.mean())) / dd if dd > 0 else 0.0


def group_rates(samples, groups) -> dict[str, NDArray[np.float64]]:
    """{temp_rate_c_s: each group's dT/dt}, the slope of temp_c over its rows (RATE_WINDOW_S at least; the
    neighbours of a group of one row), where the samples have temp_c; else {}. What aux_inputs.column_means
    gives beside each group's mean temp_c."""
    if "temp_c" not in samples or "t_s" not in samples or not len(groups):
        return {}
    t = np.asarray(samples["t_s"], float)
    spans = [t[g] for g in groups]
    return {"temp_rate_c_s": temperature_rate(t, samples["temp_c"], [float(np.mean(x)) for x in spans],
                                              np.maximum([float(np.ptp(x)) for x in spans], RATE_WINDOW_S))}


def rate_input(samples, effects) -> dict[str, NDArray[np.float64]]:
    """{temp_rate_c_s: each row's dT/dt} where one of the library effects read it and the samples have temp_c
    (apply, validate: a calibration with a temperature-rate effect); else {} (no cost where none reads it)."""
    from simucal.generated.effects import EFFECTS
    if "temp_c" not in samples or not any("temp_rate_c_s" in EFFECTS[e].reads for e in effects if e in EFFECTS):
        return {}
    return {"temp_rate_c_s": temperature_rate(samples["t_s"], samples["temp_c"])}


def clusters(T, spread=SPREAD_C) -> np.ndarray:
    """Each temperature's cluster (0, 1, ...): sorted, a new cluster where a temperature lies more
    than `spread` above its cluster's first. Their number is the distinct temperatures."""
    T = np.asarray(T, float)
    out, k, start = np.empty(len(T), int), -1, -np.inf
    for i in np.argsort(T):
        if T[i] - start > spread:
            k, start = k + 1, T[i]
        out[i] = k
    return out


def top_degree(T) -> int:
    """The highest degree temperatures T can test: their distinct values less one, at most MAX_DEGREE."""
    return max(0, min(MAX_DEGREE, len(np.unique(clusters(T))) - 1))


def _wls(dT, y, s, d):
    """Coefficients c_0..c_d, their covariance and chi^2 of a weighted polynomial fit."""
    A = np.vander(dT, d + 1, increasing=True) / s[:, None]
    b = y / s
    cov = np.linalg.pinv(A.T @ A)
    c = cov @ A.T @ b
    return c, cov, float(np.sum((A @ c - b) ** 2))


def fit_polynomial(T_c, values, std, t_ref_c: float, degree: int | None = None) -> records.ThermalPolynomial:
    """One parameter's polynomial in (T - t_ref_c): {degree, coefficients, std, chi2, dof, p_value}.
    degree None: chosen by the sequential chi^2 test (module doc)."""
    dT = np.asarray(T_c, float) - t_ref_c
    y, s = np.asarray(values, float), np.maximum(np.asarray(std, float), 1e-300)
    top = top_degree(T_c)
    if degree is not None and degree > top:
        raise CalibrationError(f"--thermal-degree {degree}: the plateaus hold {top + 1} distinct temperatures (more "
                               f"than {SPREAD_C:g} degC apart), which test at most degree {top}: give more plateaus, "
                               "or a lower degree")
    if degree is None:
        d, (c, cov, chi2) = 0, _wls(dT, y, s, 0)
        while d < top:
            c1, cov1, chi2_1 = _wls(dT, y, s, d + 1)
            if chi2_sf(max(chi2 - chi2_1, 0.0), 1) >= DEGREE_ALPHA:
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


def terms(thermal: records.Thermal | None, name: str, unit: str) -> list[tuple[str, int, float, float, str]]:
    """Parameter `name`'s temperature terms in a block's `thermal` (k >= 1): (name.Tk, k, coefficient, its std,
    unit/degC^k), the parameter in `unit`; none without a polynomial of it."""
    poly = (thermal or {}).get("parameters", {}).get(name, {})
    return [(f"{name}.T{k}", k, float(c), float(e), f"{unit}/degC" + (f"^{k}" if k > 1 else ""))
            for k, (c, e) in enumerate(zip(poly.get("coefficients", [])[1:], poly.get("std", [])[1:]), start=1)]


def std_at(thermal: records.Thermal, name: str, dT) -> np.ndarray:
    """Parameter `name`'s std at dT = T - T_ref (any shape): sqrt(x' C x), x = (1, dT, dT^2, ...), C its
    coefficients' covariance where the block's `thermal` holds it (else their stds, uncorrelated)."""
    f = thermal["parameters"][name]
    dT = np.asarray(dT, float)
    V = np.vander(dT.reshape(-1), len(f["coefficients"]), increasing=True)
    cov = thermal.get("covariance")
    names = [name] + [f"{name}.T{k}" for k in range(1, len(f["coefficients"]))]
    if cov and all(n in cov["names"] for n in names):
        idx = [cov["names"].index(n) for n in names]
        C = np.asarray(cov["matrix"], float)[np.ix_(idx, idx)]
    else:
        C = np.diag(np.asarray(f["std"], float) ** 2)
    return np.sqrt(np.maximum(np.einsum("ik,kl,il->i", V, C, V), 0.0)).reshape(dT.shape)


def params_at(thermal: records.Thermal, names, temp_c) -> np.ndarray:
    """(n, m): the parameters `names` at each temperature temp_c (n,), from a block's `thermal`
    section (its t_ref_c and per-parameter coefficients)."""
    dT = np.asarray(temp_c, float) - thermal["t_ref_c"]
    return np.stack([evaluate(thermal["parameters"][k]["coefficients"], dT) for k in names], axis=-1)


class ThermalModel:
    """A sensor model whose every parameter is a polynomial in (T - T_ref) inside the model, each row at
    its own temperature (the row's dtemp_c):

        N_i = h(u_i, p(T_i)),   p_j(T) = c_j0 + sum_{k=1..d_j} c_jk (T - T_ref)^k

    (IEEE 1293's thermal model, PX4's and ArduPilot's polynomials, for every parameter of h, the
    misalignments included). Its parameters are the base's c_j0 (the unit at T_ref, in the base's
    order) and then c_jk named `<name>.T<k>`, in the base's parameter unit per degC^k. Rows of any
    set of temperatures (plateaus, a ramp) are fitted at once by the exact norm fit (norm_fit), since
    output, jacobians and matrix_and_bias take per-row parameters through the base's generated module.
    No `effects` attribute: the fits treat it as a model of its own (no compiled base fit)."""

    def __init__(self, base, degrees):
        self.base, self.degrees = base, tuple(int(d) for d in degrees)
        self.sensor, self.unit, self.aux = base.sensor, base.unit, base.aux
        m = len(base.params)
        self.terms = [(j, 0) for j in range(m)] + [(j, k) for k in range(1, MAX_DEGREE + 1)
                                                   for j in range(m) if self.degrees[j] >= k]
        self.params = tuple(base.params[j] if not k else f"{base.params[j]}.T{k}" for j, k in self.terms)
        self.param_units = tuple(base.param_units[j] + (f"/degC^{k}" if k > 1 else "/degC" if k else "")
                                 for j, k in self.terms)
        self.name = base.name + "@T" + "".join(map(str, self.degrees))
        self._j = np.array([j for j, _ in self.terms])
        self._k = np.array([k for _, k in self.terms])

    def _powers(self, aux, shape):
        """(..., n, MAX_DEGREE + 1): each row's (T - T_ref)^k."""
        dT = np.zeros(shape or ()) if aux is None else aux.array(("dtemp_c",), shape)[..., 0]  # no aux: at T_ref
        return dT[..., None] ** np.arange(MAX_DEGREE + 1)

    def per_row(self, p, aux, shape):
        """The base's parameters at each row's temperature, (..., n, m), for coefficients p (..., m_ext)."""
        p = np.asarray(p, float)
        C = np.zeros(p.shape[:-1] + (len(self.base.params), MAX_DEGREE + 1))
        C[..., self._j, self._k] = p
        V = self._powers(aux, shape)
        return np.einsum("...jk,...nk->...nj", C, V)

    def _rows(self, u, P, aux):
        """N, dN/du, dN/dp of the base with one parameter vector per row."""
        base = getattr(self.base, "base", self.base)  # an AugmentedModel's generated model
        m0 = len(base.params)
        A = base.aux_array(aux, u.shape[:-1])
        N = base.module.output(u, P[..., :m0], A)
        Ju, Jp = base.module.output_jacobians(u, P[..., :m0], A)
        if base is not self.base and self.base.effects:
            cols = []
            for q, (axis, phi, dphi) in zip(np.moveaxis(P[..., m0:], -1, 0), self.base._terms(u, aux)):
                N[..., axis] += q * phi
                Ju[..., axis, :] += q[..., None] * dphi
                col = np.zeros(u.shape)
                col[..., axis] = phi
                cols.append(col)
            Jp = np.concatenate([Jp, np.stack(cols, axis=-1)], axis=-1)
        return N, Ju, Jp

    def output(self, u, p, aux=None):
        u = np.asarray(u, float)
        return self._rows(u, self.per_row(p, aux, u.shape[:-1]), aux)[0]

    def jacobians(self, u, p, aux=None):
        """N, dN/du and dN/dc: the base's dN/dp_j times each row's (T - T_ref)^k."""
        u = np.asarray(u, float)
        N, Ju, Jp = self._rows(u, self.per_row(p, aux, u.shape[:-1]), aux)
        V = self._powers(aux, u.shape[:-1])
        return N, Ju, Jp[..., self._j] * V[..., None, self._k]

    def matrix_and_bias(self, p, aux=None):
        """M and the bias at each row's temperature (at T_ref where aux holds no temperature)."""
        p = np.asarray(p, float)
        if p.ndim == 3 and p.shape[1] == 1:  # gauss_newton.directions: one p per set, broadcast over rows
            p = p[:, 0]
        if aux is None or ("temp_c" not in aux.values and "dtemp_c" not in aux.values):
            return self.base.matrix_and_bias(p[..., :len(self.base.params)])
        return self.base.matrix_and_bias(self.per_row(p, aux, None), aux)
