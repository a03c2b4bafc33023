"""The error-state Kalman filter and RTS smoother of systematic calibration (derive/systematic.py).

Strapdown mechanisation in n (ENU) at a fixed place (Titterton & Weston eq. 3.28, 3.51; the
unit does not move, so w_in^n = w_ie^n and there is no transport rate):

    C_k = exp(-[w_ie dt x]) C_{k-1} exp([dtheta_k x])                      attitude C_b^n
    v_k = v_{k-1} + (exp(-[w_ie dt x] / 2) C_{k-1} exp([dtheta_k x] / 2) f_k g0 + g^n - 2 w_ie x v_{k-1}) dt

with dtheta_k and f_k the compensated readings u_hat = h^-1(N; p_hat) (the gyro's turned into b by
C_b^d(eta_hat)^T). The error state x = [phi, dv, p_acc, p_gyro, eta] (derive/systematic.py) is
propagated sample by sample through the moves and a block of samples at a time at rest (the
inputs are constant there), and updated by zero velocity at the end of each block at rest; the
steps between two updates are composed into one transition first (`compose`), so the filter's
Python loop runs once per update, not once per sample.
Open loop about a nominal solution (the parameters and initial attitude of the pass before): only
the velocity is reset at each update (a known shift of dv), so the error state may move along
directions the data barely see (a level error against a horizontal accelerometer bias at one
position) without moving the point the model is linearised at: fed back at every update, such
excursions of a few mrad gave second-order velocity errors of several noise stds per second and the
filter diverged. The passes repeat (calibrate.py) as an iterated extended Kalman smoother
(Gauss-Newton). The RTS smoother (Rauch, Tung & Striebel 1965) runs over the update epochs.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from simucal.fit.aux_inputs import MOTION, motion
from simucal.fit.rotations import exp_so3, skew
from simucal.fit.row_solve import solve_rows
from simucal.generated import systematic as gen
from simucal.generated import table
from simucal.generated.effects import EFFECTS

if TYPE_CHECKING:
    from simucal.fit.augmented import AugmentedModel

CHUNK = 256  # epochs whose smoother gains are solved at once (memory: 3 CHUNK n^2 doubles; more pages cost more)
SMOOTH_S = 0.1  # the window over which a regressor's inputs are averaged (smoothed)
# np.linalg.solve's own LAPACK kernel (the same numbers) without its checks, a quarter of its cost on the filter's
# one 3 x 3 per update: a singular S gives NaN (which calibrate.divergence names) where the checks raised
lapack_solve = importlib.import_module("numpy.linalg._umath_linalg").solve  # private, so no stub in every numpy


def smoothed(inputs, dt):
    """Each input (n, 3) averaged over SMOOTH_S about each step. A column's regressor evaluated at the
    measured input carries that sample's noise, which the innovations carry too: for a term nonlinear
    in it (w^2: 2 w n) the two correlate, and the score test reads the noise as the effect (a MEMS
    gyro's 30 deg/h gave gyro.quadratic a chi-square of 9-16 on clean sequences). The table's
    moves change the rate over seconds, so the average keeps the input and divides the noise's
    variance by the window's samples. Each edge is padded with its own value (scipy.ndimage's "nearest",
    whose import cost calibrate 0.3-0.6 s)."""
    size = max(1, int(round(SMOOTH_S / float(np.median(dt))))) | 1
    return tuple(np.lib.stride_tricks.sliding_window_view(np.pad(x, [(size // 2,) * 2] + [(0, 0)] * (x.ndim - 1),
                                                                 mode="edge"), size, axis=0).mean(axis=-1)
                 for x in inputs)


def reads_motion(model) -> bool:
    """Whether an (augmented) model's terms read the body rate: a library lever arm or time delay, or a
    user's model file (whose terms may)."""
    return model.base.source != "built-in" or any(set(MOTION) & set(EFFECTS[e].reads) for e in model.effects)


