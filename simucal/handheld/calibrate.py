"""Calibration of a hand-placed session (Tedaldi et al. 2014, as in imu_tk): a continuous stream of
a unit put by hand in many static poses.

- the accelerometer from the static poses (poses.py: found by static_detect, the exact norm
  fit of any model);
- the gyro from the moves between them (moves.py: T = M_g^-1 and the bias, each move's
  integrated rotation against the gravity directions before and after), here prepared from
  the stream (the moves' samples, their noise, the regressors of candidate effects along them),
  with the effects a failing fit needs (`--add auto`: moves_selection.select_effects) and the
  entries of T the moves cannot see.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit import family
from simucal.fit.candidates import advice, advice_text, forward_selection, targeted
from simucal.fit.results import ModelTest
from simucal.generated.effects import EFFECTS
from simucal.handheld.gyro_moves import (
    GyroMoves,
    chi2_test,
    gyro_noise_dps,
    move_covariances,
    pose_directions,
    prepare_moves,
    regressor_inputs,
    with_terms,
)
from simucal.handheld.moves import (GYRO_MODEL_TEXT, GYRO_MODELS, PRIOR_T, UNSEEN_STD, GyroFit, choose_gyro_model,
                                    fit_gyro)
from simucal.handheld.moves_selection import moves_family, rank_move_candidates, select_effects
from simucal.io import blocks, calibration, units
from simucal.io.details import FamilyTest
from simucal.io.calibration import Calibration, EffectValue, SensorBlock
from simucal.handheld.poses import acc_from_poses
from simucal.handheld.static_detect import Detection, dropped_text


def _gyro_fit(ms, gm: GyroMoves, acc_cal, gyro_effects, auto):
    """The gyro's fit over the moves with the effects asked for (auto: and those the failing moves
    need, moves_selection.select_effects): (fit, {id: EffectValue}, the auto selection or None)."""
    f = fit_gyro(gm.mv, gm.g_dirs, gm.bias_std)
    effects, chosen = {}, None
    if auto and f.converged:
        chosen = select_effects(gm, f, gyro_noise_dps(ms, gm), regressor_inputs(ms, gm, f, acc_cal))
        gyro_effects = tuple(dict.fromkeys(tuple(gyro_effects) + tuple(chosen["effects"])))
    if gyro_effects and f.converged:
        gm.mv = with_terms(gm.mv, list(gyro_effects), regressor_inputs(ms, gm, f, acc_cal))
        f = fit_gyro(gm.mv, gm.g_dirs, gm.bias_std, np.r_[f.T.ravel(), f.db, np.zeros(len(gyro_effects))])
        std_p = np.sqrt(np.diag(f.cov)[12:])
        effects = {e: EffectValue(v, sd, EFFECTS[e].unit, EFFECTS[e].meaning)
                   for e, v, sd in zip(gyro_effects, f.p, std_p)}
    if not f.converged:
        raise CalibrationError(f"{ms.path}: the gyro fit over the moves did not converge in {f.iterations} "
                               "Gauss-Newton steps; look at the moves (simucal diagnose) for ones the model "
                               "cannot follow")
    return f, effects, chosen


def _hold_unseen(ms, gm: GyroMoves, f: GyroFit):
    """Entries of T the moves barely see (std alone above UNSEEN_STD: the unit hardly turned about
    that axis) held at nominal under a prior: (fit, their indices, {name: why}, the quiet outputs)."""
    mv = gm.mv
    std_alone = np.sqrt(np.diag(f.cov)[:9])
    unseen = [k for k in range(9) if std_alone[k] > UNSEEN_STD]
    if not unseen:
        return f, unseen, {}, []
    rms = np.sqrt(np.sum(mv.y ** 2 * mv.dt, axis=(1, 2)) / np.sum(mv.dt))  # per output axis, deg/s
    dead = [f"{'xyz'[j]} ({rms[j]:.2g} deg/s against {rms.max():.2g})" for j in range(3) if rms[j] < 0.05 * rms.max()]
    if len(unseen) == 9:
        raise CalibrationError(f"{ms.path}: the moves leave every entry of the gyro's T unobservable (std above "
                               f"{UNSEEN_STD}): " + (f"gyro output {', '.join(dead)} hardly changes during the moves: "
                                                     "a dead or unconnected channel?" if dead else
                                                     "turn the unit about every axis between poses"))
    f = fit_gyro(mv, gm.g_dirs, gm.bias_std, np.r_[f.T.ravel(), f.db, f.p], held=unseen)
    undetermined = {f"T_{'xyz'[k // 3]}{'xyz'[k % 3]}": {
        "determined": False, "std_moves_alone": float(std_alone[k]), "held_at": float(np.eye(3).ravel()[k]),
        "prior_std": PRIOR_T,
        "to_determine": f"turn about the {'xyz'[k % 3]} axis by at least 90 deg between two poses"} for k in unseen}
    return f, unseen, undetermined, dead


def _gyro_block(ms, det, am, obs, fa, acc_cal, gyro_effects, auto) -> SensorBlock:
    """The gyro's block: T = M^-1 and the bias from the moves, the model (nominal, scale or full)
    chosen by the moves left out, the chi-square of the moves."""
    gm = prepare_moves(ms, det, *pose_directions(am, obs, fa))
    f, effects, chosen = _gyro_fit(ms, gm, acc_cal, gyro_effects, auto)
    f, unseen, undetermined, dead = _hold_unseen(ms, gm, f)
    mv = gm.mv
    assert mv.t_span is not None  # build_moves gives every move's times
    gyro_model, f, choice = choose_gyro_model(mv, gm.g_dirs, gm.bias_std, f, unseen)
    fixed = GYRO_MODELS[gyro_model]
    if gyro_model != "full":
        undetermined = {k: v for k, v in undetermined.items() if "xyz".index(k[2]) * 4 not in fixed
                        and "xyz".index(k[2]) == "xyz".index(k[3])}
    chi2, dof, p_value = omnibus = chi2_test(f, move_covariances(gm, f, gyro_noise_dps(ms, gm)), gm.bias_std, mv)
    if undetermined and dead and p_value is not None and p_value < 1e-6:
        # a quiet output that the held nominal cannot explain: the channel does not respond
        raise CalibrationError(f"{ms.path}: gyro output {', '.join(dead)} hardly changes during the moves, and "
                               f"holding {list(undetermined)} at nominal leaves the moves unexplained (chi2 "
                               f"{chi2:.3g} on {dof} dof): a dead or unconnected channel?")
    to_add, inputs = None, regressor_inputs(ms, gm, f, acc_cal)
    test, problem = moves_family(gm, f, inputs, omnibus, effects, fixed)
    if ModelTest.of(test).fails and not effects:  # the strongest candidate, as diagnose names it
        to_add = advice_text(rank_move_candidates(gm, f, inputs, True, fixed=fixed, problem=problem), None, test)
    bias_std = gm.bias_std if gyro_model == "nominal" else np.sqrt(np.diag(f.cov)[9:12])
    std_T = [[None if 3 * i + j in fixed else float(np.sqrt(f.cov[3 * i + j, 3 * i + j])) for j in range(3)]
             for i in range(3)]
    M_g = np.linalg.inv(f.T)
    units.check_scale("gyro", M_g, ms.path / "samples.csv")
    return blocks.affine_block(
        "gyro", M_g, (gm.bias + f.db) * units.DPH_PER_DPS,
        {"T": std_T, "bias": (bias_std * units.DPH_PER_DPS).tolist()},
        float(np.sqrt(np.mean(np.sum(f.r ** 2, 1)))), GYRO_MODEL_TEXT[gyro_model],
        residual_unit="gravity direction (unit vector), per move", effects=effects,
        T=f.T.tolist(), T_note="T = M^-1: the rate in b is T (output - bias - effects)",
        moves=[{"from_pose": int(a), "to_pose": int(b), "t_s": list(span), "residual": ri.tolist()}
               for a, b, span, ri in zip(mv.before, mv.after, mv.t_span, f.r)],
        moves_used=int(len(f.r)), moves_skipped=gm.skipped, saturation=gm.saturation,
        moves_opposite_sense=gm.flipped, iterations=f.iterations, **test,
        std_note="stds scale with the moves' own residual scatter, so they include any misfit",
        undetermined=undetermined, gyro_model=gyro_model, model_choice=choice, advice=to_add,
        **({"auto": chosen["steps"], "auto_stopped": chosen["stopped"]} if chosen else {"auto": []} if auto else {}))


def dropped_warnings(det: Detection, t) -> list[str]:
    """The console's line for the still intervals a rule dropped (static_detect: each with its rule and numbers;
    stretches shorter than half --min-static-s, a pause in a move, counted), with the gyro limit in force."""
    if not det.dropped:
        return []
    min_s = det.min_samples * float(np.median(np.diff(t)))
    limit = f" ({det.gyro_limit['text']})" if det.gyro_limit else ""
    return [f"static detection: {len(det.dropped)} still interval{'s' * (len(det.dropped) != 1)} dropped: "
            + dropped_text(det.dropped, "; ", skip_short_s=min_s / 2) + limit]


def calibrate_handheld(ms, acc_model="acc_baseline", detect=None, pose_window_s=1.0, gyro_effects=(),
                       auto=False) -> Calibration:
    """pose_window_s: seconds at the start of each static interval averaged into the
    pose (None: the whole interval). Hand-placed poses creep: on imu_tk's Xsens
    session the baseline's chi2 falls from 472 to 141 (29 dof) when only the first
    second is used, which is also imu_tk's convention (100 samples).
    gyro_effects: candidate ids fit with T and the bias over the moves."""
    obs, det, am, fa, tau, std_noise = acc_from_poses(ms, acc_model, detect, pose_window_s)
    if auto:  # the library effects the failing poses need (candidates.forward_selection)
        acc_auto = forward_selection(am, obs, table=False)
        if acc_auto.steps:
            obs, det, am, fa, tau, std_noise = acc_from_poses(ms, acc_auto.model, detect, pose_window_s)
    M_a, b_a = am.matrix_and_bias(fa.vector(am.params))
    units.check_scale("acc", M_a, ms.path / "samples.csv")
    cal = calibration.header("handheld (Tedaldi): exact norm fit + gyro moves", ms)
    cal.details["static_detection"] = {**det.as_dict(ms.samples["t_s"]), "pose_window_s": pose_window_s}
    cal.warnings += dropped_warnings(det, ms.samples["t_s"])
    cal.acc = blocks.sensor_block(am, fa, M_a, b_a)
    # the poses' test made the model test's family (fit/family.py), each pose weighted as the fit weighs it
    test: FamilyTest = {"p_value": cal.acc.p_value, "test": "chi-square of the poses against their own noise"}
    assert obs.sigma is not None  # each pose's std (pose_observations)
    family.fold(test, targeted(am, replace(obs, sigma=np.hypot(obs.sigma, tau)), fa))
    cal.acc.p_value = test.pop("p_value")
    cal.acc.details.update(test)
    cal.acc.details.update({"undetermined": fa.undetermined, "model_error_std_g": tau, "note": None if tau == 0 else (
        "the model does not explain the poses down to their own noise (see chi2, p_value before "
        "the extra variance: simucal diagnose); each pose got an extra variance tau^2 so that "
        "chi2/dof = 1, and the stds include it")})
    if std_noise:  # the certificate's budget: u's share from the poses' noise, the rest the model's misfit
        cal.acc.details["std_noise"] = {n: float(v) for n, v in std_noise.items() if n in cal.acc.params}
    if auto:
        cal.acc.details.update({"auto": acc_auto.steps, "auto_stopped": acc_auto.stopped})
    if cal.acc.verdict == "fails" and not fa.undetermined:
        cal.acc.details["advice"] = advice(am, obs)  # what diagnose names for the poses (its fit has no prior)
    if ms.has_gyro:
        cal.gyro = _gyro_block(ms, det, am, obs, fa, (am, fa.vector(am.params)), gyro_effects, auto)
    return cal
