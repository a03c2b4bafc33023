"""The gyro of a hand-placed session against its moves: noise floor, test, candidates.

Noise floor, from the stream's own rests (handheld.gyro_noise_dps, move_covariances,
chi2_test: calibrate reports the same test). The gyro's white noise (first
differences over the initial rest, at least the quantisation's q^2/12: sigma_g
per axis and sample, deg/s)
integrates over a move into an attitude error of covariance
    S_theta = T diag(sigma_g^2) T^T sum_k dt_k^2        (rad^2 after scaling),
and each pose direction carries the noise of its accelerometer mean (sigma_a,
g, across the direction). The residual r_i = g_{i+1} - R_i^T g_i then has
    S_i = [p x] S_theta [p x]^T + sigma_a(i+1)^2 P(g_{i+1}) + sigma_a(i)^2 P(p),
p = R_i^T g_i and P(u) = I - u u^T (rank 2: the component along gravity is second
order). chi2 = sum_i r_i^T S_i^+ r_i + |db / sigma_db|^2 on 2m + 3 - 12 dof tests
"the model explains the moves down to the noise". The floor is white noise only:
bias instability over a move, timing jitter and creep of the poses are effects
the test is there to reveal.

Candidates: ranked and chosen over the moves as handheld/moves_selection.py says.
"""
from __future__ import annotations

from typing import Any, cast

import numpy as np

from simucal.fit.augmented import check_effect
from simucal.fit.aux_inputs import FORCE
from simucal.fit.results import Added, ModelTest, SensorDiagnosis, added_params, model_test_keys
from simucal.generated.effects import EFFECTS
from simucal.handheld.gyro_moves import (
    chi2_test,
    gyro_noise_dps,
    move_covariances,
    pose_directions,
    prepare_moves,
    regressor_inputs,
    with_terms,
)
from simucal.handheld.moves import GyroFit, fit_gyro, fit_gyro_moves
from simucal.handheld.moves_selection import moves_family, rank_move_candidates, select_effects
from simucal.io.units import DPH_PER_DPS


def _param_names(n_terms_names):
    return [f"T_{a}{b}" for a in "xyz" for b in "xyz"] + [f"b_{a}" for a in "xyz"] + list(n_terms_names)


def move_rows(gm, fit: GyroFit, S, columns: dict):
    """Per-move residuals in the shape of api/diagnosing.residual_table (one row per move); columns:
    each auxiliary samples.csv column's mean over each move (temp_c, a user's supply_v, ...)."""
    mv, sig = gm.mv, np.sqrt(np.einsum("mii->mi", S))
    return [{"segment": i, "kind": "move", "from_pose": int(a), "to_pose": int(b), "t_span_s": list(span),
             "outer_rate_dps": None, **{k: float(v[i]) for k, v in columns.items()}, "t_s": (span[0] + span[1]) / 2,
             "direction": gm.g_dirs[a].tolist(), "residual": r.tolist(), "sigma": s.tolist(),
             "normalized": (r / s).tolist()}
            for i, (a, b, span, r, s) in enumerate(zip(mv.before, mv.after, mv.t_span, fit.r, sig))]