@dataclass
class Sensors:
    """The two models, their current estimates and what the filter's blocks need of them."""
    acc: AugmentedModel
    gyro: AugmentedModel
    p_acc: np.ndarray
    p_gyro: np.ndarray     # the gyro's own parameters
    eta: np.ndarray        # C_b^d = mounting(eta), rad

    @property
    def n(self) -> int:
        return 6 + len(self.p_acc) + len(self.p_gyro) + 3

    def vector(self) -> np.ndarray:
        return np.r_[self.p_acc, self.p_gyro, self.eta]

    def compensate(self, N_a, N_g, aux_a, aux_g, dt_s=None):
        """u_hat: f_b (g) and w_b (deg/h) per step (n, 3), the models inverted at the estimates, and the
        accelerometer's auxiliary inputs: with the steps' lengths dt_s, the motion the gyros give where its
        terms read it (lever arms, time delay: f_b inverted again with it; the gyro's g-sensitivity is
        left at the first f_b, a change far below its noise)."""
        from simucal.fit.apply import model_inputs
        f_b = model_inputs(self.acc, self.p_acc, N_a, aux_a, "the systematic filter")
        C_b_d = table.mounting(self.eta)
        w_d = model_inputs(self.gyro, self.p_gyro, N_g, aux_g.with_values(**_force(f_b @ C_b_d.T)),
                           "the systematic filter")
        w_b = w_d @ C_b_d
        if dt_s is not None and reads_motion(self.acc):
            aux_a = aux_a.with_values(**motion(w_b, dt_s))
            f_b = model_inputs(self.acc, self.p_acc, N_a, aux_a, "the systematic filter")
        return f_b, w_b, aux_a

    def sensitivities(self, f_b, w_b, aux_a, aux_g):
        """D_a (n, 3, n_acc) and D_g (n, 3, n_gyro + 3): du_hat / dp_hat = -A^-1 J (derive/systematic.py)."""
        _, Ju, Jp = self.acc.jacobians(f_b, self.p_acc, aux_a)
        D_a = -solve_rows(Ju, Jp)
        C_b_d = table.mounting(self.eta)
        w_d = w_b @ C_b_d.T
        _, Ju, Jp = self.gyro.jacobians(w_d, self.p_gyro, aux_g.with_values(**_force(f_b @ C_b_d.T)))
        S = gen.frame_rate_sensitivity(np.broadcast_to(self.eta, w_b.shape), w_b)
        D_g = np.concatenate([-C_b_d.T @ solve_rows(Ju, Jp), -np.broadcast_to(C_b_d.T, S.shape) @ S], axis=-1)
        return D_a, D_g


def _force(f_d):
    return {"f_x": f_d[:, 0], "f_y": f_d[:, 1], "f_z": f_d[:, 2]}


@dataclass
class Epoch:
    """What the smoother needs of one update epoch: the transition Phi from the epoch before, the
    predicted and filtered covariances and states (x before the velocity's reset: `update`), the
    innovation and its covariance."""
    Phi: np.ndarray
    P_pred: np.ndarray
    P: np.ndarray
    x_pred: np.ndarray
    x: np.ndarray
    nu: np.ndarray | None = None
    S: np.ndarray | None = None
    t_s: float = 0.0
    nu_zero: np.ndarray | None = None  # a return's zero-position innovation and its covariance (zero_position.py)
    S_zero: np.ndarray | None = None


def nominal(C0, dtheta_b, f_b, dt, zupt, w_ie, g0):
    """The nominal navigation over the steps (module doc): the attitude at each step's start
    (m, 3, 3), the velocity at each update (m, 3; the nominal velocity is reset to 0 after each).
    Vectorised: the Earth's turn is about one axis (exp(-[w_ie T x]) to the time T), the body's a
    prefix product, and the velocity between updates a linear recurrence (`compose`)."""
    m = len(dt)
    half = exp_so3(0.5 * dtheta_b)
    turn = np.empty((m, 3, 3))
    turn[0], turn[1:] = np.eye(3), prefix_products(half @ half)[:-1]
    T = np.cumsum(dt) - dt                                   # each step's start
    Cs = exp_so3(-w_ie[None] * T[:, None]) @ C0 @ turn
    C_mid = exp_so3(-0.5 * w_ie[None] * dt[:, None]) @ Cs @ half
    f_n = np.einsum("kij,kj->ki", C_mid, f_b) * g0          # the specific force at the middle of dt
    gain = np.eye(3) - 2 * skew(w_ie) * dt[:, None, None]   # v <- (I - 2 [w_ie x] dt) v + (f_n - g) dt
    v_at = np.zeros((m, 3))
    ends = np.flatnonzero(zupt)
    v_at[ends] = compose(gain, ((f_n - [0.0, 0.0, g0]) * dt[:, None])[..., None], None, ends)[1][..., 0]
    return Cs, v_at


