"""Calibrate a turntable measurement set by dong2018's norm observation (methods exact and linear).

- exact (default): maximum-likelihood norm fits (norm_fit.fit_exact) of both
  triads, then the gyro frame d tied to b by each rate run's mean specific force
  (in b) and mean rate (in d), both along the outer axis (unification.py):
  no accurate table angles needed, unlike eq. 25-27; C_b^d and the gyro M in b
  come with their stds.
- linear: the paper as printed: eq. 8 / 12 with the back-substitution, and
  frame unification by the (derived) eq. 25-27 at the Table 2 positions.
The traditional multi-position method is multiposition.py. Outputs follow
output = M f + bias with f in b (g, deg/h).
"""
from __future__ import annotations

import numpy as np

from simucal.errors import CalibrationError, NotConverged
from simucal.fit.augmented import AugmentedModel, for_sensor
from simucal.fit.candidates import advice_text, forward_selection
from simucal.fit.results import ALPHA, ModelTest
from simucal.fit.lack_of_fit import noise_dof, with_estimated_sigma
from simucal.fit.norm_fit import fit_linear
from simucal.io import blocks, calibration, units
from simucal.turntable.consistency import handedness, latitude_check, static_gyro_rows
from simucal.turntable.model_test import ROWS, AtRest, rank, test_and_rank, with_static_rows
from simucal.turntable.observations import read_observations, table_accuracy_rad
from simucal.turntable.tilt import add_tilt
from simucal.turntable.unification import Unifier, unify, unify_paper


def _find(segs, kind, **want):
    """The index of the first segment of this kind at the angles want, or None."""
    for i, s in enumerate(segs):
        if s.kind == kind and all(getattr(s, k) is not None and abs(getattr(s, k) - v) < 1e-6 for k, v in want.items()):
            return i
    return None


def _rate_run_acc_means(acc_obs, acc_segs, gyro_segs):
    """The rate runs' mean accelerometer outputs (Unifier's acc_means), or None without any, taken
    from the accelerometers' observations as segment_observations gave them (before a fit fills
    their sigma): NaN where neither their scatter nor a statement gives it (the unification then
    estimates it from the rate-run pairs)."""
    if acc_obs is None or gyro_segs is None:  # an accelerometer-only set has no gyro rows to pair
        return None
    at = {s.segment: i for i, s in enumerate(acc_segs) if s.kind == "rate"}
    rows = [j for j, s in enumerate(gyro_segs) if s.segment in at]
    if len(rows) < 2:
        return None
    k = [at[gyro_segs[j].segment] for j in rows]
    return np.array(rows), acc_obs.N[k], acc_obs.sigma[k], acc_obs.aux.take(k)


def _exact_sensor(model, obs, segs, method, where, ranked=True, at_rest=None):
    """Fit and test one sensor by the one model test (model_test.py). Returns (fit, test block or
    None for the linear method, the effect to add when the model fails or None, the observations
    with the noise used). ranked False: no candidates ranked where the model fails (a thermal
    calibration's plateau, whose temperature terms are fitted elsewhere); at_rest: model_test.rank's."""
    if method == "linear":
        if model.effects:
            raise CalibrationError("--add needs --method exact: the paper's linear regression exists for "
                                   "derived models only (or derive a model file with the term and use it)")
        return fit_linear(model, obs), None, None, obs
    try:
        fit, obs2, base, cands, shape, _ = test_and_rank(model, obs, segs, only_if_failing=True, ranked=ranked,
                                                      at_rest=at_rest)
    except NotConverged as e:
        raise CalibrationError(f"{e}; or calibrate by the commanded attitudes alone, which needs no iteration "
                               "(--method multiposition: the Ferraris and multi-position protocols' method)") from None
    if getattr(obs, "noise_file", None) and base.get("noise_warning") and not base.get("noise_too_small"):
        raise CalibrationError(  # a warning for a stated number; a noise file this far off is of another unit
            f"{obs.noise_file}: the {model.sensor} residuals are "
            f"{np.sqrt((base['chi2'] or 0.0) / base['dof']):.2g} times its noise (the chi-square below its 0.1 % "
            "lower tail): the report is of another unit, another output unit or another rate, and would let every "
            "model pass; measure this unit's still recording with simucal noise (or leave --noise out)")
    base["noise"]["text"] = _noise_text(base["noise"], obs2, model.unit)
    advice = advice_text(cands, shape, base) if ModelTest.of(base).fails else None
    return fit, base, advice, with_estimated_sigma(obs2, base["noise"])


def _noise_text(noise, obs, unit):
    """Which noise a fit used and where it came from, in words."""
    if not noise.get("rows_estimated"):
        return f"{np.median(obs.sigma):.2g} {unit} per row (median), from {noise['source']}"
    est = f"{noise['estimated_std']:.2g} {unit} per row estimated from the fit's residuals ({noise['dof']:.3g} dof)"
    n_known = len(obs.N) - noise["rows_estimated"]
    return est + (f" for {noise['rows_estimated']} rows; {n_known} from their scatter or the stated noise" if n_known
                  else ": none in the data or stated")