def diagnose_moves(ms, obs, det, am, fa, add=(), truth=None) -> SensorDiagnosis:
    """The gyro block of `simucal diagnose` for a stream (same keys as for a turntable set): its model test,
    candidates and residuals those of the model with the effects `add`, as on a turntable set; "added"
    compares it with the model without them."""
    gm = prepare_moves(ms, det, *pose_directions(am, obs, fa))
    base = fit = fit_gyro(gm.mv, gm.g_dirs, gm.bias_std)
    sigma_g = gyro_noise_dps(ms, gm)
    S0 = S = move_covariances(gm, base, sigma_g)
    inputs = regressor_inputs(ms, gm, base, (am, fa.vector(am.params)))
    test0, problem = moves_family(gm, base, inputs, chi2_test(base, S0, gm.bias_std, gm.mv))
    mv, names = gm.mv, _param_names([])
    if add:
        for e in add:
            check_effect(e, "gyro")
        mv = with_terms(gm.mv, list(add), inputs)
        fit = fit_gyro_moves(mv, gm.g_dirs, np.r_[base.T.ravel(), base.db, np.zeros(len(add))], gm.bias_std)
        names = _param_names(EFFECTS[e].parameter for e in add)
        S = move_covariances(gm, fit, sigma_g)
    test, problem = (moves_family(gm, fit, inputs, chi2_test(fit, S, gm.bias_std, mv), tuple(add)) if add
                     else (test0, problem))
    chi2, dof, p = test["chi2"], test["dof"], test["p_value"]
    floor = float(np.sqrt(np.einsum("mii->", S) / (3 * len(S)) * max(dof, 0) / (2 * len(S))))
    block = {"residual_rms": float(np.sqrt(np.mean(fit.r ** 2))), "residual_unit": "(gravity direction)",
             "dof": dof, "model": "full 3x3 T + bias" + "".join(f" + {e}" for e in add) + " (moves)",
             "noise": {"source": "the rests' white noise"}, "noise_floor": floor, "noise_std_of_mean": None,
             "gyro_white_noise_dps": sigma_g.tolist(), **test}
    if not fit.converged:  # the test is of the last step, not of a fitted model: said
        block["note"] = f"the moves' fit with {', '.join(add)} did not converge in {fit.iterations} steps"
    inside = gm.mv.dt > 0
    columns = {k: np.sum(np.where(inside, v, 0.0), 1) / np.maximum(inside.sum(1), 1)
               for k, v in inputs.moves[1].values.items() if k not in FORCE}
    fails = ModelTest(chi2, dof, p).fails
    cands = rank_move_candidates(gm, fit, inputs, fails, tuple(add), problem=problem)
    shares = (select_effects(gm, base, sigma_g, inputs, cands)
              if not add and fails and any(c.get("significant") for c in cands) else None)
    vec = lambda f: np.r_[f.T.ravel(), (gm.bias + f.db) * DPH_PER_DPS, f.p]
    std = lambda f: np.sqrt(np.diag(f.cov)) * np.r_[np.ones(9), np.full(3, DPH_PER_DPS), np.ones(len(f.p))]
    out: dict[str, Any] = {**model_test_keys(block), "candidates": cands, "misfit_shares": shares,
           "params": dict(zip(names, vec(fit).tolist())), "std": dict(zip(names, std(fit).tolist())),
           "param_units": {"T": "1 (deg/s of rate per deg/s of output)", "b": "deg/h"},
           "residuals": move_rows(gm, fit, S, columns), "residual_unit": "gravity direction (unit vector), per move",
           "moves_skipped": gm.skipped, "saturation": gm.saturation, "moves_opposite_sense": gm.flipped}
    if add:
        comp = added_params(dict(zip(names, vec(fit).tolist())), dict(zip(names, std(fit).tolist())),
                            dict(zip(names, vec(base).tolist())), dict(zip(names, std(base).tolist())), _known(truth))
        before_after: Added = {"effects": list(add), "residual_rms_before": float(np.sqrt(np.mean(base.r ** 2))),
                               "residual_rms_after": block["residual_rms"], "residual_unit": block["residual_unit"],
                               "p_value_before": test0["p_value"], "p_value_after": p,
                               "params": comp, "residuals_before": move_rows(gm, base, S0, columns)}
        out["added"] = before_after
    return cast(SensorDiagnosis, out)  # tests/test_calibration_file.py checks its keys


def _known(truth) -> dict:
    """What a simulated session's truth.json knows of the moves' parameters (T and the bias in deg/h)."""
    g = (truth or {}).get("gyro", {})
    known = {}
    if "T" in g:
        known.update({f"T_{a}{b}": g["T"][i][j] for i, a in enumerate("xyz") for j, b in enumerate("xyz")})
    if "bias_dps" in g:
        known.update({f"b_{a}": DPH_PER_DPS * g["bias_dps"][i] for i, a in enumerate("xyz")})
    known.update(g.get("params", {}))
    return known