def prefix_products(R):
    """R_0 R_1 ... R_k for every k of R (m, a, a): a Hillis-Steele scan, log2(m) batched products."""
    P, s = R.copy(), 1
    while s < len(P):
        P[s:] = P[:-s] @ P[s:]
        s *= 2
    return P


def compose(A, B, Q, ends):
    """The steps x <- A_k x + B_k (and P <- A_k P A_k^T + Q_k) composed over each interval of steps
    that ends at an index of `ends` (the first starts at step 0): per interval (A, B, Q) of the whole,
    A = A_j..A_i, B = sum_k A_j..A_k+1 B_k, Q = sum_k (A_j..A_k+1) Q_k (..)^T. A tree of pairs:
    each interval padded with identities to a power of two and halved log2 times, batched."""
    starts = np.r_[0, ends[:-1] + 1]
    lengths = ends - starts + 1
    sizes = 1 << np.ceil(np.log2(lengths)).astype(int)
    out = [np.empty((len(ends),) + X.shape[1:]) if X is not None else None for X in (A, B, Q)]
    for size in np.unique(sizes):
        sel = np.flatnonzero(sizes == size)
        idx = starts[sel, None] + np.arange(size)
        pad = np.arange(size) >= lengths[sel, None]
        a, b = A[np.where(pad, 0, idx)], B[np.where(pad, 0, idx)]
        a[pad], b[pad] = np.eye(A.shape[-1]), 0.0
        q = None if Q is None else np.where(pad[..., None, None], 0.0, Q[np.where(pad, 0, idx)])
        while a.shape[1] > 1:  # (later, earlier) pairs: x -> a1 (a0 x + b0) + b1
            a0, a1 = a[:, 0::2], a[:, 1::2]
            b = a1 @ b[:, 0::2] + b[:, 1::2]
            if q is not None:
                q = a1 @ q[:, 0::2] @ np.swapaxes(a1, -1, -2) + q[:, 1::2]
            a = a1 @ a0
        for o, x in zip(out, (a, b, q)):
            if o is not None:
                o[sel] = x[:, 0]
    return out


def nav_blocks(Cs, f_b, D_a, D_g, w_ie, g0):
    """F's rows of phi and dv at m instants, F_nn (m, 6, 6) and F_np (m, 6, n - 6), in
    d[phi, dv]/dt = F_nn [phi, dv] + F_np [p_acc, p_gyro, eta] (the parameters' rows are zero): the
    derived navigation blocks and the models' sensitivities (derive/systematic.error_state_model
    assembles the same symbolically)."""
    c = Cs.reshape(len(Cs), 9)
    B = gen.nav_B(c, g0)  # d[phi, dv]/dt from dw_b = D_g [dp_gyro, deta] and df_b = D_a dp_acc
    return gen.nav_F(c, f_b, w_ie, g0), np.concatenate([B[:, :, 3:] @ D_a, B[:, :, :3] @ D_g], axis=-1)


