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

from dataclasses import dataclass, replace

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.augmented import AugmentedModel, effect_ids
from simucal.fit.aux_inputs import (
    SENSOR_AUX,
    AuxInputs,
    column_means,
    columns_at,
    specific_force,
)
from simucal.fit.candidates import ALPHA, forward_selection
from simucal.fit.distributions import chi2_sf, f_sf
from simucal.fit.noise import quantization_step, white_noise_var
from simucal.fit.norm_fit import (
    Observations,
    check_not_coplanar,
    fit_exact,
    full_covariance,
    initial_directions,
)
from simucal.fit.rotations import skew
from simucal.generated import moves as gen_moves
from simucal.generated.effects import EFFECTS
from simucal.handheld.static_detect import Detection, DetectSettings, detect_static
from simucal.io import units
from simucal.io.sensor_checks import saturated_rows


@dataclass
class Moves:
    y: np.ndarray        # (3, m, L) bias-free gyro outputs (deg/s), zero-padded
    dt: np.ndarray       # (m, L) sample intervals, 0 on padding
    before: np.ndarray   # (m,) index of the pose before
    after: np.ndarray    # (m,) index of the pose after
    t_span: list = None  # (m,) (start, end) times (s)
    rows: list = None    # (m,) (a, b): the move integrates stream rows a+1 .. b
    phi: np.ndarray = None  # (q, m, L) regressors of added effects, (deg/s) per unit parameter, 0 on padding
    phi_axes: tuple = ()    # the output axis each one acts on
    phi_rest: np.ndarray = None  # (q,) their mean over the initial rest, which reads b + sum_j p_j e_j phi_j

    @property
    def n_terms(self):
        return len(self.phi_axes)


@dataclass
class GyroFit:
    T: np.ndarray        # omega = T (y - b_rest - db - sum_j p_j e_j phi_j), deg/s
    db: np.ndarray       # correction to the rest's bias (deg/s)
    p: np.ndarray        # parameters of added effects (their own units)
    r: np.ndarray        # (m, 3) gravity-direction residuals
    cov: np.ndarray      # of [vec(T), db, p]
    iterations: int
    converged: bool


UNSEEN_STD = 0.05  # an entry of T (near I) whose std from the moves alone is above this is not determined
PRIOR_T = 0.05     # such an entry is held at nominal with this std: 5 % scale, 50 mrad misalignment
FIXED_STD = 1e-9   # an entry a simpler gyro model leaves out (GYRO_MODELS): at nominal
PRIOR_MISALIGNMENT_RAD = 0.01  # accelerometer misalignments the poses cannot see: held at 0 with this std


def build_moves(w, t, det: Detection, bias, bad):
    """The moves between consecutive poses, leaving out (and naming) those with saturated
    samples or a time gap (samples missing: more than 5 median steps), which no integration
    can bridge. A move runs from the end of one static interval to the start of the next
    (imu_tk's convention). Integrating from the end of the pose's averaging window instead
    takes in the whole rest, whose g-sensitive bias (not in the baseline) then accrues: on
    imu_tk's Xsens session the chi2 grows from 12643 to ~380000 on 65 dof. The gyro samples at
    the detector's edges are quiet (a centred window ends a static interval early), so no
    rotation is lost at a move's start."""
    dt_all = np.diff(t)
    gap = np.r_[False, dt_all > 5 * np.median(dt_all)]  # row k follows a gap
    idx, skipped = [], []
    for i in range(len(det.starts) - 1):
        a, b = det.ends[i] - 1, det.starts[i + 1]
        why = ("saturated samples in the move" if bad[a:b + 1].any() else
               f"a time gap of {dt_all[a:b].max():.3g} s in the move (samples missing)" if gap[a + 1:b + 1].any()
               else None)
        if why:
            skipped.append({"from_pose": i, "to_pose": i + 1, "t_s": [float(t[a]), float(t[b])], "reason": why})
            continue
        idx.append((i, a, b))
    if not idx:
        reasons = sorted({s["reason"].split(" of ")[0] for s in skipped})
        raise CalibrationError(f"every move between poses holds {' or '.join(reasons)}: nothing left to fit the gyro")
    L = max(b - a for _, a, b in idx)
    y = np.zeros((3, len(idx), L))
    dt = np.zeros((len(idx), L))
    for m, (i, a, b) in enumerate(idx):
        y[:, m, :b - a] = (w[a + 1:b + 1] - bias).T
        dt[m, :b - a] = np.diff(t[a:b + 1])
    return Moves(y, dt, np.array([i for i, _, _ in idx]), np.array([i + 1 for i, _, _ in idx]),
                 [(float(t[a]), float(t[b])) for _, a, b in idx], [(a, b) for _, a, b in idx]), skipped


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