def _tie(ms, acc, gm, fg, gyro_obs, gyro_segs, base_g):
    """The exact unification of the frames (unification.unify): C_b^d, M in b, its std and the record."""
    am, fa, acc_obs, acc_segs, base_a, acc_means = acc
    un = Unifier(am, fa, acc_obs, gm, fg, gyro_obs, acc_means, noise_dof(base_a["noise"]), noise_dof(base_g["noise"]))
    return unify(un, acc_segs, gyro_segs, _find, table_accuracy_rad(ms))


def _at_rest(ms, acc, gm, fg, gyro_obs, gyro_noise_dph, C_b_d, tie=None) -> AtRest | None:
    """The gyro's static rows as a judge of its model (model_test.AtRest, with the unification pairs where
    tie is given), or None where the set has none."""
    rows, static_gyro = static_gyro_rows(ms, acc[3], gyro_noise_dph)
    return AtRest(ms, acc[1].directions[rows], C_b_d, static_gyro, gm, gyro_obs, fg, tie) if rows else None


def _at_rest_factory(ms, acc, gyro_segs, gyro_noise_dph):
    """at_rest(model, obs, fit, base) for the gyro's ranking (model_test.rank): its static rows with the
    frames tied by this fit, or None where they cannot be (no accelerometer fit, no angles to pair)."""
    fa, acc_segs, acc_means = acc[1], acc[3], acc[5]
    if fa is None or (acc_means is None and any(s.middle_deg is None or s.inner_deg is None
                                                for s in acc_segs + gyro_segs)):
        return None

    def at_rest(model, obs, fit, base):
        try:
            C_b_d = _tie(ms, acc, model, fit, obs, gyro_segs, base)[0]
        except CalibrationError:
            return None
        return _at_rest(ms, acc, model, fit, obs, gyro_noise_dph, C_b_d,
                        lambda m, f: _tie(ms, acc, m, f, obs, gyro_segs, base))
    return at_rest


def _gyro_block(ms, method, cal, acc, gyro, gyro_noise_dph, static_probe=None) -> calibration.SensorBlock:
    """The gyro's block with M in b: the frame d tied to b by the exact unification (any model) or the
    paper's eq. 25-27 (linear, baseline models); in d where nothing ties them (no accelerometers, or
    rate runs without accelerometer data or table angles). Sets cal.unification and, for the exact
    method, the latitude check."""
    am, fa, acc_obs, acc_segs, base_a, acc_means = acc
    gm, fg, gyro_obs, gyro_segs, base_g = gyro
    M_d, b_g = gm.matrix_and_bias(fg.vector(gm.params))
    no_angles = any(s.middle_deg is None or s.inner_deg is None for s in (acc_segs or []) + gyro_segs)
    if fa is None or (no_angles and acc_means is None):
        why = ("no accelerometer data" if fa is None else "the rate runs have no accelerometer data and "
               "segments.csv gives no middle/inner angles to pair them with static positions")
        units.check_scale("gyro", M_d, gm.name)
        block = blocks.sensor_block(gm, fg, M_d, b_g, base_g, np.eye(3))
        block.details.update({"frame": "d (the gyro parameter frame)",
                              "note": f"M is in the gyro frame d, not in b: {why}, so the frames cannot be tied"})
        return block
    std_M = None
    if method == "exact":
        C_b_d, M_b, std_M, info = _tie(ms, acc, gm, fg, gyro_obs, gyro_segs, base_g)
        consistency = cal.details["consistency"]
        consistency["latitude"] = latitude_check(ms, fa, acc_segs, gm, fg, C_b_d, gyro_noise_dph)
        consistency["lines"].append("latitude: " + consistency["latitude"]["verdict"])
        judge = _at_rest(ms, acc, gm, fg, gyro_obs, gyro_noise_dph, C_b_d,
                         lambda m, f: _tie(ms, acc, m, f, gyro_obs, gyro_segs, base_g))
        if judge is not None:  # the gyro's test covers its rows at rest too
            with_static_rows(base_g, judge.test())
            if static_probe:  # diagnose: the same rows judge its twins
                static_probe(judge)
    else:
        if (am.name, gm.name) != ("acc_baseline", "gyro_baseline"):
            raise CalibrationError(f"the paper's frame unification (eq. 25-27) is derived for the baseline "
                                   f"models; {am.name} / {gm.name} have other terms it would neglect: use "
                                   "--method exact, whose unification holds for any model")
        C_b_d, info = unify_paper(acc_obs, acc_segs, gyro_obs, gyro_segs,
                                  fa.vector(am.params), fg.vector(gm.params), ms.meta, _find)
        M_b = M_d @ C_b_d
        info = {"method": "dong2018 eq. 25-27 at the Table 2 positions", "C_b_d": C_b_d.tolist(), **info}
    units.check_scale("gyro", M_b, gm.name)
    block = blocks.sensor_block(gm, fg, M_b, b_g, base_g, C_b_d)
    block.details["M_in_d"] = np.asarray(M_d).tolist()
    if std_M is not None:
        block.details["std_M"] = std_M.tolist()
    if base_g is not None and "static_rows" in base_g:
        block.chi2, block.dof, block.details["static_rows"] = base_g["chi2"], base_g["dof"], base_g["static_rows"]
    cal.unification = info
    return block


