"""The error-state Kalman filter and RTS smoother of systematic calibration (derive/systematic.py).

Strapdown mechanisation in n (ENU) at a fixed place (Titterton & Weston eq. 3.28, 3.51; the
unit does not move, so w_in^n = w_ie^n and there is no transport rate):

    C_k = exp(-[w_ie dt x]) C_{k-1} exp([dtheta_k x])                      attitude C_b^n
    v_k = v_{k-1} + (exp(-[w_ie dt x] / 2) C_{k-1} exp([dtheta_k x] / 2) f_k g0 + g^n - 2 w_ie x v_{k-1}) dt

with dtheta_k and f_k the compensated readings u_hat = h^-1(N; p_hat) (the gyro's turned into b by
C_b^d(eta_hat)^T). The error state x = [phi, dv, p_acc, p_gyro, eta] (derive/systematic.py) is
propagated sample by sample through the moves and a block of samples at a time at rest (the
inputs are constant there), and updated by zero velocity at the end of each block at rest.
Open loop about a nominal solution (the parameters and initial attitude of the pass before): only
the velocity is reset at each update (a known shift of dv), so the error state may move along
directions the data barely see (a level error against a horizontal accelerometer bias at one
position) without moving the point the model is linearised at: fed back at every update, such
excursions of a few mrad gave second-order velocity errors of several noise stds per second and the
filter diverged. The passes repeat (calibrate.py) as an iterated extended Kalman smoother
(Gauss-Newton). The RTS smoother (Rauch, Tung & Striebel 1965) runs over the update epochs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simucal.fit.rotations import exp_so3
from simucal.generated import systematic as gen
from simucal.generated import table

RAD_S_PER_DPH = np.pi / 180 / 3600


@dataclass
class Sensors:
    """The two models, their current estimates and what the filter's blocks need of them."""
    acc: object            # AugmentedModel
    gyro: object           # AugmentedModel
    p_acc: np.ndarray
    p_gyro: np.ndarray     # the gyro's own parameters
    eta: np.ndarray        # C_b^d = mounting(eta), rad

    @property
    def n(self) -> int:
        return 6 + len(self.p_acc) + len(self.p_gyro) + 3

    def vector(self) -> np.ndarray:
        return np.r_[self.p_acc, self.p_gyro, self.eta]

    def compensate(self, N_a, N_g, aux_a, aux_g):
        """u_hat: f_b (g) and w_b (deg/h) per sample (n, 3), the models inverted at the estimates."""
        from simucal.fit.apply import model_inputs
        f_b = model_inputs(self.acc, self.p_acc, N_a, aux_a, "the systematic filter")
        C_b_d = table.mounting(self.eta)
        w_d = model_inputs(self.gyro, self.p_gyro, N_g, aux_g.with_values(**_force(f_b @ C_b_d.T)),
                           "the systematic filter")
        return f_b, w_d @ C_b_d

    def sensitivities(self, f_b, w_b, aux_a, aux_g):
        """D_a (n, 3, n_acc) and D_g (n, 3, n_gyro + 3): du_hat / dp_hat = -A^-1 J (derive/systematic.py)."""
        _, Ju, Jp = self.acc.jacobians(f_b, self.p_acc, aux_a)
        D_a = -np.linalg.solve(Ju, Jp)
        C_b_d = table.mounting(self.eta)
        w_d = w_b @ C_b_d.T
        _, Ju, Jp = self.gyro.jacobians(w_d, self.p_gyro, aux_g.with_values(**_force(f_b @ C_b_d.T)))
        S = gen.frame_rate_sensitivity(np.broadcast_to(self.eta, w_b.shape), w_b)
        D_g = np.concatenate([-C_b_d.T @ np.linalg.solve(Ju, Jp), -np.broadcast_to(C_b_d.T, S.shape) @ S], axis=-1)
        return D_a, D_g


def _force(f_d):
    return {"f_x": f_d[:, 0], "f_y": f_d[:, 1], "f_z": f_d[:, 2]}


@dataclass
class Epoch:
    """What the smoother needs of one update epoch: the transition Phi from the epoch before, the
    predicted and filtered covariances and states, the innovation and its covariance."""
    Phi: np.ndarray
    P_pred: np.ndarray
    P: np.ndarray
    x_pred: np.ndarray
    x: np.ndarray
    nu: np.ndarray | None = None
    S: np.ndarray | None = None
    t_s: float = 0.0


def nominal(C0, dtheta_b, f_b, dt, zupt, w_ie, g0):
    """The nominal navigation over the steps (module doc): the attitude at each step's start
    (m, 3, 3), the velocity at each update (m, 3; the nominal velocity is reset to 0 after each)."""
    m = len(dt)
    Cs, v_at = np.empty((m, 3, 3)), np.zeros((m, 3))
    half = exp_so3(0.5 * dtheta_b)
    earth = exp_so3(-0.5 * w_ie[None] * dt[:, None])
    up = np.array([0.0, 0.0, g0])
    C, v = C0, np.zeros(3)
    for k in range(m):
        Cs[k] = C
        e = earth[k]
        C_mid = e @ C @ half[k]
        f_n = C_mid @ f_b[k] * g0                          # the specific force at the middle of dt
        v = v + (f_n - up - 2 * _cross(w_ie, v)) * dt[k]
        C = e @ C_mid @ half[k]
        if zupt[k]:
            v_at[k], v = v, np.zeros(3)
    return Cs, v_at