def move_residuals(T, mv: Moves, g_dirs, jac=True, db=None, p=None):
    """r (m, 3) and dr/d[vec(T), db, p] (m, 3, 12 + q) of Tedaldi's cost (derive/moves.py);
    omega = T (y - db - sum_j p_j e_j phi_j) in deg/s, y the outputs less the rest bias, db a
    correction to that bias, phi_j the regressor of an added effect on output axis j."""
    y = mv.y if db is None else mv.y - db[:, None, None] * (mv.dt > 0)
    if mv.n_terms:
        y = y - np.einsum("j,ja,jmk->amk", p, np.eye(3)[list(mv.phi_axes)], mv.phi)
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
    cols = [Rt @ (W @ y.transpose(1, 2, 0)).reshape(m, 3, 9),  # sum_k W_k (x) y_k
            -Rt @ W.sum(2).reshape(m, 3, 3) @ T]
    for j, axis in enumerate(mv.phi_axes):
        cols.append(-Rt @ (W @ mv.phi[j][..., None]).reshape(m, 3, 3) @ T[:, axis:axis + 1])
    dphi = np.concatenate(cols, axis=2) * np.radians(1.0)
    return r, -np.matmul(skew(pred), dphi)


def _prior(mv: Moves, n, bias_std, held=(), fixed=()):
    """The prior rows and their targets for x = [vec(T), db, p]: the rest read b_rest = b + sum_j
    p_j e_j phi_j(rest), so db + that sum = 0 +- bias_std; entries `held` of vec(T) at nominal (I)
    with std PRIOR_T (a soft prior), entries `fixed` at nominal (a simpler model: FIXED_STD)."""
    E = np.zeros((3, n - 12))
    if mv.n_terms:
        E[list(mv.phi_axes), np.arange(n - 12)] = mv.phi_rest
    prior = np.c_[np.zeros((3, 9)), np.eye(3), E] / bias_std[:, None]
    target = np.zeros(3)
    for idx, std in ((list(held), PRIOR_T), (list(fixed), FIXED_STD)):
        if idx:
            rows = np.zeros((len(idx), n))
            rows[np.arange(len(idx)), idx] = 1.0 / std
            prior = np.vstack([prior, rows])
            target = np.r_[target, np.eye(3).ravel()[idx] / std]
    return prior, target


def fit_gyro_moves(mv: Moves, g_dirs, x0, bias_std, max_iter=30, step_tol=1e-3, offset=0.0, held=(),
                   fixed=()) -> GyroFit:
    """Gauss-Newton on x = [vec(T), db, p] from x0, the rest's bias entering as a prior
    with its standard error bias_std (deg/s): the moves inform the bias too. The
    direction noise sigma_r is the moves' residual rms (re-estimated each step).
    offset is added to the residuals (a coarse level's defect, see fit_gyro). held, fixed: entries
    of vec(T) near nominal by a prior (_prior).

    Converged when no step exceeds step_tol of its parameter's std: that step is
    taken and only the residual recomputed, the Jacobian of the point before serving
    the covariance (it differs by ~step_tol)."""
    x = np.array(x0, float)
    n = len(x)
    prior, target = _prior(mv, n, bias_std, held, fixed)

    def evaluate(x, jac=True):
        r, J = move_residuals(x[:9].reshape(3, 3), mv, g_dirs, jac, db=x[9:12], p=x[12:])
        return r + offset, J

    def system(x, r, J, s_r):
        return np.vstack([J.reshape(-1, n) / s_r, prior]), np.r_[r.ravel() / s_r, prior @ x - target]

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
    s_r = float(np.sqrt(np.sum(r ** 2) / max(2 * len(r) - n, 1)))
    A = system(x, r, J, s_r)[0]
    return GyroFit(x[:9].reshape(3, 3), x[9:12], x[12:], r, np.linalg.pinv(A.T @ A), it, converged)


