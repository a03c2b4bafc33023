"""One thermal fit of every row at its own temperature, and each parameter's degree chosen by the data.

The rows of all plateaus (or of one ramp) are fitted at once with every parameter a polynomial in
(T - T_ref) (thermal.ThermalModel; the exact norm fit, norm_fit.fit_exact). Degrees per parameter:

1. every parameter at the top degree the data can test: the distinct temperatures (clusters of rows
   within SPREAD_C of each other: plateaus, or bands of a ramp) less one, at most MAX_DEGREE;
   (where the rows are fewer than SATURATED_ROWS per coefficient, or that fit does not converge, the
   coefficients are added one at a time from constants instead, the best of the k candidates while
   its chi^2 drop is beyond ALPHA / k's tail of chi^2(1), the best of k tested as such, or while the
   model fails its test: something it lacks shows);
2. backward elimination by the model's own test: the highest coefficient of the parameter whose Wald
   statistic (c / std)^2 is weakest is dropped while its chi^2(1) tail is above ALPHA / (j + 1) after
   j drops, and the model refitted: Hochberg's step-up (1988), so that ALPHA (the model test's level)
   bounds the chance that ANY coefficient the truth lacks stays, not each one's (at ALPHA each, the
   18 coefficients a sensor tests to degree 2 kept one the truth lacks, at 3.4 std, in one bench seed of 8);
   a coefficient stays wherever the model without it fails the model test and the model with it passes
   (a ramp's gyro: 50 rows cannot show b_z's curvature beyond ALPHA / k, yet fail without it);
3. prediction of a group left out (an inner plateau, an inner band of a ramp: interpolation): each
   parameter's top coefficient is also dropped where the model without it predicts the left-out
   groups' rows no worse (their chi^2 summed over the folds), wherever every fold still holds the
   distinct temperatures the degrees need (three plateaus cannot test a quadratic this way: 2 would
   be left) and the model predicts them (their chi^2 within its ALPHA tail over their rows: a ramp in
   the plan's order leaves out a band of positions the rest cannot predict, held-out chi^2 1752 on
   about 50 rows in one bench seed, where dropping the gyro's true b_x curvature "predicted better"),
   and never where the model without it fails its test and with it passes (as in step 2: at plateaus
   0, 25 and 50 degC the outer two predict the middle one as well without a linear bias term as with it).

Each group's rows are then tested under the joint model (chi^2 over the group with its share of the
degrees of freedom: its rows less their leverage on the parameters).
"""
from __future__ import annotations

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.distributions import chi2_sf
from simucal.fit.gauss_newton import directions
from simucal.fit.norm_fit import fit_exact, jacobian_blocks
from simucal.fit.thermal import SPREAD_C, ThermalModel, clusters, top_degree
from simucal.io import records

ALPHA = 1e-3      # the model test's level: the chance of keeping any coefficient the truth lacks (module doc)
RAMP_BANDS = 4    # a ramp is left out in this many equal bands of its temperature range
SATURATED_ROWS = 2  # every coefficient at once where the rows are at least this many per coefficient


def _start(model, prev=None, fit=None):
    """Start values for model: the previous fit's coefficients where it had them, else 0."""
    if prev is None:
        return None
    old = dict(zip(prev.params, fit.vector(prev.params)))
    return np.array([old.get(n, 0.0) for n in model.params])


def fit_degrees(base, obs, degrees, prev=None, prev_fit=None, p0=None):
    """(model, fit) of base with the given degrees, started from a previous fit or p0."""
    model = ThermalModel(base, degrees)
    if prev is not None:
        start = _start(model, prev, prev_fit)
    elif isinstance(p0, dict):
        start = np.array([p0.get(n, 0.0) for n in model.params])
    else:
        start = np.zeros(len(model.params)) if p0 is None else p0
    return model, fit_exact(model, obs, start)


def _weakest(model, fit):
    """(parameter index, its top coefficient's chi^2(1) tail) of the weakest top coefficient, or None."""
    best = None
    for j, d in enumerate(model.degrees):
        if d:
            name = f"{model.base.params[j]}.T{d}"
            p = chi2_sf((fit.params[name] / max(fit.std[name], 1e-300)) ** 2, 1)
            if best is None or p > best[1]:
                best = (j, p)
    return best