def calibrate_table(ms, method, acc_model, gyro_model, ids, acc_noise_g=None, gyro_noise_dph=None,
                    auto=False, noise_curves=None, ranked=True, static_probe=None) -> calibration.Calibration:
    """Calibrate a turntable set (segments.csv) by `method` (exact or linear: methods.py), the models with
    the effect ids added (auto: and the library effects that a failing model needs,
    candidates.forward_selection); noise_curves: {sensor: std of a mean over tau s} (`calibrate --noise`,
    segment_observations); ranked: candidates ranked where a model fails (_exact_sensor); static_probe:
    called with the gyro's static-row test as a function of an added term (diagnose's twins)."""
    if auto and method != "exact":
        raise CalibrationError("--add auto needs --method exact (the effects are chosen by the exact fit's test)")
    # the paper's linear regression (eq. 8) takes static positions only
    rows = ROWS if method == "exact" else {**ROWS, "acc": {"static"}}
    cal, (acc_obs, acc_segs, gyro_obs, gyro_segs) = read_observations(ms, method, rows, acc_noise_g, gyro_noise_dph,
                                                                      noise_curves)
    am = AugmentedModel(acc_model, for_sensor(ids, "acc"))
    gm = AugmentedModel(gyro_model, for_sensor(ids, "gyro"))
    chosen = {}
    if auto and acc_obs is not None:
        chosen["acc"] = forward_selection(am, acc_obs, lambda m, o, f, b: rank(m, o, f, b, acc_segs)[:2])
        am = chosen["acc"].model
    fa = fg = base_a = None
    acc_read = acc_obs  # as read: _exact_sensor returns them with each row's sigma filled in
    if acc_obs is not None:
        fa, base_a, advice_a, acc_obs = _exact_sensor(am, acc_obs, acc_segs, method, str(ms.path), ranked)
        M, b = am.matrix_and_bias(fa.vector(am.params))
        units.check_scale("acc", M, am.name)
        cal.acc = blocks.sensor_block(am, fa, M, b, base_a)
        cal.acc.details["advice"] = advice_a
    acc = (am, fa, acc_obs, acc_segs, base_a,
           _rate_run_acc_means(acc_read, acc_segs, gyro_segs) if fa is not None and method == "exact" else None)
    # the gyro's twins chosen with its static rows too (model_test.choose_twin)
    at_rest = (_at_rest_factory(ms, acc, gyro_segs, gyro_noise_dph) if gyro_obs is not None and method == "exact"
               else None)
    if auto and gyro_obs is not None:
        chosen["gyro"] = forward_selection(gm, gyro_obs, lambda m, o, f, b: rank(m, o, f, b, gyro_segs, at_rest)[:2])
        gm = chosen["gyro"].model
    if gyro_obs is not None:
        fg, base_g, advice_g, gyro_obs = _exact_sensor(gm, gyro_obs, gyro_segs, method, str(ms.path), ranked, at_rest)
    if method == "exact":
        cal.details["consistency"] = {"lines": handedness(ms, fa, acc_obs, acc_segs, fg, gyro_segs)}
    if gyro_obs is not None:
        cal.gyro = _gyro_block(ms, method, cal, acc, (gm, fg, gyro_obs, gyro_segs, base_g), gyro_noise_dph,
                               static_probe)
        if method == "exact":
            add_tilt(cal.gyro, gm, fg, gyro_obs, gyro_segs, ms.meta, lambda p: gm.matrix_and_bias(p)[0],
                     cal.unification and np.array(cal.unification["C_b_d"]))
        cal.gyro.details["advice"] = advice_g
    for s, block in cal.blocks():
        blocks.inflate_if_failing(block)
        if s in chosen:
            block.details["auto"], block.details["auto_stopped"] = chosen[s].steps, chosen[s].stopped
            if (block.details.get("static_rows") or {}).get("p_value", 1.0) < ALPHA \
                    and chosen[s].stopped.startswith("the model passes"):  # auto weighs the rate runs only
                block.details["auto_stopped"] += " over the rate runs; the static rows still misfit (no library" \
                                                 " effect describes a term the rate runs cannot see)"
    if ms.has_gyro and cal.gyro is None:  # the data hold a gyro, the plan determines none of it
        n_rate = sum(s.kind == "rate" for s in ms.segments)
        cal.drop_sensor("gyro", (f"no usable rate runs ({n_rate} in segments.csv, all saturated)" if n_rate else
                                 "no rate runs in segments.csv") + ": the gyro is not calibrated; the norm needs rate "
                        "runs about several axes (the outer axis turning at several middle/inner angles)")
    return cal