def fit_gyro(mv: Moves, g_dirs, bias_std, x0=None, held=(), fixed=()) -> GyroFit:
    """Coarse to fine; only the full-resolution fixed point is reported. Moves in blocks
    of 16 samples get near it; blocks of 4, with their defect against the full
    resolution at that point added (defect correction), get close enough that one
    full-resolution Jacobian usually suffices."""
    x = np.r_[np.ravel(np.eye(3)), np.zeros(3 + mv.n_terms)] if x0 is None else x0
    f = fit_gyro_moves(decimate(mv, 16), g_dirs, x, bias_std, held=held, fixed=fixed)
    x = np.r_[f.T.ravel(), f.db, f.p]
    mv4 = decimate(mv, 4)
    defect = (move_residuals(f.T, mv, g_dirs, jac=False, db=f.db, p=f.p)[0]
              - move_residuals(f.T, mv4, g_dirs, jac=False, db=f.db, p=f.p)[0])
    f = fit_gyro_moves(mv4, g_dirs, x, bias_std, offset=defect, held=held, fixed=fixed)
    return fit_gyro_moves(mv, g_dirs, np.r_[f.T.ravel(), f.db, f.p], bias_std, held=held, fixed=fixed)


RICHER_GAIN = 0.98  # a richer gyro model must predict the moves left out 2 % better than the simpler one
GYRO_MODELS = {"nominal": None, "scale": (1, 2, 3, 5, 6, 7), "full": ()}  # entries of vec(T) fixed at nominal
GYRO_MODEL_TEXT = {
    "nominal": "nominal scale factors (T = I; std null: not estimated), bias from the initial rest: the moves do not "
               "support more (model_choice)",
    "scale": "scale factors only (T diagonal; off-diagonal std null: not estimated), bias from the initial rest refined "
             "by the moves: the moves do not support a full matrix (model_choice)",
    "full": "full 3x3 M (scale, misalignment, triad rotation), bias from the initial rest, effects over the moves"}


def held_out_moves(mv: Moves, g_dirs, f: GyroFit, bias_std, held=(), fixed=()) -> np.ndarray:
    """Each move's gravity-direction residual (rad, ~ the angle) predicted by the fit without that
    move: the leave-one-out identity of the Gauss-Newton step at the optimum, r_(k) = (I - H_kk)^-1 r_k
    with H_kk = A_k (A^T A)^-1 A_k^T the move's block of the hat matrix (the prior rows stay in A)."""
    r, J = move_residuals(f.T, mv, g_dirs, db=f.db, p=f.p)
    n = J.shape[-1]
    prior = _prior(mv, n, bias_std, held, fixed)[0]
    s_r = max(float(np.sqrt(np.mean(r ** 2))), 1e-12)
    B = np.linalg.pinv(np.vstack([J.reshape(-1, n) / s_r, prior]).T @ np.vstack([J.reshape(-1, n) / s_r, prior]))
    H = np.einsum("mai,ij,mbj->mab", J / s_r, B, J / s_r)
    return np.linalg.norm(np.linalg.solve(np.eye(3) - H, r[..., None])[..., 0], axis=1)


def _rms_deg(angles_rad):
    return float(np.degrees(np.sqrt(np.mean(np.asarray(angles_rad) ** 2))))


def choose_gyro_model(mv: Moves, g_dirs, bias_std, f_full: GyroFit, held=()) -> tuple[str, GyroFit, dict]:
    """The gyro's T by what the moves support, judged on moves left out (issue: a full matrix from
    few moves can be worse than the nominal one): nominal (T = I, the rest's bias), scale factors
    only, or the full 3x3. The one whose left-out moves are predicted best is taken (a richer one only
    where its held-out rms is below the simpler one's by more than RICHER_GAIN), so the chosen
    model's held-out error is never above the nominal's. The table also gives the paired test's p
    (cross_validation.paired_improvement) of each against the model before it. Returns (name, its
    fit, the table)."""
    from simucal.fit.cross_validation import paired_improvement
    nominal = GyroFit(np.eye(3), np.zeros(3), f_full.p * 0, move_residuals(np.eye(3), mv, g_dirs, jac=False,
                      db=np.zeros(3), p=f_full.p * 0)[0], np.zeros_like(f_full.cov), 0, True)
    fits = {"nominal": (nominal, np.linalg.norm(nominal.r, axis=1))}
    x0 = np.r_[f_full.T.ravel(), f_full.db, f_full.p]
    held_diag = [k for k in held if k not in GYRO_MODELS["scale"]]
    scale = fit_gyro(mv, g_dirs, bias_std, x0, held=held_diag, fixed=GYRO_MODELS["scale"])
    fits["scale"] = (scale, held_out_moves(mv, g_dirs, scale, bias_std, held_diag, GYRO_MODELS["scale"]))
    fits["full"] = (f_full, held_out_moves(mv, g_dirs, f_full, bias_std, held=held))
    chosen, table = "nominal", {}
    for name, (fit, held_out) in fits.items():
        table[name] = {"held_out_rms_deg": _rms_deg(held_out), "in_sample_rms_deg": _rms_deg(np.linalg.norm(fit.r, axis=1))}
        if name != "nominal":
            table[name].update(compared_with=chosen, p_better=paired_improvement({"held_out": fits[chosen][1]},
                                                                                  {"held_out": held_out}))
            if fit.converged and table[name]["held_out_rms_deg"] < RICHER_GAIN * table[chosen]["held_out_rms_deg"]:
                chosen = name
    return chosen, fits[chosen][0], table