def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def system_matrices(Cs, f_b, D_a, D_g, w_ie, g0):
    """F (m, n, n) of d(x)/dt = F x at m instants: the derived navigation blocks and the models'
    sensitivities (derive/systematic.error_state_model assembles the same symbolically)."""
    m, na = len(Cs), D_a.shape[-1]
    n = 6 + na + D_g.shape[-1]
    c = Cs.reshape(m, 9)
    F = np.zeros((m, n, n))
    F[:, :6, :6] = gen.nav_F(c, f_b, w_ie, g0)
    B = gen.nav_B(c, g0)
    F[:, :6, 6:6 + na] = B[:, :, 3:] @ D_a     # d[phi, dv]/dt from df_b = D_a dp_acc
    F[:, :6, 6 + na:] = B[:, :, :3] @ D_g      # ... and from dw_b = D_g [dp_gyro, deta]
    return F


def transitions(Cs, f_b, D_a, D_g, dt, q, w_ie, g0):
    """Phi (m, n, n) = I + F dt + (F dt)^2 / 2 of every step (F constant over it) and the noise's
    Q (m, 6, 6) = G diag(q dt) G^T over it (it drives phi and dv only), vectorised."""
    n = 6 + D_a.shape[-1] + D_g.shape[-1]
    Fdt = system_matrices(Cs, f_b, D_a, D_g, w_ie, g0) * dt[:, None, None]
    G = gen.nav_G(Cs.reshape(len(Cs), 9))
    return np.eye(n) + Fdt + 0.5 * Fdt @ Fdt, (G * (q * dt[:, None])[:, None, :]) @ np.swapaxes(G, 1, 2)


def kalman(x, P, Phi_acc, Phi, Q6, zupt, v_at, R, t_s, epochs):
    """The filter over the steps: x <- Phi x, P <- Phi P Phi^T + Q, and at each update (zupt) the
    zero-velocity update of `update`, recorded in epochs; Phi_acc the transition since the last.
    Returns (x, P, Phi_acc) at the end."""
    n = len(P)
    for k in range(len(Phi)):
        x = Phi[k] @ x
        P = Phi[k] @ P @ Phi[k].T
        P[:6, :6] += Q6[k]
        Phi_acc = Phi[k] @ Phi_acc
        if zupt[k]:
            x, P = update(x, P, v_at[k], R, Phi_acc, t_s[k], epochs)
            Phi_acc = np.eye(n)
    return x, P, Phi_acc


def update(x_pred, P_pred, v, R, Phi, t_s, epochs):
    """The update by v = 0 (z = v_nominal = dv + noise, H = [0 I 0], R (3, 3)) in Joseph form, the
    epoch recorded; then the nominal velocity's reset to 0 (dv shifted by the same)."""
    n = len(P_pred)
    H = np.zeros((3, n))
    H[:, :6] = gen.H
    nu = v - H @ x_pred                               # z - H x_pred
    S = H @ P_pred @ H.T + R                          # innovation covariance
    K = np.linalg.solve(S, H @ P_pred).T              # K = P H^T S^-1
    x = x_pred + K @ nu
    IKH = np.eye(n) - K @ H
    P = IKH @ P_pred @ IKH.T + K @ R @ K.T            # Joseph form
    x[3:6] -= v                                       # the reset: dv = v_nominal - v
    epochs.append(Epoch(Phi, P_pred, P, x_pred, x, nu, S, t_s))
    return x, P


def smooth(epochs) -> tuple[np.ndarray, np.ndarray]:
    """The RTS smoother over the epochs: (x_s (m, n), P_s (m, n, n)):
        A_k = P_k|k Phi_k+1^T P_k+1|k^-1
        x_k|N = x_k|k + A_k (x_k+1|N - x_k+1|k)
        P_k|N = P_k|k + A_k (P_k+1|N - P_k+1|k) A_k^T"""
    m, n = len(epochs), len(epochs[-1].P)
    x_s, P_s = np.empty((m, n)), np.empty((m, n, n))
    x_s[-1], P_s[-1] = epochs[-1].x, epochs[-1].P
    for k in range(m - 2, -1, -1):
        nxt = epochs[k + 1]
        d = np.sqrt(np.diag(nxt.P_pred))  # P_pred spans ~20 decades: solved as the correlation matrix
        A = (np.linalg.solve(nxt.P_pred / np.outer(d, d), (nxt.Phi @ epochs[k].P) / d[:, None]) / d[:, None]).T
        x_s[k] = epochs[k].x + A @ (x_s[k + 1] - nxt.x_pred)
        P_s[k] = epochs[k].P + A @ (P_s[k + 1] - nxt.P_pred) @ A.T
    return x_s, P_s


def level(C, f_b):
    """C corrected so that C f_b points up (the least rotation): the accelerometers' levelling."""
    f_n = C @ f_b
    axis = np.cross(f_n / np.linalg.norm(f_n), [0.0, 0.0, 1.0])
    s = np.linalg.norm(axis)
    return C if s < 1e-15 else exp_so3(axis / s * np.arcsin(min(s, 1.0))) @ C
