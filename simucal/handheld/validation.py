"""`simucal validate`'s checks on a stream (a hand-placed session): |f| = 1 g at each static pose,
and each move's gravity direction after the move predicted by the integrated gyro against the one
the calibrated accelerometers measure (Tedaldi's cost; handheld/moves.py), as an angle in deg.

Both arms take the gyro's bias from this session's initial rest: a MEMS gyro's turn-on bias changes
with every power-up, so no calibration can carry it, and the check is of what it can carry (T: the
scale factors and misalignments). Both use the calibrated accelerometers' directions. The stream's
time stamps are read as the calibration read its own (api/validating.py: io/timestamps.with_timestamps).

The moves' floor, per move, is what the angle would be if T were exact (rad^2, summed over the two
components across gravity, 2/3 of the angle's): the rest's white gyro noise sigma_g (at least its
quantisation's) integrated over the move,
|sigma_g|^2 sum dt^2; the rest bias's own error over the move's length, |sigma_g|^2 / n_rest (sum dt)^2
(q^2/12 where the noise is below the quantum q: a quiet rest's mean keeps its rounding);
the two poses' directions: each pose mean's noise across gravity (2 sigma_pose^2) and the
accelerometer calibration's uncertainty propagated to its direction (fit/validation.direction_var);
and the gyro calibration's own uncertainty over the move's rotation (_gyro_cal_var).
The check's floor_rms is the rms of their square roots (the shared pieces: fit/validation.py)."""
from __future__ import annotations

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.noise import quantization_step, white_noise_var
from simucal.fit.validation import (FLOOR, CheckRecord, direction_var, input_change, norm_block, rms, segment_means,
                                    with_calibration)
from simucal.handheld.moves import build_moves, move_residuals
from simucal.handheld.static_detect import detect_static
from simucal.io import units
from simucal.io.sensor_checks import saturated_rows


def stream_checks(ms, f_before, f_after, w_before, w_after, cal) -> dict[str, list[CheckRecord]]:
    """{sensor: [check]} of a calibration cal on the stream ms (as turntable/validation.table_checks)."""
    if f_after is None:
        raise CalibrationError(f"{ms.path}: a stream without accelerometers has no reference to validate against")
    t = ms.samples["t_s"]
    det = detect_static(f_after, t, gyro_dps=None if w_before is None else w_before / units.DPH_PER_DPS)
    rest = slice(det.starts[0] + det.window // 2, det.ends[0] - det.window // 2)
    groups = [slice(a, b) for a, b in zip(det.starts, det.ends)]
    (mb, _), (ma, fl) = segment_means(f_before, groups, None), segment_means(f_after, groups, None)
    whole, with_cal = with_calibration(fl, cal, "acc", ma, [np.arange(a, b) for a, b in zip(det.starts, det.ends)], ms)
    out = {"acc": [norm_block("g", np.linalg.norm(mb, axis=1) - 1, np.linalg.norm(ma, axis=1) - 1, whole,
                              f"|f| - 1 g at each of the {len(groups)} static poses" + FLOOR[with_cal],
                              [f"pose at {t[a]:.1f} s" for a in det.starts])]}
    if w_after is not None:
        bad = saturated_rows(ms, "gyro")[0]
        angles = []
        g_dirs = ma / np.linalg.norm(ma, axis=1, keepdims=True)  # the calibrated accelerometers: the gyro's reference
        for w in (w_before, w_after):
            w_dps = w / units.DPH_PER_DPS
            mv, _ = build_moves(w_dps, t, det, w_dps[rest].mean(0), bad)  # both: this session's rest bias
            angles.append(np.degrees(np.linalg.norm(move_residuals(np.eye(3), mv, g_dirs, jac=False)[0], axis=1)))
        floor = np.degrees(np.sqrt(_move_var(w_before / units.DPH_PER_DPS, rest, mv, fl / np.linalg.norm(ma, axis=1),
                                             direction_var(cal, "acc", ma, {}))
                                   + _gyro_cal_var(cal, mv, g_dirs)))
        out["gyro"] = [{"what": "gravity direction after each move: the integrated gyro against the calibrated "
                                "accelerometers (both with the gyro bias from this session's initial rest; floor: the "
                                "gyro's white noise, the rest bias's error and the poses' directions)", "unit": "deg",
                        "n": int(len(angles[1])), "before_rms": rms(angles[0]), "after_rms": rms(angles[1]),
                        "floor_rms": rms(floor)}]
    return out


def _gyro_cal_var(cal, mv, g_dirs) -> np.ndarray:
    """Each move's angle variance (rad^2) from the gyro calibration's own uncertainty: the rotation
    vector's error is dT Phi, Phi the move's integrated calibrated rate (to first order), and only its
    part across gravity turns the predicted direction: sum_i var(dtheta_i) (1 - g_i^2), g the pose
    after. From the stds of T (a stream's calibration: independent entries), else from the file's
    covariance through the model (its biases left out: both arms take the rest's); 0 without either."""
    phi_dps = np.sum(mv.y * np.where(mv.dt > 0, mv.dt, 0.0)[None], axis=2).T  # (m, 3) deg
    std_T = cal.gyro.std.get("T")
    if std_T is not None:
        var_T = np.array([[0.0 if v is None else v ** 2 for v in row] for row in std_T])
        var = phi_dps ** 2 @ var_T.T  # var(dtheta_i) = sum_j var(T_ij) Phi_j^2
    else:
        found = input_change(cal, "gyro", phi_dps * units.DPH_PER_DPS, {})
        if found is None:
            return np.zeros(len(phi_dps))
        _, du, cov, names = found
        keep = np.array([not n.startswith("b_") and "." not in n for n in names])  # T's own: linear in the rate
        du = du[:, :, keep] / units.DPH_PER_DPS  # deg per unit parameter, over the move (du is linear in Phi)
        var = np.einsum("nim,mk,nik->ni", du, cov[np.ix_(keep, keep)], du)
    g = g_dirs[mv.after]
    return np.radians(1.0) ** 2 * np.sum(var * (1 - g ** 2), axis=1)


def _move_var(w_dps, rest, mv, pose_sd, pose_cal_var) -> np.ndarray:
    """Each move's angle variance (rad^2) if T were exact (module doc): w_dps the gyro at its nominal
    scale (deg/s), whose rest gives sigma_g (at least its quantisation's q^2/12: a quiet rest reads
    constant while the moves' samples round by up to q/2, as calibrate's gyro_noise_dps); pose_sd each
    pose mean's noise over its norm (relative), pose_cal_var each pose direction's variance from the
    calibration (None: the file holds no covariance)."""
    white, q2 = white_noise_var(w_dps[rest]), quantization_step(w_dps[rest], w_dps) ** 2 / 12
    across = 2 / 3 * np.radians(1.0) ** 2  # two of the angle's three components turn the gravity direction
    s2 = float(np.sum(np.maximum(white, q2))) * across  # per sample, rad^2/s^2
    # the rest's mean: its white noise averages down where it dithers the rounding, else it keeps q^2/12
    b2 = float(np.sum(np.where(white >= q2, white / (rest.stop - rest.start), q2))) * across
    dt = np.where(mv.dt > 0, mv.dt, 0.0)
    pose = 2 * pose_sd ** 2 + (0.0 if pose_cal_var is None else pose_cal_var)
    return s2 * np.sum(dt ** 2, axis=1) + b2 * np.sum(dt, axis=1) ** 2 + pose[mv.before] + pose[mv.after]