def inner_groups(groups, T) -> list:
    """The groups whose mean temperature is neither the lowest nor the highest."""
    ids = np.unique(groups)
    means = [np.mean(T[groups == g]) for g in ids]
    return [g for g, t in zip(ids, means) if min(means) < t < max(means)]


def predict_chi2(model, obs, p) -> np.ndarray:
    """Each row's chi^2 under parameters p, its direction taken from the output (M^-1 (N - b))."""
    u = directions(model, obs.N, p, obs.aux)
    r = (obs.N - model.output(obs.rho[:, None] * u, p, obs.aux)) / obs.sigma
    return np.sum(r ** 2, axis=1)


def held_out(base, obs, groups, degrees, p0) -> float | None:
    """The left-out groups' rows' chi^2 summed over the folds (each inner group predicted by the fit
    without it: interpolation, as the calibration will be used; an end group left out is an
    extrapolation that a subset's confounded coefficients can throw anywhere), or None where a fold
    lacks the distinct temperatures the degrees need."""
    T = obs.aux.column("temp_c", len(obs.N))
    total = 0.0
    for g in inner_groups(groups, T):
        keep = groups != g
        if len(np.unique(clusters(T[keep]))) - 1 < max(degrees):
            return None
        try:
            model, fit = fit_degrees(base, obs.take(np.nonzero(keep)[0]), degrees, p0=p0)
        except CalibrationError:
            return None
        total += float(np.sum(predict_chi2(model, obs.take(np.nonzero(~keep)[0]), fit.vector(model.params))))
    return total


def select(base, obs, groups, forced=None, p0=None):
    """(model, fit, how each degree was chosen, obs with every row's sigma) for one sensor: module doc. groups: each
    row's plateau or band; forced: one degree for every parameter; p0: start values by name. Rows without a known
    sigma take one estimated from the top-degree fit (lack_of_fit.fit_with_noise)."""
    m = len(base.params)
    T = obs.aux.column("temp_c", len(obs.N))
    top = top_degree(T)
    if obs.sigma is None or not np.all(np.isfinite(obs.sigma)):
        from simucal.fit.lack_of_fit import fit_with_noise, with_estimated_sigma
        model = ThermalModel(base, [top] * m)
        _, obs, noise = fit_with_noise(model, obs, np.array([(p0 or {}).get(n, 0.0) for n in model.params]))
        obs = with_estimated_sigma(obs, noise)
    if forced is not None:
        if forced > top:
            raise CalibrationError(f"--thermal-degree {forced}: the {base.sensor} rows hold {top + 1} distinct "
                                   f"temperatures (more than {SPREAD_C:g} degC apart), which test at most degree "
                                   f"{top}: give more plateaus or a wider ramp, or a lower degree")
        model, fit = fit_degrees(base, obs, [forced] * m, p0=p0)
        return model, fit, {"from": "--thermal-degree", "dropped": [], "top": top}, obs
    dropped: list[dict] = []
    try:
        if len(obs.N) < SATURATED_ROWS * m * (top + 1):
            raise CalibrationError("too few rows for every coefficient at once")
        model, fit = fit_degrees(base, obs, [top] * m, p0=p0)
    except CalibrationError:  # every coefficient at once is more than the rows determine: add them one by one
        model, fit = _forward(base, obs, top, p0, dropped)
    for j in range(1, len(base.params) * top + 1):  # j - 1 dropped: Hochberg's level ALPHA / j (module doc)
        weak = _weakest(model, fit)
        if weak is None or weak[1] < ALPHA / j:
            break
        deg = list(model.degrees)
        deg[weak[0]] -= 1
        trial = fit_degrees(base, obs, deg, model, fit)
        if _fails(trial[1]) and not _fails(fit):  # the model test needs it: it stays
            break
        dropped.append({"parameter": base.params[weak[0]], "degree": model.degrees[weak[0]], "by": "model test",
                        "p_value": float(weak[1]), "level": ALPHA / j})
        model, fit = trial
    model, fit = _by_prediction(base, obs, groups, model, fit, dropped)
    return model, fit, {"from": "the data", "dropped": dropped, "top": top}, obs


