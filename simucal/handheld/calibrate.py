"""Calibration of a hand-placed session (Tedaldi et al. 2014, as in imu_tk): a continuous stream of
a unit put by hand in many static poses.

- the accelerometer from the static poses (poses.py: found by static_detect, the exact norm
  fit of any model);
- the gyro from the moves between them (moves.py: T = M_g^-1 and the bias, each move's
  integrated rotation against the gravity directions before and after), here prepared from
  the stream (the moves' samples, their noise, the regressors of candidate effects along them),
  with the effects a failing fit needs (misfit_shares) and the entries of T the moves cannot see.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.augmented import effect_ids, regressor
from simucal.fit.apply import model_inputs
from simucal.fit.aux_inputs import AuxInputs, columns_at, specific_force
from simucal.fit.candidates import advice, forward_selection
from simucal.fit.results import ALPHA, ModelTest
from simucal.fit.distributions import chi2_sf, f_sf
from simucal.fit.noise import quantization_step, white_noise_var
from simucal.fit.norm_fit import full_covariance
from simucal.fit.rotations import skew
from simucal.generated.effects import EFFECTS
from simucal.handheld.static_detect import Detection
from simucal.io import calibration, units
from simucal.io.calibration import Calibration, EffectValue, SensorBlock
from simucal.io.sensor_checks import saturated_rows


from simucal.handheld.moves import (
    GYRO_MODEL_TEXT,
    GYRO_MODELS,
    PRIOR_T,
    UNSEEN_STD,
    GyroFit,
    Moves,
    build_moves,
    check_rotation_sense,
    choose_gyro_model,
    decimate,
    fit_gyro,
    fit_gyro_moves,
    move_residuals,
)
from simucal.handheld.poses import acc_from_poses


@dataclass
class GyroMoves:
    """What the gyro fit needs from a stream (calibrate and diagnose share it)."""
    mv: Moves
    g_dirs: np.ndarray     # (poses, 3) calibrated gravity directions of the poses, in b
    dir_var: np.ndarray    # (poses,) variance of each tangent component of g_dirs (rad^2)
    bias: np.ndarray       # gyro bias from the initial rest (deg/s)
    bias_std: np.ndarray   # its standard error (deg/s)
    rest: slice            # the rest's rows
    skipped: list          # moves left out, with the reason
    saturation: list       # saturated samples found
    flipped: list          # moves turning gravity against the gyro's sense


def pose_directions(am, obs, fa):
    """The poses' calibrated gravity directions in b (n, 3) and the variance of each of their
    tangent components (n,), from the accelerometer fit's full covariance: the pose's own noise
    and the accelerometer parameters' uncertainty, which the poses share. The noise alone is
    about 2/3 of it on a 30-pose session; counting only it left the moves' chi2/dof at 1.14
    on clean simulated sessions. The directions are the exact fit's own, of the whole model (its
    effects too), which that covariance describes."""
    C = full_covariance(am, obs, fa)
    m = len(am.params)
    tangent = np.diagonal(C[m:, m:]).reshape(-1, 2).sum(1) / 2
    return fa.directions, tangent


def prepare_moves(ms, det: Detection, g_dirs, dir_var) -> GyroMoves:
    w = ms.gyro_dph() / units.DPH_PER_DPS  # deg/s
    # the first static interval, trimmed by half a window: a centred window sees
    # the start of a move half a window late
    rest = slice(det.starts[0] + det.window // 2, det.ends[0] - det.window // 2)
    bias = w[rest].mean(0)
    bad, sat = saturated_rows(ms, "gyro")
    mv, skipped = build_moves(w, ms.samples["t_s"], det, bias, bad)
    flipped = check_rotation_sense(decimate(mv, 4), g_dirs, np.eye(3))  # a sign question: coarse moves suffice
    # a rest quieter than one LSB averages to within about q/sqrt(12), not s/sqrt(n)
    s, q = w[rest].std(0, ddof=1), quantization_step(w[rest], w)
    bias_std = np.maximum(np.where(s < q, q / np.sqrt(12), s / np.sqrt(rest.stop - rest.start)), 1e-9)
    return GyroMoves(mv, g_dirs, dir_var, bias, bias_std, rest, skipped, sat, flipped)


def gyro_noise_dps(ms, gm) -> np.ndarray:
    """White noise of one gyro sample (deg/s) from the initial rest: a moving gyro has at
    least its quantisation noise, even where the rest reads constant."""
    rest = ms.gyro_dph()[gm.rest] / units.DPH_PER_DPS
    return np.sqrt(np.maximum(white_noise_var(rest), quantization_step(rest, ms.gyro_dph() / units.DPH_PER_DPS) ** 2 / 12))


def move_covariances(gm, fit: GyroFit, sigma_g_dps):
    """S_i of every move (m, 3, 3), in squared unit-vector components: the gyro noise integrated
    over the move, and the two poses' direction variances (pose_directions), each in the plane
    normal to its direction."""
    mv = gm.mv
    ang = fit.T @ np.diag(sigma_g_dps ** 2) @ fit.T.T * np.radians(1.0) ** 2
    S_theta = ang[None] * np.sum(mv.dt ** 2, axis=1)[:, None, None]
    g1 = gm.g_dirs[mv.after]
    pred = g1 - fit.r
    pred /= np.linalg.norm(pred, axis=1, keepdims=True)
    s_a2 = gm.dir_var
    P = lambda u: np.eye(3) - u[:, :, None] * u[:, None, :]
    K = skew(pred)
    return (K @ S_theta @ K.transpose(0, 2, 1) + s_a2[mv.after, None, None] * P(g1)
            + s_a2[mv.before, None, None] * P(pred))


def chi2_test(fit: GyroFit, S, bias_std, mv: Moves):
    chi2 = sum(float(r @ np.linalg.pinv(s, rcond=1e-6, hermitian=True) @ r) for r, s in zip(fit.r, S))
    rest = fit.db.copy()  # the rest reads b + sum_j p_j e_j phi_j(rest): the prior's residual
    for j, axis in enumerate(mv.phi_axes):
        rest[axis] += fit.p[j] * mv.phi_rest[j]
    chi2 += float(np.sum((rest / bias_std) ** 2))
    dof = 2 * len(fit.r) + 3 - 12 - len(fit.p)
    return chi2, dof, float(chi2_sf(chi2, dof)) if dof > 0 else None


def misfit_shares(gm, base: GyroFit, sigma_g, inputs, chi0, dof0, max_terms=9) -> dict:
    """How much of the moves' misfit the library explains, effect by effect: forward selection.
    Each step adds the candidate that lowers the chi-square most, kept while its F test against
    the remaining misfit, F = (chi2_before - chi2_after) / (chi2_after / dof_after), beats
    ALPHA / (candidates left), ALPHA the model test's level (fit/results.py). share: its chi-square
    drop over the baseline's excess
    (chi2 - dof); `unexplained` is what the chosen effects leave of that excess."""
    excess0 = max(chi0 - dof0, 1e-300)
    chosen, steps, chi_prev, fit = [], [], chi0, base
    left = [e for e in effect_ids("gyro") if has_input(e, inputs)]
    while len(chosen) < max_terms:
        # rank the candidates on moves in blocks of 4 samples with their defect against full
        # resolution at the current fit (as fit_gyro does), then refit the best at full resolution
        mv = with_terms(gm.mv, chosen, inputs)
        defect = (move_residuals(fit.T, mv, gm.g_dirs, jac=False, db=fit.db, p=fit.p)[0]
                  - move_residuals(fit.T, decimate(mv, 4), gm.g_dirs, jac=False, db=fit.db, p=fit.p)[0])
        trials = []
        for eid in left:
            mv4 = decimate(with_terms(gm.mv, chosen + [eid], inputs), 4)
            f = fit_gyro_moves(mv4, gm.g_dirs, np.r_[fit.T.ravel(), fit.db, fit.p, 0.0], gm.bias_std, offset=defect)
            if f.converged and np.all(np.isfinite(f.cov)):
                trials.append((float(np.sum(f.r ** 2)), eid))
        if not trials:
            break
        eid = min(trials)[1]
        mv = with_terms(gm.mv, chosen + [eid], inputs)
        f = fit_gyro_moves(mv, gm.g_dirs, np.r_[fit.T.ravel(), fit.db, fit.p, 0.0], gm.bias_std)
        if not f.converged:
            break
        chi2, dof, _ = chi2_test(f, move_covariances(gm, f, sigma_g), gm.bias_std, mv)
        F = (chi_prev - chi2) / max(chi2 / dof, 1e-300) if dof > 0 else 0.0
        p = float(f_sf(max(F, 0.0), 1, dof)) if dof > 0 else 1.0
        if p >= ALPHA / len(left):
            break
        k = len(chosen)
        steps.append({"id": eid, "estimate": float(f.p[k]), "std": float(np.sqrt(f.cov[12 + k, 12 + k])),
                      "unit": EFFECTS[eid].unit, "chi2_after": chi2, "dof_after": dof, "F": float(F), "p_value": p,
                      "share": float((chi_prev - chi2) / excess0),
                      "residual_rms_after": float(np.sqrt(np.mean(f.r ** 2)))})
        chosen.append(eid)
        left = [e for e in left if e != eid]
        chi_prev, fit = chi2, f
    return {"chi2": chi0, "dof": dof0, "residual_rms": float(np.sqrt(np.mean(base.r ** 2))), "steps": steps,
            "effects": chosen,
            "unexplained": float(max(chi_prev - (steps[-1]["dof_after"] if steps else dof0), 0.0) / excess0)}


def has_input(eid, inputs) -> bool:
    """Whether effect eid's regressor is anywhere nonzero at the inputs (regressor_inputs): a temperature
    term has none in a recording without temp_c, and is then not worth integrating along the moves."""
    return any(np.any(regressor(eid, u, aux)) for u, aux in inputs)


def regressor_inputs(ms, gm, fit: GyroFit, acc_cal):
    """Inputs of the candidate regressors, (u deg/h, AuxInputs), at every move sample (m, L) and
    at every sample of the initial rest (n,): the calibrated rate, the calibrated specific
    force (acc_cal: the accelerometer's model and parameters, inverted whole) and the samples'
    auxiliary columns (t_s, temp_c, ...)."""
    am, p_a = acc_cal
    mv = gm.mv
    m, L = mv.dt.shape
    idx = np.zeros((m, L), int)
    for i, (a, b) in enumerate(mv.rows):
        idx[i, :b - a] = np.arange(a + 1, b + 1)
    rest = np.arange(gm.rest.start, gm.rest.stop)
    w = ms.gyro_dph() / units.DPH_PER_DPS - gm.bias - fit.db
    out = []
    for ix in (idx, rest):
        columns = columns_at(ms.samples, ix, t_ref_c=ms.t_ref_c)
        flat = AuxInputs({k: np.ravel(v) if np.ndim(v) else v for k, v in columns.items()})
        f = model_inputs(am, p_a, ms.acc_g()[ix].reshape(-1, 3), flat, ms.path / "samples.csv").reshape(ix.shape + (3,))
        out.append((w[ix] @ fit.T.T * units.DPH_PER_DPS, AuxInputs({**columns, **specific_force(f)})))
    return out


def with_terms(mv: Moves, ids, inputs) -> Moves:
    """mv with the regressors of effects ids along the moves and their mean over the rest."""
    (u, aux), (u0, aux0) = inputs
    mask = mv.dt > 0
    phi = np.array([regressor(e, u, aux) * mask / units.DPH_PER_DPS for e in ids]).reshape(len(ids), *mask.shape)
    phi_rest = np.array([np.mean(regressor(e, u0, aux0)) / units.DPH_PER_DPS for e in ids])
    return Moves(mv.y, mv.dt, mv.before, mv.after, mv.t_span, mv.rows, phi, tuple(EFFECTS[e].axis for e in ids),
                 phi_rest)


def _gyro_fit(ms, gm: GyroMoves, acc_cal, gyro_effects, auto):
    """The gyro's fit over the moves with the effects asked for (auto: and those the failing moves
    need, misfit_shares): (fit, {id: EffectValue}, the auto steps or None)."""
    f = fit_gyro(gm.mv, gm.g_dirs, gm.bias_std)
    effects, chosen = {}, None
    if auto and f.converged:
        sigma_g = gyro_noise_dps(ms, gm)
        chi2, dof, p_value = chi2_test(f, move_covariances(gm, f, sigma_g), gm.bias_std, gm.mv)
        if ModelTest(chi2, dof, p_value).fails:
            shares = misfit_shares(gm, f, sigma_g, regressor_inputs(ms, gm, f, acc_cal), chi2, dof)
            chosen = shares["steps"]
            gyro_effects = tuple(dict.fromkeys(tuple(gyro_effects) + tuple(shares["effects"])))
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
        "prior_std": PRIOR_T, "to_determine": f"turn about the {'xyz'[k % 3]} axis by at least 90 deg between two poses"}
        for k in unseen}
    return f, unseen, undetermined, dead


def _gyro_block(ms, det, am, obs, fa, acc_cal, gyro_effects, auto) -> SensorBlock:
    """The gyro's block: T = M^-1 and the bias from the moves, the model (nominal, scale or full)
    chosen by the moves left out, the chi-square of the moves."""
    gm = prepare_moves(ms, det, *pose_directions(am, obs, fa))
    f, effects, chosen = _gyro_fit(ms, gm, acc_cal, gyro_effects, auto)
    f, unseen, undetermined, dead = _hold_unseen(ms, gm, f)
    mv = gm.mv
    gyro_model, f, choice = choose_gyro_model(mv, gm.g_dirs, gm.bias_std, f, unseen)
    fixed = [] if gyro_model == "full" else list(range(9)) if gyro_model == "nominal" else list(GYRO_MODELS["scale"])
    if gyro_model != "full":
        undetermined = {k: v for k, v in undetermined.items() if "xyz".index(k[2]) * 4 not in fixed
                        and "xyz".index(k[2]) == "xyz".index(k[3])}
    chi2, dof, p_value = chi2_test(f, move_covariances(gm, f, gyro_noise_dps(ms, gm)), gm.bias_std, mv)
    if undetermined and dead and p_value is not None and p_value < 1e-6:
        # a quiet output that the held nominal cannot explain: the channel does not respond
        raise CalibrationError(f"{ms.path}: gyro output {', '.join(dead)} hardly changes during the moves, and "
                               f"holding {list(undetermined)} at nominal leaves the moves unexplained (chi2 "
                               f"{chi2:.3g} on {dof} dof): a dead or unconnected channel?")
    to_add = None
    if ModelTest(chi2, dof, p_value).fails and not effects:  # the effects diagnose would add (misfit_shares)
        sigma_g = gyro_noise_dps(ms, gm)
        shares = misfit_shares(gm, f, sigma_g, regressor_inputs(ms, gm, f, acc_cal), chi2, dof, max_terms=1)
        to_add = shares["effects"][0] if shares["effects"] else None
    bias_std = gm.bias_std if gyro_model == "nominal" else np.sqrt(np.diag(f.cov)[9:12])
    std_T = [[None if 3 * i + j in fixed else float(np.sqrt(f.cov[3 * i + j, 3 * i + j])) for j in range(3)]
             for i in range(3)]
    M_g = np.linalg.inv(f.T)
    units.check_scale("gyro", M_g, ms.path / "samples.csv")
    return calibration.affine_block(
        "gyro", M_g, (gm.bias + f.db) * units.DPH_PER_DPS,
        {"T": std_T, "bias": (bias_std * units.DPH_PER_DPS).tolist()},
        float(np.sqrt(np.mean(np.sum(f.r ** 2, 1)))), GYRO_MODEL_TEXT[gyro_model],
        residual_unit="gravity direction (unit vector), per move", effects=effects,
        T=f.T.tolist(), T_note="T = M^-1: the rate in b is T (output - bias - effects)",
        moves=[{"from_pose": int(a), "to_pose": int(b), "t_s": list(span), "residual": ri.tolist()}
               for a, b, span, ri in zip(mv.before, mv.after, mv.t_span, f.r)],
        moves_used=int(len(f.r)), moves_skipped=gm.skipped, saturation=gm.saturation,
        moves_opposite_sense=gm.flipped, iterations=f.iterations, chi2=chi2, dof=dof, p_value=p_value,
        test="chi-square of the moves against the rests' white noise (simucal diagnose shows them)",
        std_note="stds scale with the moves' own residual scatter, so they include any misfit",
        undetermined=undetermined, gyro_model=gyro_model, model_choice=choice, advice=to_add,
        **({"auto": chosen or []} if auto else {}))


def calibrate_handheld(ms, acc_model="acc_baseline", detect=None, pose_window_s=1.0, gyro_effects=(),
                       auto=False) -> Calibration:
    """pose_window_s: seconds at the start of each static interval averaged into the
    pose (None: the whole interval). Hand-placed poses creep: on imu_tk's Xsens
    session the baseline's chi2 falls from 472 to 141 (29 dof) when only the first
    second is used, which is also imu_tk's convention (100 samples).
    gyro_effects: candidate ids fit with T and the bias over the moves."""
    obs, det, am, fa, tau = acc_from_poses(ms, acc_model, detect, pose_window_s)
    if auto:  # the library effects the failing poses need (candidates.forward_selection)
        acc_auto = forward_selection(am, obs)
        if acc_auto.steps:
            obs, det, am, fa, tau = acc_from_poses(ms, acc_auto.model, detect, pose_window_s)
    M_a, b_a = am.matrix_and_bias(fa.vector(am.params))
    units.check_scale("acc", M_a, ms.path / "samples.csv")
    cal = calibration.header("handheld (Tedaldi): exact norm fit + gyro moves", ms)
    cal.details["static_detection"] = {**det.as_dict(ms.samples["t_s"]), "pose_window_s": pose_window_s}
    cal.acc = calibration.sensor_block(am, fa, M_a, b_a)
    cal.acc.details.update(undetermined=fa.undetermined, model_error_std_g=tau, note=None if tau == 0 else (
        "the model does not explain the poses down to their own noise (see chi2, p_value before "
        "the extra variance: simucal diagnose); each pose got an extra variance tau^2 so that "
        "chi2/dof = 1, and the stds include it"))
    if auto:
        cal.acc.details.update(auto=acc_auto.steps, auto_stopped=acc_auto.stopped)
    if cal.acc.verdict == "fails" and not fa.undetermined:
        cal.acc.details["advice"] = advice(am, obs)  # what diagnose names for the poses (its fit has no prior)
    if ms.has_gyro:
        cal.gyro = _gyro_block(ms, det, am, obs, fa, (am, fa.vector(am.params)), gyro_effects, auto)
    return cal
