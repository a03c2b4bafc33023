"""A hand-placed session's gyro moves prepared from the stream, and their model test (Tedaldi et al.
2014, as in imu_tk; calibrate and diagnose share it).

- GyroMoves: the moves' samples (moves.build_moves), the poses' calibrated gravity directions with
  their variances (pose_directions), the bias and its std from the initial rest;
- the test: each move's residual covariance S_i from the rests' white noise integrated over the move
  and the two poses' direction variances (move_covariances), chi2 = sum r_i^T S_i^+ r_i plus the
  bias prior (chi2_test; handheld/diagnose_moves.py gives the derivation);
- candidate effects along the moves: their inputs at every move sample (regressor_inputs), their
  regressors there evaluated once (regressors) and integrated into the moves (with_terms).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from simucal.fit.augmented import regressor
from simucal.fit.apply import model_inputs
from simucal.fit.aux_inputs import AuxInputs, columns_at, specific_force
from simucal.fit.distributions import chi2_sf
from simucal.fit.noise import moving_sample_var, quantization_step
from simucal.fit.norm_fit import full_covariance
from simucal.fit.rotations import skew
from simucal.generated.effects import EFFECTS
from simucal.handheld.moves import GyroFit, Moves, build_moves, check_rotation_sense, decimate
from simucal.handheld.static_detect import Detection
from simucal.io import units
from simucal.io.sensor_checks import saturated_rows


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
    w = ms.gyro_dph() / units.DPH_PER_DPS
    return np.sqrt(moving_sample_var(w[gm.rest], w))


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
        assert mv.phi_rest is not None  # with_terms gives phi_rest with phi_axes
        rest[axis] += fit.p[j] * mv.phi_rest[j]
    chi2 += float(np.sum((rest / bias_std) ** 2))
    # 2 per move, 3 for the rest's reading where the moves estimate the bias, less what they estimate: the
    # entries with a variance (a simpler gyro model's fixed entries of T have none, nominal's bias neither)
    estimated = np.diag(fit.cov) > 0
    dof = 2 * len(fit.r) + 3 * bool(estimated[9:12].any()) - int(estimated.sum())
    return chi2, dof, float(chi2_sf(chi2, dof)) if dof > 0 else None


class RegressorInputs(NamedTuple):
    """The candidate regressors' inputs (regressor_inputs): (u deg/h, AuxInputs) along the moves (m, L) and at
    the initial rest (n,), with each effect's regressors there once evaluated (`regressors`): a ranking, its
    trial fits and each step of --add auto ask for the same effects again at the same inputs."""
    moves: tuple
    rest: tuple
    evaluated: dict


def regressors(eid, inputs: RegressorInputs) -> tuple[np.ndarray, np.ndarray]:
    """Effect eid's regressor along the moves (m, L) and at the rest (n,), evaluated once per inputs."""
    if eid not in inputs.evaluated:
        inputs.evaluated[eid] = tuple(regressor(eid, u, aux) for u, aux in (inputs.moves, inputs.rest))
    return inputs.evaluated[eid]


def has_input(eid, inputs: RegressorInputs) -> bool:
    """Whether effect eid's regressor is anywhere nonzero at the inputs (regressor_inputs): a temperature
    term has none in a recording without temp_c, and is then not worth integrating along the moves."""
    return any(np.any(phi) for phi in regressors(eid, inputs))


def regressor_inputs(ms, gm, fit: GyroFit, acc_cal) -> RegressorInputs:
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
    return RegressorInputs(out[0], out[1], {})


def with_terms(mv: Moves, ids, inputs: RegressorInputs) -> Moves:
    """mv with the regressors of effects ids along the moves and their mean over the rest."""
    mask = mv.dt > 0
    phi = np.array([regressors(e, inputs)[0] * mask / units.DPH_PER_DPS for e in ids]).reshape(len(ids), *mask.shape)
    phi_rest = np.array([np.mean(regressors(e, inputs)[1]) / units.DPH_PER_DPS for e in ids])
    return Moves(mv.y, mv.dt, mv.before, mv.after, mv.t_span, mv.rows, phi, tuple(EFFECTS[e].axis for e in ids),
                 phi_rest)


def with_term_added(mv: Moves, eid, inputs) -> Moves:
    """mv (with_terms' of some effects, or none) with effect eid's regressor after theirs: theirs not evaluated
    again (a ranking's every candidate is tried beside the same effects)."""
    if not mv.n_terms:
        return with_terms(mv, [eid], inputs)
    assert mv.phi is not None and mv.phi_rest is not None  # with_terms gives them with phi_axes
    one = with_terms(mv, [eid], inputs)
    return Moves(mv.y, mv.dt, mv.before, mv.after, mv.t_span, mv.rows, np.concatenate([mv.phi, one.phi]),
                 mv.phi_axes + one.phi_axes, np.r_[mv.phi_rest, one.phi_rest])
