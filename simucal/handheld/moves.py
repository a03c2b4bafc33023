"""The gyro of a hand-placed session from its moves (Tedaldi et al. 2014, as in imu_tk).

T = M_g^-1 (full 3x3: scale factors, misalignment and the rotation between the triads, so omega
is in the accelerometer frame b) and the bias from the moves between consecutive poses:
integrate omega_k = T (y_k - b_g) over the move and ask that the gravity direction the
calibrated accelerometer sees after the move equal the one before, rotated:
    r_i = g_{i+1} - R_i(T)^T g_i.
R_i = prod_k exp([omega_k dt x]); a right perturbation gives the Jacobian
d(phi_i) = sum_k A_k^T J_r(omega_k dt) d(omega_k) dt with A_k the product of
the later steps and J_r the right Jacobian of SO(3), and d(r_i) = -[g_pred x] d(phi_i).
Also: the gyro model chosen by the moves left out (choose_gyro_model), and moves whose rotation
sense contradicts the accelerometers refused (check_rotation_sense).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.rotations import skew
from simucal.generated import moves as gen_moves
from simucal.handheld.static_detect import Detection
from simucal.io import records, timestamps, units



@dataclass
class Moves:
    y: np.ndarray                       # (3, m, L) bias-free gyro outputs (deg/s), zero-padded
    dt: np.ndarray                      # (m, L) sample intervals, 0 on padding
    before: np.ndarray                  # (m,) index of the pose before
    after: np.ndarray                   # (m,) index of the pose after
    t_span: list | None = None          # (m,) (start, end) times (s)
    rows: list | None = None            # (m,) (a, b): the move integrates stream rows a+1 .. b
    phi: np.ndarray | None = None       # (q, m, L) regressors of added effects, (deg/s) per unit parameter,
                                        # 0 on padding
    phi_axes: tuple = ()                # the output axis each one acts on
    phi_rest: np.ndarray | None = None  # (q,) their mean over the initial rest, which reads b + sum_j p_j e_j phi_j

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


def build_moves(w, t, det: Detection, bias, bad):
    """The moves between consecutive poses, leaving out (and naming) those with saturated
    samples or a time gap (samples missing: io/timestamps.gaps), which no integration
    can bridge. A move runs from the end of one static interval to the start of the next
    (imu_tk's convention). Integrating from the end of the pose's averaging window instead
    takes in the whole rest, whose g-sensitive bias (not in the baseline) then accrues: on
    imu_tk's Xsens session the chi2 grows from 12643 to ~380000 on 65 dof. The gyro samples at
    the detector's edges are quiet (a centred window ends a static interval early), so no
    rotation is lost at a move's start."""
    dt_all = np.diff(t)
    gap = np.zeros(len(t), bool)  # row k follows a gap
    gap[[g["after_row"] + 1 for g in timestamps.gaps(t)]] = True
    idx: list[tuple[int, int, int]] = []  # (pose before, a, b): the move integrates rows a+1 .. b
    skipped: list[dict] = []
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
    if not jac:
        return integrated(T, mv, g_dirs, db, p, jac=False).r, None
    it = integrated(T, mv, g_dirs, db, p)
    return it.r, jacobian(it, T, mv)


def jacobian(it: Integrated, T, mv: Moves) -> np.ndarray:
    """dr/d[vec(T), db, p] (m, 3, 12 + q) at the point the moves were integrated at."""
    assert it.W is not None  # integrated with its Jacobian (jac=True)
    m = len(it.r)
    cols = [it.Rt @ (it.W @ it.y.transpose(1, 2, 0)).reshape(m, 3, 9),  # sum_k W_k (x) y_k
            -it.Rt @ it.W.sum(2).reshape(m, 3, 3) @ T]
    dphi = np.concatenate(cols, axis=2) * np.radians(1.0)
    effects = []
    if mv.n_terms:
        assert mv.phi is not None  # with_terms gives phi with phi_axes
        effects = [effect_column(it, T, phi, axis) for phi, axis in zip(mv.phi, mv.phi_axes)]
    return np.concatenate([-np.matmul(skew(it.pred), dphi)] + effects, axis=2)


@dataclass
class Integrated:
    """The moves integrated at one point: the outputs y less the biases and effects (3, m, L), the
    residuals r (m, 3), each move's R_i^T (m, 3, 3), the predicted gravity directions pred (m, 3), and
    the integration's Jacobian W (m, 9, L) (None without the Jacobian)."""
    y: np.ndarray
    r: np.ndarray
    Rt: np.ndarray
    pred: np.ndarray
    W: np.ndarray | None


def integrated(T, mv: Moves, g_dirs, db=None, p=None, jac=True) -> Integrated:
    """The moves integrated at (T, db, p) (move_residuals' first half)."""
    y = mv.y if db is None else mv.y - db[:, None, None] * (mv.dt > 0)
    if mv.n_terms:
        assert mv.phi is not None  # with_terms gives phi with phi_axes
        y = y - np.einsum("j,ja,jmk->amk", p, np.eye(3)[list(mv.phi_axes)], mv.phi)
    v = np.einsum("ab,bmk->amk", T, y) * (np.radians(1.0) * mv.dt)
    Q = gen_moves.step_quaternion(v)
    Q_end = total_products(Q) if not jac else prefix_products(Q)[..., -1]
    Rt = np.moveaxis(gen_moves.rotation_matrix(Q_end), -1, 0).swapaxes(1, 2)  # (m, 3, 3): R_i^T
    pred = np.einsum("mab,mb->ma", Rt, g_dirs[mv.before])
    m, L = mv.dt.shape
    W = gen_moves.integration_jacobian(Q, v, mv.dt).reshape(9, m, L).transpose(1, 0, 2) if jac else None
    return Integrated(y, g_dirs[mv.after] - pred, Rt, pred, W)


def effect_column(it: Integrated, T, phi, axis) -> np.ndarray:
    """dr/dp (m, 3, 1) of an effect with regressor phi (m, L) on output axis `axis`, at the point it was
    integrated at: a candidate's column needs no integration of its own (the ranking's 33 columns each
    cost a whole Jacobian)."""
    d = -it.Rt @ (it.W @ phi[..., None]).reshape(len(it.r), 3, 3) @ T[:, axis:axis + 1] * np.radians(1.0)
    return -np.matmul(skew(it.pred), d)


def with_effect(it: Integrated, J, T, mv: Moves) -> tuple[np.ndarray, np.ndarray]:
    """(r, dr/dx) of moves mv at the point `it` was integrated at, with the coefficient of mv's last effect 0
    there: `it` and its Jacobian J without that effect serve (the same integration), its column added
    (effect_column). Each trial fit of a ranking starts there (fit_gyro_moves' start)."""
    assert mv.phi is not None  # with_terms gives phi with phi_axes
    return it.r, np.concatenate([J, effect_column(it, T, mv.phi[-1], mv.phi_axes[-1])], axis=2)


def _prior(mv: Moves, n, bias_std, held=()):
    """The prior rows and their targets for x = [vec(T), db, p]: the rest read b_rest = b + sum_j
    p_j e_j phi_j(rest), so db + that sum = 0 +- bias_std; entries `held` of vec(T) at nominal (I)
    with std PRIOR_T (a soft prior)."""
    E = np.zeros((3, n - 12))
    if mv.n_terms:
        E[list(mv.phi_axes), np.arange(n - 12)] = mv.phi_rest
    prior = np.c_[np.zeros((3, 9)), np.eye(3), E] / bias_std[:, None]
    target = np.zeros(3)
    if held:
        rows = np.zeros((len(held), n))
        rows[np.arange(len(held)), list(held)] = 1.0 / PRIOR_T
        prior = np.vstack([prior, rows])
        target = np.r_[target, np.eye(3).ravel()[list(held)] / PRIOR_T]
    return prior, target


def free_entries(n, fixed) -> np.ndarray:
    """The entries of x = [vec(T), db, p] estimated: all but `fixed`, the entries of vec(T) a simpler gyro
    model (GYRO_MODELS) leaves at nominal. Left out of the fit, not held by a prior: a prior of std 1e-9
    made the scale model's system so ill-conditioned (cond 2e11) that its steps never converged, so
    the scale model could never be chosen."""
    return np.setdiff1d(np.arange(n), list(fixed))


def fit_gyro_moves(mv: Moves, g_dirs, x0, bias_std, max_iter=30, step_tol=1e-3, offset=0.0, held=(),
                   fixed=(), start=None) -> GyroFit:
    """Gauss-Newton on x = [vec(T), db, p] from x0, the rest's bias entering as a prior
    with its standard error bias_std (deg/s): the moves inform the bias too. The
    direction noise sigma_r is the moves' residual rms (re-estimated each step).
    offset is added to the residuals (a coarse level's defect, see fit_gyro). held: entries of vec(T)
    near nominal by a prior (_prior); fixed: entries at nominal, left out of the fit (free_entries); start:
    (r, J) at x0 (offset not added) where at hand (with_effect), else integrated here.

    Converged when no step exceeds step_tol of its parameter's std: that step is
    taken and only the residual recomputed, the Jacobian of the point before serving
    the covariance (it differs by ~step_tol). Step halving tries the residuals alone, the
    Jacobian formed at the point taken: a nearly singular model (T's diagonal alone with six
    g-sensitivities on imu_tk's Xsens session, cond 6e11) ran 30 steps of 14 trials each: that
    calibrate took 5.0 s with a Jacobian at every trial, 2.5 s without."""
    x = np.array(x0, float)
    n = len(x)
    x[list(fixed)] = np.eye(3).ravel()[list(fixed)]
    free = free_entries(n, fixed)
    prior, target = _prior(mv, n, bias_std, held)

    def evaluate(x, jac=True):
        r, J = move_residuals(x[:9].reshape(3, 3), mv, g_dirs, jac, db=x[9:12], p=x[12:])
        return r + offset, J

    def whitened(x, r, s_r):  # the residuals and the prior's, each over its std
        return np.r_[r.ravel() / s_r, prior @ x - target]

    def system(x, r, J, s_r):  # the rows over the free entries alone
        return np.vstack([J.reshape(-1, n) / s_r, prior])[:, free], whitened(x, r, s_r)

    r, J = evaluate(x) if start is None else (start[0] + offset, start[1])
    converged = False
    for it in range(1, max_iter + 1):
        s_r = max(float(np.sqrt(np.mean(r ** 2))), 1e-12)
        A, e = system(x, r, J, s_r)
        step = np.zeros(n)
        step[free] = np.linalg.lstsq(A, -e, rcond=None)[0]
        if np.all(np.abs(step[free]) < step_tol * np.sqrt(np.diag(np.linalg.pinv(A.T @ A)))):
            x = x + step
            r = evaluate(x, jac=False)[0]
            converged = True
            break
        cost, lam = float(e @ e), 1.0
        while True:  # step halving, the residuals alone; GN steps near the optimum are taken whole, with the Jacobian
            x_new = x + lam * step
            r_new, J_new = evaluate(x_new, jac=lam == 1.0)
            e_new = whitened(x_new, r_new, s_r)
            if e_new @ e_new <= cost or lam < 1e-4:
                break
            lam /= 2
        x, r, J = (x_new, r_new, J_new) if J_new is not None else (x_new, *evaluate(x_new))
    # each residual joins two unit vectors, so it has 2 degrees of freedom, not 3
    s_r = float(np.sqrt(np.sum(r ** 2) / max(2 * len(r) - len(free), 1)))
    A = system(x, r, J, s_r)[0]
    cov = np.zeros((n, n))  # a fixed entry's row and column zero: not estimated
    cov[np.ix_(free, free)] = np.linalg.pinv(A.T @ A)
    return GyroFit(x[:9].reshape(3, 3), x[9:12], x[12:], r, cov, it, converged)


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


GYRO_MODELS = {"nominal": tuple(range(9)), "scale": (1, 2, 3, 5, 6, 7), "full": ()}  # vec(T)'s entries at nominal
GYRO_MODEL_TEXT = {
    "nominal": "nominal scale factors (T = I; std null: not estimated), bias from the initial rest: the moves do not "
               "support more (model_choice)",
    "scale": "scale factors only (T diagonal; off-diagonal std null: not estimated), bias from the initial rest "
             "refined by the moves: the moves do not support a full matrix (model_choice)",
    "full": "full 3x3 M (scale, misalignment, triad rotation), bias from the initial rest, effects over the moves"}


def held_out_moves(mv: Moves, g_dirs, f: GyroFit, bias_std, held=(), fixed=(), at=None) -> np.ndarray:
    """Each move's gravity-direction residual (rad, ~ the angle) predicted by the fit without that
    move: the leave-one-out identity of the Gauss-Newton step at the optimum, r_(k) = (I - H_kk)^-1 r_k
    with H_kk = A_k (A^T A)^-1 A_k^T the move's block of the hat matrix (the prior rows stay in A).
    at: (r, J) of the moves at f where at hand (move_residuals' there)."""
    r, J = move_residuals(f.T, mv, g_dirs, db=f.db, p=f.p) if at is None else at
    n = J.shape[-1]
    free = free_entries(n, fixed)
    J = J[..., free]
    prior = _prior(mv, n, bias_std, held)[0][:, free]
    s_r = max(float(np.sqrt(np.mean(r ** 2))), 1e-12)
    A = np.vstack([J.reshape(len(J) * 3, -1) / s_r, prior])
    H = np.einsum("mai,ij,mbj->mab", J / s_r, np.linalg.pinv(A.T @ A), J / s_r)
    return np.linalg.norm(np.linalg.solve(np.eye(3) - H, r[..., None])[..., 0], axis=1)


def _rms_deg(angles_rad):
    return float(np.degrees(np.sqrt(np.mean(np.asarray(angles_rad) ** 2))))


def choose_gyro_model(mv: Moves, g_dirs, bias_std, f_full: GyroFit,
                      held=()) -> tuple[str, GyroFit, dict[str, records.GyroModelScore]]:
    """The gyro's T by what the moves support, judged on moves left out (issue: a full matrix from
    few moves can be worse than the nominal one): nominal (T = I, the rest's bias), scale factors
    only, or the full 3x3. A richer one is taken only where it predicts the left-out moves better than
    the one chosen before it, significantly: the paired test of their squared held-out errors
    (cross_validation.paired_improvement) at fit/selection.HELD_OUT_ALPHA, the level of `--add auto`'s
    same question (a fixed 2 % gain took a full T at p = 0.29 that transferred 22 % worse).
    So the chosen model's held-out error is never above the nominal's. Returns (name, its fit, the
    table: each model's held-out and in-sample rms and p_better)."""
    from simucal.fit.cross_validation import paired_improvement
    from simucal.fit.selection import HELD_OUT_ALPHA
    nominal = GyroFit(np.eye(3), np.zeros(3), f_full.p * 0, move_residuals(np.eye(3), mv, g_dirs, jac=False,
                      db=np.zeros(3), p=f_full.p * 0)[0], np.zeros_like(f_full.cov), 0, True)
    fits = {"nominal": (nominal, np.linalg.norm(nominal.r, axis=1))}
    x0 = np.r_[f_full.T.ravel(), f_full.db, f_full.p]
    held_diag = [k for k in held if k not in GYRO_MODELS["scale"]]
    scale = fit_gyro(mv, g_dirs, bias_std, x0, held=held_diag, fixed=GYRO_MODELS["scale"])
    fits["scale"] = (scale, held_out_moves(mv, g_dirs, scale, bias_std, held_diag, GYRO_MODELS["scale"]))
    fits["full"] = (f_full, held_out_moves(mv, g_dirs, f_full, bias_std, held=held))
    chosen = "nominal"
    table: dict[str, records.GyroModelScore] = {}
    for name, (fit, held_out) in fits.items():
        table[name] = {"held_out_rms_deg": _rms_deg(held_out),
                       "in_sample_rms_deg": _rms_deg(np.linalg.norm(fit.r, axis=1))}
        if name != "nominal":
            table[name].update({"compared_with": chosen, "p_better": paired_improvement(fits[chosen][1], held_out)})
            p = table[name]["p_better"]
            if fit.converged and p is not None and p < HELD_OUT_ALPHA:
                chosen = name
    return chosen, fits[chosen][0], table


def decimate(mv: Moves, k: int, base: Moves | None = None) -> Moves:
    """Moves with k samples per step (block means of the rate, summed dt): cheaper
    iterations whose composition error (~1e-3 rad) the full-resolution steps remove. base: mv's decimation
    without its last regressor (a ranking's trials each add one to the same moves), so that only that one is
    averaged (each row's mean is its own: the same numbers)."""
    m, L = mv.dt.shape
    n = -(-L // k) * k
    if base is not None:
        assert mv.phi is not None  # base: decimate(mv less its last regressor, k)
        last = _block_means(mv.phi[-1:], mv.dt, n, k, base.dt)
        phi = last if base.phi is None else np.concatenate([base.phi, last])
        return Moves(base.y, base.dt, mv.before, mv.after, mv.t_span, mv.rows, phi, mv.phi_axes, mv.phi_rest)
    dt = np.zeros((m, n))
    dt[:, :L] = mv.dt
    dt_b = dt.reshape(m, n // k, k).sum(2)
    return Moves(_block_means(mv.y, mv.dt, n, k, dt_b), dt_b, mv.before, mv.after, mv.t_span, mv.rows,
                 None if mv.phi is None else _block_means(mv.phi, mv.dt, n, k, dt_b), mv.phi_axes, mv.phi_rest)


def _block_means(z, dt, n, k, dt_b):
    """A rate-like z (..., m, L): its dt-weighted means over blocks of k samples (padded to n), dt_b their lengths."""
    out = np.zeros(z.shape[:-1] + (n,))
    out[..., :dt.shape[-1]] = z * dt
    return out.reshape(z.shape[:-1] + (n // k, k)).sum(-1) / np.where(dt_b > 0, dt_b, 1.0)


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


