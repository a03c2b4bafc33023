"""Calibration of a hand-placed session (Tedaldi et al. 2014, as in imu_tk).

A continuous stream of a unit put by hand in many static poses:
- static poses found by static_detect (threshold from the initial rest);
- accelerometer: the exact norm fit (norm_fit.fit_exact) on the pose means,
  any generated model, started from the closed-form quadric for raw offsets;
- gyro: bias from the initial rest (a prior, refined with the moves); T = M_g^-1 (full 3x3: scale factors,
  misalignment and the rotation between the triads, so omega is in the
  accelerometer frame b) from the moves between consecutive poses: integrate
  omega_k = T (y_k - b_g) over the move and ask that the gravity direction the
  calibrated accelerometer sees after the move equal the one before, rotated:
      r_i = g_{i+1} - R_i(T)^T g_i.
  R_i = prod_k exp([omega_k dt x]); a right perturbation gives the Jacobian
  d(phi_i) = sum_k A_k^T J_r(omega_k dt) d(omega_k) dt with A_k the product of
  the later steps and J_r the right Jacobian of SO(3), and
  d(r_i) = -[g_pred x] d(phi_i).
Moves holding saturated samples are left out and named; moves whose rotation
sense contradicts the accelerometers (wrong sign, rate or axes) are refused.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import units
from .augmented import AugmentedModel
from .norm_fit import CalibrationError, Observations, fit_exact, initial_directions
from .generated import moves as gen_moves
from .rotations import skew
from .static_detect import Detection, detect_static


@dataclass
class Moves:
    y: np.ndarray        # (3, m, L) bias-free gyro outputs (deg/s), zero-padded
    dt: np.ndarray       # (m, L) sample intervals, 0 on padding
    before: np.ndarray   # (m,) index of the pose before
    after: np.ndarray    # (m,) index of the pose after
    t_span: list = None  # (m,) (start, end) times (s)


def saturated_rows(raw, full_scale=None, min_run=3):
    """Rows at or beyond full scale; without it, rows equal to a column's extreme
    in a run of min_run or more (a clipped sensor repeats its rail; two equal
    extremes of quantised noise are common, three are not)."""
    bad = np.zeros(len(raw), bool)
    report = []
    for j in range(raw.shape[1]):
        col = raw[:, j]
        if full_scale is not None:
            hit = (col <= full_scale[0]) | (col >= full_scale[1])
        else:
            hit = np.zeros(len(col), bool)
            for ext in (col.min(), col.max()):
                eq = (col == ext).astype(int)
                edges = np.diff(np.r_[0, eq, 0])
                for a, b in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]):
                    if b - a >= min_run:
                        hit[a:b] = True
        if hit.any():
            report.append({"axis": "xyz"[j], "count": int(hit.sum()), "first_row": int(np.argmax(hit))})
        bad |= hit
    return bad, report


def build_moves(w, t, det: Detection, bias, bad):
    idx, skipped = [], []
    for i in range(len(det.starts) - 1):
        a, b = det.ends[i] - 1, det.starts[i + 1]
        if bad[a:b + 1].any():
            skipped.append({"from_pose": i, "to_pose": i + 1, "t_s": [float(t[a]), float(t[b])],
                            "reason": "saturated samples in the move"})
            continue
        idx.append((i, a, b))
    if not idx:
        raise CalibrationError("every move between poses holds saturated gyro samples: nothing left to fit the gyro")
    L = max(b - a for _, a, b in idx)
    y = np.zeros((3, len(idx), L))
    dt = np.zeros((len(idx), L))
    for m, (i, a, b) in enumerate(idx):
        y[:, m, :b - a] = (w[a + 1:b + 1] - bias).T
        dt[m, :b - a] = np.diff(t[a:b + 1])
    return Moves(y, dt, np.array([i for i, _, _ in idx]), np.array([i + 1 for i, _, _ in idx]),
                 [(float(t[a]), float(t[b])) for _, a, b in idx]), skipped


def prefix_products(Q):
    """Q[:, m, k] <- Q[:, m, 0] (x) ... (x) Q[:, m, k], in place: a work-efficient
    (Blelloch) scan, about 2 L products in 2 log2(L) vectorised steps."""
    n, d = Q.shape[-1], 1
    while 2 * d <= n:  # up-sweep: Q[i] <- product over (i - 2d, i] at i = 2d-1, 4d-1, ...
        Q[..., 2 * d - 1::2 * d] = gen_moves.quaternion_product(Q[..., d - 1:n - d:2 * d], Q[..., 2 * d - 1::2 * d])
        d *= 2
    while d > 1:  # down-sweep: the complete prefixes at 2d-1, 4d-1, ... fill in the halves between
        d //= 2
        Q[..., 3 * d - 1::2 * d] = gen_moves.quaternion_product(Q[..., 2 * d - 1:n - d:2 * d], Q[..., 3 * d - 1::2 * d])
    return Q


def total_products(Q):
    """Q[:, m, 0] (x) ... (x) Q[:, m, -1] by pairwise halving (order kept)."""
    while Q.shape[-1] > 1:
        if Q.shape[-1] % 2:
            Q = np.concatenate([Q, np.eye(4)[:, :1, None] * np.ones(Q.shape[1:-1] + (1,))], -1)
        Q = gen_moves.quaternion_product(Q[..., 0::2], Q[..., 1::2])
    return Q[..., 0]


def move_residuals(T, mv: Moves, g_dirs, jac=True, db=None):
    """r (m, 3) and dr/d[vec(T), db] (m, 3, 12) of Tedaldi's cost (derive/moves.py); omega =
    T (y - db) in deg/s, y the outputs less the rest bias, db a correction to that bias."""
    y = mv.y if db is None else mv.y - db[:, None, None] * (mv.dt > 0)
    v = np.einsum("ab,bmk->amk", T, y) * (np.radians(1.0) * mv.dt)
    Q = gen_moves.step_quaternion(v)
    Q_end = total_products(Q) if not jac else prefix_products(Q)[..., -1]
    Rt = np.moveaxis(gen_moves.rotation_matrix(Q_end), -1, 0).swapaxes(1, 2)  # (m, 3, 3): R_i^T
    pred = np.einsum("mab,mb->ma", Rt, g_dirs[mv.before])
    r = g_dirs[mv.after] - pred
    if not jac:
        return r, None
    m, L = mv.dt.shape
    W = gen_moves.integration_jacobian(Q, v, mv.dt).reshape(9, m, L).transpose(1, 0, 2)  # (m, 9, L)
    dphi_T = Rt @ (W @ y.transpose(1, 2, 0)).reshape(m, 3, 9)  # sum_k W_k (x) y_k
    dphi_b = -Rt @ W.sum(2).reshape(m, 3, 3) @ T
    dphi = np.concatenate([dphi_T, dphi_b], axis=2) * np.radians(1.0)
    return r, -np.matmul(skew(pred), dphi)


def fit_gyro_moves(mv: Moves, g_dirs, T0, bias_std, max_iter=30, db0=None, step_tol=1e-3, offset=0.0):
    """Gauss-Newton on vec(T) and a bias correction db, the rest's bias entering as
    a prior with its standard error bias_std (deg/s): the moves inform the bias too.
    The direction noise sigma_r is the moves' residual rms (re-estimated each step).
    offset is added to the residuals (a coarse level's defect, see calibrate_handheld).

    Converged when no step exceeds step_tol of its parameter's std: that step is
    taken and only the residual recomputed, the Jacobian of the point before serving
    the covariance (it differs by ~step_tol). Returns (T, db, r, cov, iterations, converged)."""
    x = np.r_[np.ravel(T0), np.zeros(3) if db0 is None else db0]
    prior = np.c_[np.zeros((3, 9)), np.diag(1 / bias_std)]

    def evaluate(x, jac=True):
        r, J = move_residuals(x[:9].reshape(3, 3), mv, g_dirs, jac, db=x[9:])
        return r + offset, J

    def system(x, r, J, s_r):
        return np.vstack([J.reshape(-1, 12) / s_r, prior]), np.r_[r.ravel() / s_r, x[9:] / bias_std]

    r, J = evaluate(x)
    converged = False
    for it in range(1, max_iter + 1):
        s_r = max(float(np.sqrt(np.mean(r ** 2))), 1e-12)
        A, e = system(x, r, J, s_r)
        step = np.linalg.lstsq(A, -e, rcond=None)[0]
        if np.all(np.abs(step) < step_tol * np.sqrt(np.diag(np.linalg.pinv(A.T @ A)))):
            x = x + step
            r = evaluate(x, jac=False)[0]
            converged = True
            break
        cost, lam = float(e @ e), 1.0
        while True:  # step halving; GN steps near the optimum are taken whole
            x_new = x + lam * step
            r_new, J_new = evaluate(x_new)
            e_new = system(x_new, r_new, J_new, s_r)[1]
            if e_new @ e_new <= cost or lam < 1e-4:
                break
            lam /= 2
        x, r, J = x_new, r_new, J_new
    # each residual joins two unit vectors, so it has 2 degrees of freedom, not 3
    s_r = float(np.sqrt(np.sum(r ** 2) / max(2 * len(r) - 12, 1)))
    A = system(x, r, J, s_r)[0]
    return x[:9].reshape(3, 3), x[9:], r, np.linalg.pinv(A.T @ A), it, converged


def decimate(mv: Moves, k: int) -> Moves:
    """Moves with k samples per step (block means of the rate, summed dt): cheaper
    iterations whose composition error (~1e-3 rad) the full-resolution steps remove."""
    m, L = mv.dt.shape
    n = -(-L // k) * k
    y = np.zeros((3, m, n))
    dt = np.zeros((m, n))
    y[..., :L], dt[:, :L] = mv.y * mv.dt, mv.dt
    dt_b = dt.reshape(m, n // k, k).sum(2)
    y_b = y.reshape(3, m, n // k, k).sum(3) / np.where(dt_b > 0, dt_b, 1.0)
    return Moves(y_b, dt_b, mv.before, mv.after, mv.t_span)


def check_rotation_sense(mv: Moves, g_dirs, T0):
    """Refuse a gyro whose rotations turn gravity the wrong way (sign, axes, rate)."""
    r_pos, _ = move_residuals(T0, mv, g_dirs, jac=False)
    r_neg, _ = move_residuals(-T0, mv, g_dirs, jac=False)
    good, bad = np.linalg.norm(r_pos, axis=1), np.linalg.norm(r_neg, axis=1)
    flipped = bad < 0.5 * good
    if flipped.mean() > 0.5:
        raise CalibrationError(
            f"{int(flipped.sum())} of {len(flipped)} moves turn gravity opposite to what the gyro says: the gyro's "
            "rotation sense contradicts the accelerometers (sign convention, axes or sample rate wrong); "
            "not fitted, since it would give a gyro matrix near -I")
    return [int(i) for i in np.nonzero(flipped)[0]]


def with_model_error(model, obs: Observations, fit, alpha=0.01):
    """When chi2 rejects the model, give every pose an extra variance tau^2 (the
    same on all axes) with chi2/dof = 1 and refit: the weights then reflect what
    the model misses, not only the noise within a pose, and the stds grow to match."""
    if fit.p_value is None or fit.p_value >= alpha or fit.dof <= 0:
        return fit, 0.0
    r2, s2 = fit.residuals ** 2, obs.sigma ** 2
    lo, hi = 0.0, float(np.max(r2)) * 10
    for _ in range(60):  # bisection on tau^2: sum r^2 / (s^2 + tau^2) = dof
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if np.sum(r2 / (s2 + mid)) > fit.dof else (lo, mid)
    tau2 = (lo + hi) / 2
    obs2 = Observations(obs.N, obs.rho, np.sqrt(s2 + tau2), obs.temp_c, obs.t_s, obs.labels, obs.extra)
    refit = fit_exact(model, obs2, p0=fit.vector(model.params))
    refit.chi2, refit.p_value = fit.chi2, fit.p_value  # the test is the one without the extra variance
    return refit, float(np.sqrt(tau2))


def pose_observations(ms, detect_kw=None, pose_window_s=1.0):
    """Accelerometer observations of a stream's static poses: (Observations, Detection, poses).

    Each pose is the mean of its first pose_window_s (None: the whole interval),
    with the std of that mean from the scatter of its samples."""
    t = ms.samples["t_s"]
    acc = ms.acc_g()
    det = detect_static(acc, t, **(detect_kw or {}))
    dt = float(np.median(np.diff(t)))
    win = None if pose_window_s is None else max(int(round(pose_window_s / dt)), 2)
    poses = [(a, b if win is None else min(a + win, b)) for a, b in zip(det.starts, det.ends)]
    N = np.array([acc[a:b].mean(0) for a, b in poses])
    sig = np.array([acc[a:b].std(0, ddof=1) / np.sqrt(b - a) for a, b in poses])
    temp = (np.array([ms.samples["temp_c"][a:b].mean() for a, b in poses]) if "temp_c" in ms.samples else 0.0)
    obs = Observations(N, np.ones(len(N)), np.maximum(sig, 1e-12), temp,
                       np.array([t[a:b].mean() for a, b in poses]), list(range(len(poses))))
    return obs, det, poses


def calibrate_handheld(ms, acc_model="acc_baseline", detect_kw=None, pose_window_s=1.0) -> dict:
    """pose_window_s: seconds at the start of each static interval averaged into the
    pose (None: the whole interval). Hand-placed poses creep: on imu_tk's Xsens
    session the baseline's chi2 falls from 472 to 141 (29 dof) when only the first
    second is used, which is also imu_tk's convention (100 samples)."""
    if not ms.has_acc:
        raise CalibrationError(f"{ms.path}: a hand-placed session needs accelerometer data")
    t = ms.samples["t_s"]
    obs, det, _ = pose_observations(ms, detect_kw, pose_window_s)
    units.check_magnitude("acc", np.linalg.norm(obs.N, axis=1), obs.rho, ms.path / "samples.csv", ms.meta)
    am = AugmentedModel(acc_model)
    fa = fit_exact(am, obs)
    fa, tau = with_model_error(am, obs, fa)
    M_a, b_a = am.matrix_and_bias(fa.vector(am.params))
    units.check_scale("acc", M_a, ms.path / "samples.csv")
    result = {"format": "simucal.calibration/1", "method": "handheld (Tedaldi): exact norm fit + gyro moves",
              "static_detection": {**det.as_dict(t), "pose_window_s": pose_window_s},
              "acc": {"M": M_a.tolist(), "bias": b_a.tolist(), "bias_unit": "g", "model": am.name,
                      "params": fa.params, "std": fa.std, "residual_rms": fa.residual_rms, "chi2": fa.chi2,
                      "dof": fa.dof, "p_value": fa.p_value, "model_error_std_g": tau,
                      "note": None if tau == 0 else (
                          "the model does not explain the poses down to their own noise (see chi2, p_value before "
                          "the extra variance: simucal diagnose); each pose got an extra variance tau^2 so that "
                          "chi2/dof = 1, and the stds include it")}}
    if ms.has_gyro:
        w = ms.gyro_dph() / 3600.0  # deg/s
        # the first static interval, trimmed by half a window: a centred window sees
        # the start of a move half a window late
        rest = slice(det.starts[0] + det.window // 2, det.ends[0] - det.window // 2)
        bias = w[rest].mean(0)
        raw = np.column_stack([ms.samples[c] for c in ("gx", "gy", "gz")])
        fs = ms.meta.get("full_scale", {}).get("gyro")
        bad, sat = saturated_rows(raw, fs)
        mv, skipped = build_moves(w, t, det, bias, bad)
        g_dirs = initial_directions(am, obs, fa.vector(am.params))  # the calibrated pose means, normalised
        flipped = check_rotation_sense(decimate(mv, 4), g_dirs, np.eye(3))  # a sign question: coarse moves suffice
        bias_std = w[rest].std(0, ddof=1) / np.sqrt(rest.stop - rest.start)
        bias_std = np.maximum(bias_std, 1e-9)
        # Coarse to fine; only the full-resolution fixed point is reported. Moves in blocks
        # of 16 samples get near it; blocks of 4, with their defect against the full
        # resolution at that point added (defect correction), get close enough that
        # one full-resolution Jacobian usually suffices.
        T, db, *_ = fit_gyro_moves(decimate(mv, 16), g_dirs, np.eye(3), bias_std)
        mv4 = decimate(mv, 4)
        defect = (move_residuals(T, mv, g_dirs, jac=False, db=db)[0]
                  - move_residuals(T, mv4, g_dirs, jac=False, db=db)[0])
        T, db, *_ = fit_gyro_moves(mv4, g_dirs, T, bias_std, db0=db, offset=defect)
        T, db, r, cov, it, converged = fit_gyro_moves(mv, g_dirs, T, bias_std, db0=db)
        if not converged:
            raise CalibrationError(f"{ms.path}: the gyro fit over the moves did not converge in {it} Gauss-Newton "
                                   "steps; look at the moves (simucal diagnose) for ones the model cannot follow")
        bias = bias + db
        bias_std = np.sqrt(np.diag(cov)[9:])
        M_g = np.linalg.inv(T)
        units.check_scale("gyro", M_g, ms.path / "samples.csv")
        result["gyro"] = {"M": M_g.tolist(), "bias": (bias * 3600).tolist(), "bias_unit": "deg/h",
                          "model": "full 3x3 M (scale, misalignment, triad rotation), bias from the initial rest",
                          "T": T.tolist(), "std": {"T": np.sqrt(np.diag(cov)[:9]).reshape(3, 3).tolist(),
                                                   "bias": (bias_std * 3600).tolist()},
                          "residual_rms": float(np.sqrt(np.mean(np.sum(r ** 2, 1)))),
                          "moves": [{"from_pose": int(a), "to_pose": int(b), "t_s": list(span), "residual": ri.tolist()}
                                    for a, b, span, ri in zip(mv.before, mv.after, mv.t_span, r)],
                          "residual_unit": "gravity direction (unit vector), per move",
                          "moves_used": int(len(r)), "moves_skipped": skipped, "saturation": sat,
                          "moves_opposite_sense": flipped, "iterations": it}
    result["residual_rms"] = {s: result[s]["residual_rms"] for s in ("acc", "gyro") if s in result}
    return result