def transitions(Cs, f_b, D_a, D_g, dt, q, w_ie, g0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phi = I + F dt + (F dt)^2 / 2 of every step (F constant over it) by its blocks, vectorised: the
    parameters are constants, so Phi = [[A, B], [0, I]] with A = I + F_nn dt + (F_nn dt)^2 / 2 (m, 6, 6)
    and B = F_np dt + F_nn dt F_np dt / 2 (m, 6, n - 6); and the noise's Q (m, 6, 6) over the step (it drives
    phi and dv only), the integral of e^(F s) G q G^T e^(F^T s) over it (Van Loan 1978) to the same order:
    with Q0 = G diag(q dt) G^T (block-diagonal: the gyro's noise walks phi, the accelerometers' dv) and
    F_vphi = [f^n x], the dv row's phi block, Q = Q0 plus F_vphi Q0_phi dt / 2 in dv-phi (and its transpose) and
    F_vphi Q0_phi F_vphi^T dt^2 / 3 in dv-dv: the tilt the gyro noise walks within the step and the velocity
    it makes, which Q0 alone misses (on a 1 s rest block a MEMS unit's, 30 deg/h and 2e-4 g per sample at
    100 Hz, is 18 % of the accelerometer noise's; a tactical unit's 4 %). The expansion's other terms hold
    the Earth rate (F's phi-phi and dv-dv blocks) and are |w_ie| dt (7e-5 on a 1 s block) of one kept."""
    F_nn, F_np = nav_blocks(Cs, f_b, D_a, D_g, w_ie, g0)
    F_nn, F_np = F_nn * dt[:, None, None], F_np * dt[:, None, None]
    G = gen.nav_G(Cs.reshape(len(Cs), 9))
    Q = (G * (q * dt[:, None])[:, None, :]) @ np.swapaxes(G, 1, 2)
    X = F_nn[:, 3:, :3] @ Q[:, :3, :3]
    Q[:, 3:, 3:] += X @ np.swapaxes(F_nn[:, 3:, :3], 1, 2) / 3
    Q[:, 3:, :3] += X / 2
    Q[:, :3, 3:] += np.swapaxes(X, 1, 2) / 2
    return np.eye(6) + F_nn + 0.5 * F_nn @ F_nn, F_np + 0.5 * F_nn @ F_np, Q


STEPS = 1024  # steps whose transitions are built at once (memory: about 60 STEPS doubles per state)


def composed(Cs, f_b, D_a, D_g, dt, zupt, q, w_ie, g0):
    """The steps between two updates composed into one transition (`transitions`, `compose`), STEPS steps'
    at a time: yields (those updates' indices among all, their A, B, Q). The steps after the last update see
    no data and are left out."""
    ends = np.flatnonzero(zupt)
    group = ends // STEPS  # the intervals that end in one STEPS of steps, together
    for g in np.unique(group):
        i = np.flatnonzero(group == g)
        a = ends[i[0] - 1] + 1 if i[0] else 0
        k = slice(a, ends[i[-1]] + 1)
        yield (i, *compose(*transitions(Cs[k], f_b[k], D_a[k], D_g[k], dt[k], q, w_ie, g0), ends[i] - a))


def kalman(x, P, A, B, Q, v_at, R, t_s, epochs, zero=None, C_at=None):
    """The filter over the intervals between updates, each one transition Phi = [[A, B], [0, I]]
    (`compose`): x <- Phi x, P <- Phi P Phi^T + Q, then the zero-velocity update of `update`,
    recorded in epochs. zero: a sequence's returns (zero_position.Returns: the clones' copies and the
    attitude updates, at the nominal attitudes C_at of the updates), or None. Returns (x, P) after the last."""
    n = len(P)
    Phi = np.broadcast_to(np.eye(n), (len(A), n, n)).copy()
    Phi[:, :6, :6], Phi[:, :6, 6:6 + B.shape[-1]] = A, B
    for k in range(len(A)):
        u = len(epochs) - 1  # this update's number (epochs[0] is the prior)
        Ph, Qz = (Phi[k], None) if zero is None else zero.transition(u, Phi[k])
        x = Ph @ x
        P = Ph @ P @ Ph.T
        P[:6, :6] += Q[k]
        if Qz is not None:
            P = P + Qz
        attitude = None if zero is None else zero.measurement(u, C_at[k])
        x, P = update(x, P, v_at[k], R, Ph, t_s[k], epochs, attitude)
    return x, P


DV = slice(3, 6)  # the states the update sees: H = [0 I 0] (gen.H), taken as this slice (tests hold them equal)


def update(x_pred, P_pred, v, R, Phi, t_s, epochs, attitude=None):
    """The update by v = 0 (z = v_nominal = dv + noise, H = [0 I 0], R (3, 3)) in Joseph form, then
    where the rest is a return the zero-position update (attitude: (H, z, R), zero_position.py), the
    epoch recorded (its innovation the zero-velocity one's, which the model test reads); then the nominal
    velocity's reset to 0 (dv shifted by the same: the epoch keeps
    the state before it, which x_pred of the next epoch is propagated from less the known shift, as
    the smoother needs: x_k+1 = Phi (x_k - reset) + w, so x_k+1|N - x_k+1|k carries no reset)."""
    nu = v - x_pred[DV]                               # z - H x_pred
    HP = P_pred[DV]
    S = HP[:, DV] + R                                 # innovation covariance H P H^T + R
    K = lapack_solve(S, HP).T                         # K = P H^T S^-1
    x = x_pred + K @ nu
    X = P_pred - K @ HP                               # (I - K H) P
    P = X - X[:, DV] @ K.T + K @ R @ K.T              # Joseph form: (I - K H) P (I - K H)^T + K R K^T
    nu_a = S_a = None
    if attitude is not None:                          # a second, independent measurement: in sequence
        H, z, Ra = attitude
        HP = H @ P
        nu_a, S_a = z - H @ x, HP @ H.T + Ra          # its innovation, white beside the zero-velocity one's
        K = np.linalg.solve(S_a, HP).T
        x = x + K @ nu_a
        IKH = np.eye(len(P)) - K @ H
        P = IKH @ P @ IKH.T + K @ Ra @ K.T
    epochs.append(Epoch(Phi, P_pred, P, x_pred, x, nu, S, t_s, nu_a, S_a))
    x = x.copy()
    x[DV] -= v                                        # the reset: dv = v_nominal - v
    return x, P


def smooth(epochs, covariance=True) -> tuple[np.ndarray, np.ndarray | None]:
    """The RTS smoother over the epochs: (x_s (m, n), P_s (m, n, n) or None unless covariance):
        A_k = P_k|k Phi_k+1^T P_k+1|k^-1
        x_k|N = x_k|k + A_k (x_k+1|N - x_k+1|k)
        P_k|N = P_k|k + A_k (P_k+1|N - P_k+1|k) A_k^T
    the gains A_k of CHUNK epochs solved at once, from the end back. (Bierman's modified
    Bryson-Frazier form, free of P_k+1|k^-1, carries the information instead: from the wide prior it
    left 0.4-0.6 std of round-off on the constants at the start where this leaves 0.002.)"""
    m, n = len(epochs), len(epochs[-1].P)
    x_s, P_s = np.empty((m, n)), np.empty((m, n, n)) if covariance else None
    x_s[-1] = epochs[-1].x
    if P_s is not None:  # covariance
        P_s[-1] = epochs[-1].P
    for lo in range(max(0, m - 1 - CHUNK), -CHUNK, -CHUNK):
        ks = range(max(lo, 0), min(lo + CHUNK, m - 1))
        P_pred = np.array([epochs[k + 1].P_pred for k in ks])
        with np.errstate(invalid="ignore"):  # a negative variance (diverged) gives NaN: calibrate.divergence names it
            d = np.sqrt(np.diagonal(P_pred, axis1=1, axis2=2))[:, :, None]  # P_pred spans ~20 decades:
        PhiP = np.array([epochs[k + 1].Phi for k in ks]) @ np.array([epochs[k].P for k in ks])  # solved as
        gains = np.swapaxes(np.linalg.solve(P_pred / d / np.swapaxes(d, 1, 2), PhiP / d) / d, 1, 2)  # correlations
        for k, A in zip(reversed(ks), gains[::-1]):
            x_s[k] = epochs[k].x + A @ (x_s[k + 1] - epochs[k + 1].x_pred)
            if P_s is not None:
                P_s[k] = epochs[k].P + A @ (P_s[k + 1] - epochs[k + 1].P_pred) @ A.T
    return x_s, P_s


def level(C, f_b):
    """C corrected so that C f_b points up (the least rotation): the accelerometers' levelling."""
    f_n = C @ f_b
    axis = np.cross(f_n / np.linalg.norm(f_n), [0.0, 0.0, 1.0])
    s = np.linalg.norm(axis)
    return C if s < 1e-15 else exp_so3(axis / s * np.arcsin(min(float(s), 1.0))) @ C