def _fails(fit) -> bool:
    """The model test rejects the fit at ALPHA: something the model lacks shows."""
    return fit.p_value is not None and fit.p_value < ALPHA


def _forward(base, obs, top, p0, added):
    """Forward selection from constants: the coefficient whose addition lowers chi^2 most is added while
    that drop is beyond ALPHA / k's tail of chi^2(1), k the candidates, or while the model fails its test
    (where the rows cannot hold every coefficient at once)."""
    model, fit = fit_degrees(base, obs, [0] * len(base.params), p0=p0)
    while True:
        best, k = None, sum(d < top for d in model.degrees)
        for j, d in enumerate(model.degrees):
            if d < top:
                deg = list(model.degrees)
                deg[j] += 1
                try:
                    trial = fit_degrees(base, obs, deg, model, fit)
                except CalibrationError:
                    continue
                if best is None or trial[1].chi2 < best[1].chi2:
                    best = trial
        if best is None or chi2_sf(max(fit.chi2 - best[1].chi2, 0.0), 1) >= (1.0 if _fails(fit) else ALPHA / k):
            return model, fit
        j = int(np.argmax(np.array(best[0].degrees) != np.array(model.degrees)))
        added.append({"parameter": base.params[j], "degree": best[0].degrees[j], "by": "model test (added)",
                      "p_value": float(chi2_sf(max(fit.chi2 - best[1].chi2, 0.0), 1)), "level": ALPHA / k})
        model, fit = best


def _by_prediction(base, obs, groups, model, fit, dropped):
    """Step 3 of the module doc: a top coefficient dropped where the groups left out are predicted no
    worse without it."""
    if len(np.unique(groups)) < 3:
        return model, fit
    p_now = fit.vector(model.params)
    now = held_out(base, obs, groups, model.degrees, p_now)
    inner = int(np.isin(groups, inner_groups(groups, obs.aux.column("temp_c", len(obs.N)))).sum())
    if now is None or chi2_sf(now, inner) < ALPHA:  # the folds do not predict their groups: they cannot judge
        return model, fit
    for j in np.argsort([-1 if not d else abs(fit.params[f"{base.params[j]}.T{d}"] / fit.std[f"{base.params[j]}.T{d}"])
                         for j, d in enumerate(model.degrees)]):
        d = model.degrees[j]
        if not d:
            continue
        deg = list(model.degrees)
        deg[j] -= 1
        trial = ThermalModel(base, deg)
        without = held_out(base, obs, groups, deg, _start(trial, model, fit))
        if without is None or without > now:
            continue
        trial_model, trial_fit = fit_degrees(base, obs, deg, model, fit)
        if _fails(trial_fit) and not _fails(fit):  # step 2's rule: the model test needs it, it stays (a slope
            continue                               # through plateaus symmetric about T_ref predicts the middle one)
        dropped.append({"parameter": base.params[j], "degree": d, "by": "groups left out",
                        "held_out_chi2": [without, now]})
        model, fit, now = trial_model, trial_fit, without
    return model, fit


def group_tests(model, obs, fit, groups) -> list[records.ThermalGroup]:
    """Each group's rows tested under the joint fit: chi^2 over its rows, dof = its rows less their
    leverage on the parameters (the directions profiled out; the leverages sum to the parameters)."""
    r, Jq, Jd, _ = jacobian_blocks(model, obs, fit.vector(model.params), fit.directions, obs.sigma)
    JdT = Jd.swapaxes(-1, -2)
    Jt = Jq - Jd @ np.linalg.solve(JdT @ Jd, JdT @ Jq)  # the row's Jacobian with its direction profiled out
    Hinv = np.linalg.pinv(np.einsum("iam,ian->mn", Jt, Jt))
    lev = np.einsum("iam,mn,ian->i", Jt, Hinv, Jt)
    chi = np.sum(r ** 2, axis=1)
    out: list[records.ThermalGroup] = []
    for g in np.unique(groups):
        k = groups == g
        dof = float(np.sum(k) - np.sum(lev[k]))
        c = float(np.sum(chi[k]))
        out.append({"rows": int(np.sum(k)), "chi2": c, "dof": dof,
                    "p_value": float(chi2_sf(c, dof)) if dof > 0 else None})
    return out