def decimate(mv: Moves, k: int) -> Moves:
    """Moves with k samples per step (block means of the rate, summed dt): cheaper
    iterations whose composition error (~1e-3 rad) the full-resolution steps remove."""
    m, L = mv.dt.shape
    n = -(-L // k) * k
    dt = np.zeros((m, n))
    dt[:, :L] = mv.dt
    dt_b = dt.reshape(m, n // k, k).sum(2)

    def block_means(z):  # rate-like (..., m, L): dt-weighted means over the blocks
        out = np.zeros(z.shape[:-1] + (n,))
        out[..., :L] = z * mv.dt
        return out.reshape(z.shape[:-1] + (n // k, k)).sum(-1) / np.where(dt_b > 0, dt_b, 1.0)

    return Moves(block_means(mv.y), dt_b, mv.before, mv.after, mv.t_span, mv.rows,
                 None if mv.phi is None else block_means(mv.phi), mv.phi_axes, mv.phi_rest)


def _wiring_faults() -> dict:
    """{fault: W}: the recorded gyro rates times W turn gravity as the recorded accelerometers
    see it. A gyro column reversed is W = D_k (diag with -1 at k), two gyro columns swapped the
    permutation P; an accelerometer column reversed or two swapped reflect the gravity
    directions instead, D R D = R(-D w), so W = -D_k or -P."""
    out = {}
    for k, a in enumerate("xyz"):
        D = np.diag([-1.0 if j == k else 1.0 for j in range(3)])
        out[f"g{a} reversed, the gyro's {a} column with its sign flipped"] = D
        out[f"a{a} reversed, the accelerometer's {a} column with its sign flipped"] = -D
    for i, j in ((0, 1), (0, 2), (1, 2)):
        P = np.eye(3)[[j if k == i else i if k == j else k for k in range(3)]]
        ai, aj = "xyz"[i], "xyz"[j]
        out[f"g{ai} and g{aj} swapped, the gyro's columns"] = P
        out[f"a{ai} and a{aj} swapped, the accelerometer's columns"] = -P
    return out


WIRING_FAULTS = _wiring_faults()


def check_rotation_sense(mv: Moves, g_dirs, T0):
    """Refuse a gyro whose rotations turn gravity the wrong way (sign, axes, rate), by a
    unit mix-up's factor (units.UNIT_MIXUPS: deg/s read as rad/s, ...), or only once a column
    is reversed or two are swapped (WIRING_FAULTS): the norm fits cannot see those."""
    r_pos, _ = move_residuals(T0, mv, g_dirs, jac=False)
    r_neg, _ = move_residuals(-T0, mv, g_dirs, jac=False)
    good, bad = np.linalg.norm(r_pos, axis=1), np.linalg.norm(r_neg, axis=1)
    for name, ratio in units.UNIT_MIXUPS["gyro"].items():
        mixed = np.linalg.norm(move_residuals(T0 / ratio, mv, g_dirs, jac=False)[0], axis=1)
        if np.median(mixed) < 0.3 * np.median(good) and np.median(mixed) < 0.3 * np.median(bad):
            raise CalibrationError(
                f"the gyro's rates are {ratio:.4g} times the rotations that turn gravity between the poses: the ratio "
                f"matches {name}; check gyro_unit and the nominal scale factors in meta.json")
    wiring = min(((name, np.median(np.linalg.norm(move_residuals(T0 @ W, mv, g_dirs, jac=False)[0], axis=1)))
                  for name, W in WIRING_FAULTS.items()), key=lambda kv: kv[1])
    if wiring[1] < 0.3 * np.median(good) and wiring[1] < 0.3 * np.median(bad):
        raise CalibrationError(
            f"the gyro's rotations turn gravity between the poses as the accelerometers see it only with {wiring[0]} "
            f": median move error {np.degrees(wiring[1]):.2g} deg, against {np.degrees(np.median(good)):.2g} deg as "
            "recorded; fix that column in samples.csv (or the wiring, or the column mapping) and calibrate again")
    flipped = bad < 0.5 * good
    if flipped.mean() > 0.5:
        raise CalibrationError(
            f"{int(flipped.sum())} of {len(flipped)} moves turn gravity opposite to what the gyro says: the gyro's "
            "rotation sense contradicts the accelerometers (sign convention, axes or sample rate wrong); "
            "not fitted, since it would give a gyro matrix near -I")
    return [int(i) for i in np.nonzero(flipped)[0]]


def with_model_error(model, obs: Observations, fit, prior=None, alpha=0.01):
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
    obs2 = replace(obs, sigma=np.sqrt(s2 + tau2))
    refit = fit_exact(model, obs2, p0=fit.vector(model.params), prior=prior)
    refit.chi2, refit.p_value = fit.chi2, fit.p_value  # the test is the one without the extra variance
    return refit, float(np.sqrt(tau2))


def swapped_or_still(ms, obs, poses):
    """Refuse poses whose gravity directions barely differ: accelerometer and gyro columns
    swapped (the gyro's pose means then spread instead), or a session that never turned."""
    spread = float(np.sqrt(np.trace(np.atleast_2d(np.cov(obs.N.T)))))  # g
    if spread > 0.2:
        return
    detail = (f"the {len(obs.N)} poses' accelerometer means differ by {spread:.2g} g rms, where turning the unit "
              "moves gravity by about 1 g")
    if ms.has_gyro:
        w = ms.gyro_dph()
        means = np.array([w[a:b].mean(0) for a, b in poses])
        noise = np.sqrt(np.mean([w[a:b].var(0).sum() / (b - a) for a, b in poses]))  # std of a pose mean
        if np.sqrt(np.trace(np.atleast_2d(np.cov(means.T)))) > 100 * noise:
            raise CalibrationError(f"{ms.path / 'samples.csv'}: {detail}, while the gyro's pose means differ by far "
                                   "more than their noise: the accelerometer and gyro columns look swapped (ax ay az "
                                   "hold the gyro); check the column names")
    raise CalibrationError(f"{ms.path / 'samples.csv'}: {detail}: the unit was not turned between poses")


def rail_poses(ms, poses):
    """Refuse poses whose accelerometer sits at a rail: meta's full scale where given, else a column's
    extreme value held by nearly every sample of a pose (an unclipped pose's quantised noise does not)."""
    raw = ms.raw("acc")
    fs = ms.meta.get("full_scale", {}).get("acc")
    hits = []
    for j, c in enumerate(("ax", "ay", "az")):
        rails = fs if fs is not None else (raw[:, j].min(), raw[:, j].max())
        for i, (a, b) in enumerate(poses):
            x = raw[a:b, j]
            at = (x <= rails[0]) | (x >= rails[1]) if fs is not None else np.isin(x, rails)
            if np.mean(at) > (0.0 if fs is not None else 0.9):
                hits.append((i, c, float(x[at][0])))
    if hits:
        named = ", ".join(f"pose {i + 1} ({c} at {v:g})" for i, c, v in hits[:6]) + (" ..." if len(hits) > 6 else "")
        raise CalibrationError(f"{ms.path / 'samples.csv'}: {len({h[0] for h in hits})} of {len(poses)} poses hold "
                               f"accelerometer samples at a rail ({named}): the accelerometer saturates there; use a "
                               "larger range (or give full_scale in meta.json), or record those poses again")


def pose_observations(ms, detect=None, pose_window_s=1.0):
    """Accelerometer observations of a stream's static poses: (Observations, Detection, poses).

    Each pose is the mean of its first pose_window_s (None: the whole interval),
    with the std of that mean from the scatter of its samples."""
    t = ms.samples["t_s"]
    acc = ms.acc_g()
    det = detect_static(acc, t, detect or DetectSettings())
    dt = float(np.median(np.diff(t)))
    win = None if pose_window_s is None else max(int(round(pose_window_s / dt)), 2)
    poses = [(a, b if win is None else min(a + win, b)) for a, b in zip(det.starts, det.ends)]
    rail_poses(ms, poses)
    N = np.array([acc[a:b].mean(0) for a, b in poses])
    sig = np.array([acc[a:b].std(0, ddof=1) / np.sqrt(b - a) for a, b in poses])
    aux = AuxInputs(column_means(ms.samples, [slice(a, b) for a, b in poses], t_ref_c=ms.t_ref_c))
    obs = Observations(N, np.ones(len(N)), np.maximum(sig, 1e-12), aux, list(range(len(poses))))
    return obs, det, poses


def acc_from_poses(ms, acc_model="acc_baseline", detect=None, pose_window_s=1.0):
    """The accelerometer from a stream's poses: (Observations, Detection, model, fit, tau)."""
    if not ms.has_acc:
        raise CalibrationError(f"{ms.path}: a hand-placed session needs accelerometer data")
    obs, det, poses = pose_observations(ms, detect, pose_window_s)
    swapped_or_still(ms, obs, poses)
    units.check_magnitude("acc", np.linalg.norm(obs.N, axis=1), obs.rho, ms.path / "samples.csv", ms.meta)
    check_not_coplanar(obs.N, "accelerometer", f"{ms.path}: ")
    am = acc_model if isinstance(acc_model, AugmentedModel) else AugmentedModel(acc_model)
    prior = None
    if np.all(np.max(np.abs(obs.N / np.linalg.norm(obs.N, axis=1, keepdims=True)), axis=1) > np.cos(np.radians(10))):
        # every pose along a sensor axis (the Ferraris design): the norm sees each axis's scale and bias,
        # not the misalignments (second order there): hold them at 0 by a stated prior, named undetermined
        prior = {k: (0.0, PRIOR_MISALIGNMENT_RAD) for k, unit in zip(am.params, am.param_units) if unit == "rad"}
    fa, tau = with_model_error(am, obs, fit_exact(am, obs, prior=prior), prior)
    fa.undetermined = {k: {"determined": False, "held_at": v, "prior_std": sd,
                           "to_determine": "add poses tilted between the sensor axes (e.g. 45 deg about each axis)"}
                       for k, (v, sd) in (prior or {}).items()}
    return obs, det, am, fa, tau


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
    on clean simulated sessions."""
    C = full_covariance(am, obs, fa)
    m = len(am.params)
    tangent = np.diagonal(C[m:, m:]).reshape(-1, 2).sum(1) / 2
    return initial_directions(am, obs, fa.vector(am.params)), tangent


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


def misfit_shares(gm, base: GyroFit, sigma_g, inputs, chi0, dof0, alpha=0.01, max_terms=9) -> dict:
    """How much of the moves' misfit the library explains, effect by effect: forward selection.
    Each step adds the candidate that lowers the chi-square most, kept while its F test against
    the remaining misfit, F = (chi2_before - chi2_after) / (chi2_after / dof_after), beats
    alpha / (candidates left). share: its chi-square drop over the baseline's excess
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
        if p >= alpha / len(left):
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
    effect = EFFECTS[eid]
    return any(np.any(effect.phi(u, aux.array(SENSOR_AUX["gyro"], u.shape[:-1]))[0]) for u, aux in inputs)


def regressor_inputs(ms, gm, fit: GyroFit, acc_cal):
    """Inputs of the candidate regressors, (u deg/h, AuxInputs), at every move sample (m, L) and
    at every sample of the initial rest (n,): the calibrated rate, the calibrated specific
    force and the samples' auxiliary columns (t_s, temp_c, ...)."""
    M_a, b_a = acc_cal
    mv = gm.mv
    m, L = mv.dt.shape
    idx = np.zeros((m, L), int)
    for i, (a, b) in enumerate(mv.rows):
        idx[i, :b - a] = np.arange(a + 1, b + 1)
    rest = np.arange(gm.rest.start, gm.rest.stop)
    w = ms.gyro_dph() / units.DPH_PER_DPS - gm.bias - fit.db
    out = []
    for ix in (idx, rest):
        f = np.linalg.solve(M_a, (ms.acc_g()[ix] - b_a).reshape(-1, 3).T).T.reshape(ix.shape + (3,))
        out.append((w[ix] @ fit.T.T * units.DPH_PER_DPS, AuxInputs({**columns_at(ms.samples, ix, t_ref_c=ms.t_ref_c), **specific_force(f)})))
    return out


def with_terms(mv: Moves, ids, inputs) -> Moves:
    """mv with the regressors of effects ids along the moves and their mean over the rest."""
    (u, aux), (u0, aux0) = inputs
    mask = mv.dt > 0
    A, A0 = aux.array(SENSOR_AUX["gyro"], u.shape[:-1]), aux0.array(SENSOR_AUX["gyro"], u0.shape[:-1])
    phi = np.array([EFFECTS[e].phi(u, A)[0][..., 0] * mask / units.DPH_PER_DPS for e in ids]).reshape(len(ids), *mask.shape)
    phi_rest = np.array([np.mean(np.broadcast_to(EFFECTS[e].phi(u0, A0)[0][..., 0], u0.shape[:-1])) / units.DPH_PER_DPS
                         for e in ids])
    return Moves(mv.y, mv.dt, mv.before, mv.after, mv.t_span, mv.rows, phi, tuple(EFFECTS[e].axis for e in ids),
                 phi_rest)


def calibrate_handheld(ms, acc_model="acc_baseline", detect=None, pose_window_s=1.0, gyro_effects=(),
                       auto=False) -> dict:
    """pose_window_s: seconds at the start of each static interval averaged into the
    pose (None: the whole interval). Hand-placed poses creep: on imu_tk's Xsens
    session the baseline's chi2 falls from 472 to 141 (29 dof) when only the first
    second is used, which is also imu_tk's convention (100 samples).
    gyro_effects: candidate ids fit with T and the bias over the moves."""
    from simucal.io import calibration
    t = ms.samples["t_s"]
    obs, det, am, fa, tau = acc_from_poses(ms, acc_model, detect, pose_window_s)
    acc_chosen = None
    if auto:  # the library effects the failing poses need (candidates.forward_selection)
        am2, acc_chosen, acc_stopped = forward_selection(am, obs)
        if acc_chosen:
            obs, det, am, fa, tau = acc_from_poses(ms, am2, detect, pose_window_s)
    M_a, b_a = am.matrix_and_bias(fa.vector(am.params))
    units.check_scale("acc", M_a, ms.path / "samples.csv")
    result = calibration.header("handheld (Tedaldi): exact norm fit + gyro moves", ms)
    result["static_detection"] = {**det.as_dict(t), "pose_window_s": pose_window_s}
    result["acc"] = calibration.sensor_block(am, fa, M_a, b_a)
    result["acc"]["undetermined"] = fa.undetermined
    if auto:
        result["acc"]["auto"], result["acc"]["auto_stopped"] = acc_chosen, acc_stopped
    result["acc"].update(model_error_std_g=tau, note=None if tau == 0 else (
        "the model does not explain the poses down to their own noise (see chi2, p_value before "
        "the extra variance: simucal diagnose); each pose got an extra variance tau^2 so that "
        "chi2/dof = 1, and the stds include it"))
    if ms.has_gyro:
        gm = prepare_moves(ms, det, *pose_directions(am, obs, fa))
        f = fit_gyro(gm.mv, gm.g_dirs, gm.bias_std)
        effects, chosen = {}, None
        if auto and f.converged:  # the library effects the failing moves need (misfit_shares)
            sigma_g = gyro_noise_dps(ms, gm)
            chi2, dof, p_value = chi2_test(f, move_covariances(gm, f, sigma_g), gm.bias_std, gm.mv)
            if p_value is not None and p_value < ALPHA:
                shares = misfit_shares(gm, f, sigma_g, regressor_inputs(ms, gm, f, (M_a, b_a)), chi2, dof)
                chosen = shares["steps"]
                gyro_effects = tuple(dict.fromkeys(tuple(gyro_effects) + tuple(shares["effects"])))
        if gyro_effects and f.converged:
            inputs = regressor_inputs(ms, gm, f, (M_a, b_a))
            gm.mv = with_terms(gm.mv, list(gyro_effects), inputs)
            f = fit_gyro(gm.mv, gm.g_dirs, gm.bias_std, np.r_[f.T.ravel(), f.db, np.zeros(len(gyro_effects))])
            std_p = np.sqrt(np.diag(f.cov)[12:])
            effects = {e: calibration.effect_entry(v, sd, EFFECTS[e].unit, EFFECTS[e].meaning)
                       for e, v, sd in zip(gyro_effects, f.p, std_p)}
        if not f.converged:
            raise CalibrationError(f"{ms.path}: the gyro fit over the moves did not converge in {f.iterations} "
                                   "Gauss-Newton steps; look at the moves (simucal diagnose) for ones the model "
                                   "cannot follow")
        mv = gm.mv
        std_alone = np.sqrt(np.diag(f.cov)[:9])
        unseen = [k for k in range(9) if std_alone[k] > UNSEEN_STD]
        undetermined = {}
        if unseen:  # T is near I: a 5 % std means the moves barely turn the unit about that axis
            rms = np.sqrt(np.sum(mv.y ** 2 * mv.dt, axis=(1, 2)) / np.sum(mv.dt))  # per output axis, deg/s
            dead = [f"{'xyz'[j]} ({rms[j]:.2g} deg/s against {rms.max():.2g})" for j in range(3)
                    if rms[j] < 0.05 * rms.max()]
            names = [f"T_{'xyz'[k // 3]}{'xyz'[k % 3]}" for k in unseen]
            if len(unseen) == 9:
                raise CalibrationError(f"{ms.path}: the moves leave every entry of the gyro's T unobservable (std "
                                       f"above {UNSEEN_STD}): " + (
                                           f"gyro output {', '.join(dead)} hardly changes during the moves: a dead "
                                           "or unconnected channel?" if dead else
                                           "turn the unit about every axis between poses"))
            f = fit_gyro(mv, gm.g_dirs, gm.bias_std, np.r_[f.T.ravel(), f.db, f.p], held=unseen)
            undetermined = {n: {"determined": False, "std_moves_alone": float(std_alone[k]),
                                "held_at": float(np.eye(3).ravel()[k]), "prior_std": PRIOR_T,
                                "to_determine": f"turn about the {'xyz'[k % 3]} axis by at least 90 deg between two poses"}
                            for n, k in zip(names, unseen)}
        gyro_model, f, choice = choose_gyro_model(mv, gm.g_dirs, gm.bias_std, f, unseen)
        fixed = [] if gyro_model == "full" else list(range(9)) if gyro_model == "nominal" else list(GYRO_MODELS["scale"])
        if gyro_model != "full":
            undetermined = {k: v for k, v in undetermined.items() if "xyz".index(k[2]) * 4 not in fixed
                            and "xyz".index(k[2]) == "xyz".index(k[3])}
        T, r, cov = f.T, f.r, f.cov
        chi2, dof, p_value = chi2_test(f, move_covariances(gm, f, gyro_noise_dps(ms, gm)), gm.bias_std, mv)
        if undetermined and dead and p_value is not None and p_value < 1e-6:
            # a quiet output that the held nominal cannot explain: the channel does not respond
            raise CalibrationError(f"{ms.path}: gyro output {', '.join(dead)} hardly changes during the moves, and "
                                   f"holding {list(undetermined)} at nominal leaves the moves unexplained (chi2 "
                                   f"{chi2:.3g} on {dof} dof): a dead or unconnected channel?")
        bias = gm.bias + f.db
        bias_std = gm.bias_std if gyro_model == "nominal" else np.sqrt(np.diag(cov)[9:12])
        std_T = [[None if 3 * i + j in fixed else float(np.sqrt(cov[3 * i + j, 3 * i + j])) for j in range(3)]
                 for i in range(3)]
        M_g = np.linalg.inv(T)
        units.check_scale("gyro", M_g, ms.path / "samples.csv")
        result["gyro"] = calibration.affine_block(
            "gyro", M_g, bias * units.DPH_PER_DPS, {"T": std_T, "bias": (bias_std * units.DPH_PER_DPS).tolist()},
            float(np.sqrt(np.mean(np.sum(r ** 2, 1)))), GYRO_MODEL_TEXT[gyro_model],
            residual_unit="gravity direction (unit vector), per move", effects=effects,
            T=T.tolist(), T_note="T = M^-1: the rate in b is T (output - bias - effects)",
            moves=[{"from_pose": int(a), "to_pose": int(b), "t_s": list(span), "residual": ri.tolist()}
                   for a, b, span, ri in zip(mv.before, mv.after, mv.t_span, r)],
            moves_used=int(len(r)), moves_skipped=gm.skipped, saturation=gm.saturation,
            moves_opposite_sense=gm.flipped, iterations=f.iterations, chi2=chi2, dof=dof, p_value=p_value,
            test="chi-square of the moves against the rests' white noise (simucal diagnose shows them)",
            std_note="stds scale with the moves' own residual scatter, so they include any misfit",
            undetermined=undetermined, gyro_model=gyro_model, model_choice=choice,
            **({"auto": chosen or []} if auto else {}))
    result["residual_rms"] = {s: result[s]["residual_rms"] for s in ("acc", "gyro") if s in result}
    return result
