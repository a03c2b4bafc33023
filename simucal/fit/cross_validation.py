"""Judge a norm fit on rows it did not see: leave-one-position-out prediction error.

On its own rows a model with more terms always fits better; on a row left out it does
only if the terms are real. For each row i the exact fit is made without it (started
from the full fit's parameters), and row i's output N_i is inverted by that fit,
u_i = h^-1(N_i; p_(i)). The norm observation (dong2018 eq. 2: |u| is known, 1 g at
rest, |w_T + w_e sin L| in a rate run) is then the prediction: the held-out error is
|u_i| - rho_i, in the input's unit (g or deg/h). The same quantity at the full fit's
parameters is the in-sample error it is compared with.

Used by the model test (candidates.test_model) for every calibration and diagnosis,
and by `--add auto` (fit/selection.py), which adds an effect only when it lowers the held-out
errors by more than chance (paired_improvement; a stream's moves give theirs by
handheld/moves.held_out_moves).
"""
from __future__ import annotations

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.apply import model_function, rowwise_function, solve_inputs
from simucal.fit.distributions import f_sf
from simucal.fit.gauss_newton import fit_batch
from simucal.fit.norm_fit import Fit, Observations, fit_exact
from simucal.io import records


def _norm_error(model, p, obs: Observations, rows, h=None) -> np.ndarray:
    """|h^-1(N_i)| - rho_i for the given rows; h: the model at p (default), or another function of the
    rows (each left-out row's refit), Newton started from the model at p."""
    M, bias = model.matrix_and_bias(p)
    u = solve_inputs(h or model_function(model, p), M, bias, obs.N[rows], obs.aux.take(rows), model.sensor,
                     "cross-validation")
    return np.linalg.norm(u, axis=1) - obs.rho[rows]


def _refits(model, obs: Observations, p) -> np.ndarray:
    """The n fits without one row each, (n, m), all at once, each started at the full fit's p: one call
    of the model's compiled fit, else gauss_newton.fit_batch vectorised over the n sets (each set its
    own rows' auxiliary inputs); NaN rows where a refit did not converge cleanly (leave_one_out then
    refits them one by one, as fit_exact)."""
    n = len(obs.N)
    keep = np.array([np.r_[0:i, i + 1:n] for i in range(n)])  # (n, n - 1): set i lacks row i
    sig = np.broadcast_to(obs.sigma if obs.sigma is not None else 1.0, (n, 3))[keep]
    aux, p0 = obs.aux.take(keep), np.tile(p, (n, 1))
    target = getattr(model, "base", model) if not getattr(model, "effects", ()) else None
    if target is not None and getattr(target, "_fit", None) is not None:
        p_all, _, _, _, _, status = target.fit_compiled(obs.N[keep], obs.rho[keep], sig,
                                                        target.aux_array(aux, keep.shape), p0, covariance=False)
    else:
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            p_all, _, _, _, _, status = fit_batch(model, obs.N[keep], obs.rho[keep], sig, p0, aux)
    p_all[status != 0] = np.nan
    return p_all


def leave_one_out(model, obs: Observations, fit: Fit) -> records.CrossValidation | None:
    """Held-out and in-sample norm errors per row, or None where a row cannot be left out (fewer rows
    than parameters + 1). Rows whose refit fails are counted, not hidden. The refits run at once
    (_refits), and each left-out row is inverted by its refit's parameters, all rows at once."""
    n, m = len(obs.N), len(model.params)
    if n < m + 2:
        return None
    p = fit.vector(model.params)
    P = _refits(model, obs, p)
    failed = []
    for i in np.nonzero(~np.all(np.isfinite(P), axis=1))[0]:
        try:
            P[i] = fit_exact(model, obs.take(np.r_[0:i, i + 1:n]), p0=p).vector(model.params)
        except (CalibrationError, np.linalg.LinAlgError):
            failed.append(obs.labels[i] if obs.labels else int(i))
    held = np.full(n, np.nan)
    ok = np.all(np.isfinite(P), axis=1)
    if ok.any():
        rows = np.nonzero(ok)[0]
        held[rows] = _norm_error(model, p, obs, rows, rowwise_function(model, P[rows]))
    inside = _norm_error(model, p, obs, np.arange(n))
    ok = np.isfinite(held)
    return {"rows": n, "failed": failed, "unit": model.unit,
            "held_out": held.tolist(), "in_sample": inside.tolist(),
            "held_out_rms": float(np.sqrt(np.mean(held[ok] ** 2))) if ok.any() else None,
            "in_sample_rms": float(np.sqrt(np.mean(inside ** 2))),
            "what": "leave one position out: |u_i| - rho_i of the left-out row, inverted by the fit without it"}


def paired_improvement(before, after) -> float | None:
    """One-sided p-value that the errors `after` predict the pieces left out better than `before`
    (each a sequence of held-out errors, one per row or move, NaN where a refit failed): the paired
    differences of squared held-out errors, d_i = e0_i^2 - e1_i^2, by a t test (t^2 ~ F(1, n-1)).
    None where either is None."""
    if before is None or after is None:
        return None
    e0, e1 = np.asarray(before, float), np.asarray(after, float)
    ok = np.isfinite(e0) & np.isfinite(e1)
    d = e0[ok] ** 2 - e1[ok] ** 2
    if len(d) < 3:
        return None
    sd = d.std(ddof=1)
    if sd == 0:
        return 0.0 if d.mean() > 0 else 1.0
    t = d.mean() / (sd / np.sqrt(len(d)))
    p_two = float(f_sf(t * t, 1, len(d) - 1))
    return p_two / 2 if t > 0 else 1 - p_two / 2
