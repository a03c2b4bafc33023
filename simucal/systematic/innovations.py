"""The filter's innovations as the loop's evidence: the model test (NIS, whiteness, and the candidates'
targeted tests with it: fit/family.py) and the candidate effects scored on them, through the project's one ranking
(fit/ranking.py).

The zero-velocity innovations of a linear(ised) Kalman filter are its data whitened in time order
(the innovations form of the likelihood, Schweppe 1965): with the parameters held at their estimates
and only the navigation errors (phi, dv) filtered, the stacked innovations L_k^-1 nu_k (S_k = L_k L_k^T)
are the whitened residual r of a least-squares problem in the parameters, and the sensitivity of
those innovations to a parameter theta is its whitened column. It follows the filter's recursion
(Willsky & Jones 1976, the generalised likelihood ratio's signature):

    mu <- Phi_nn mu + Gamma_k        over each step (Gamma_k = d[phi, dv] / d theta over the step)
    g_k = H mu,   mu <- mu - K_k g_k  at each update,      column = [L_k^-1 g_k]_k

The model's own parameters (and the frame angles eta) give the basis, each library effect not in the
model a candidate column; projecting the basis out of the residual leaves the innovations of the
filter that estimates them (their squared norm is its NIS, less the prior's term), and a candidate's
projected column is the signature that filter would see. A candidate's likelihood ratio is then
(col . r)^2 / |col|^2 on 1 dof, its estimate and std the one Gauss-Newton step of the filter with
its state added: the score test of adding it, which --add auto confirms by running that filter.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from simucal.fit.augmented import AugmentedModel, effect_ids, follows_temperature
from simucal.fit.aux_inputs import AuxInputs, motion
from simucal.fit import family
from simucal.fit.distributions import chi2_sf
from simucal.fit.ranking import Trial, rank
from simucal.fit.row_solve import inverse_rows
from simucal.fit.results import ModelTest
from simucal.generated import systematic as gen
from simucal.generated import table
from simucal.generated.effects import EFFECTS, SEPARATE
from simucal.io import records, units
from simucal.systematic.calibrate import ZUPT_STD_MPS
from simucal.systematic.filter import (Sensors, lapack_solve, nominal, prefix_products, reads_motion, smoothed,
                                      transitions)


class WhitenedTest(records.InnovationTest, total=False):
    """The innovations' test (innovation_test) with the whitened innovations it was taken on."""
    innovations_whitened: NDArray[np.float64]  # (updates, 3): L^-1 nu of each zero-velocity update, unitless


def innovation_test(epochs) -> WhitenedTest:
    """The model test on the innovations: NIS, the sum of nu^T S^-1 nu over the zero-velocity updates
    and the zero-position returns (a return's attitude innovation, zero_position.py), against chi-square
    with 3 dof per update (Bar-Shalom, Li & Kirubarajan 2001, sec. 5.4), and the zero-velocity
    innovations' whiteness: each axis's lag-1 autocorrelation of the whitened innovations (L^-1 nu,
    S = L L^T), about N(0, 1/m) for white ones."""
    updates = [e for e in epochs if e.nu is not None]
    L = np.linalg.cholesky(np.array([e.S for e in updates]))
    nu = np.linalg.solve(L, np.array([e.nu for e in updates])[..., None])[..., 0]
    m = len(nu)
    returns = [e for e in updates if e.nu_zero is not None]
    nis_zero = float(sum(e.nu_zero @ np.linalg.solve(e.S_zero, e.nu_zero) for e in returns))
    nis, dof = float((nu ** 2).sum()) + nis_zero, 3 * (m + len(returns))
    r1 = (nu[1:] * nu[:-1]).sum(0) / (nu ** 2).sum(0)
    return {"nis": nis, "dof": dof, "nis_per_update": nis / (m + len(returns)), "p_value": chi2_sf(nis, dof),
            "test": "NIS of the zero-velocity innovations" + (
                f" and of {len(returns)} zero-position returns" if returns else "") + " (chi-square, 3 dof per update)",
            "lag1_autocorrelation": r1.tolist(), "lag1_z": (r1 * np.sqrt(m)).tolist(), "updates": m,
            "returns": len(returns), "nis_returns": nis_zero, "innovations_whitened": nu}


def family_test(result) -> tuple[WhitenedTest, Signatures]:
    """The sequence's model test (fit/family.py): the NIS (innovation_test) as the omnibus, with the
    targeted test of every candidate on the innovations (InnovationsProblem's score tests, the
    statistic its likelihood ratio already is). Returns the test and the signatures, which the
    ranking reuses."""
    test, sig = innovation_test(result.epochs), signatures(result)
    family.fold(test, family.targeted(InnovationsProblem(sig), list(sig.B)))
    return test, sig


def candidate_ids(sensors) -> tuple[str, ...]:
    """The library effects not in the models: the accelerometer's, then the gyro's. Those that read the
    temperature are left out: a sequence holds no temp_c column (simulate --sequence writes none)."""
    return tuple(e for s, model in (("acc", sensors.acc), ("gyro", sensors.gyro)) for e in effect_ids(s)
                 if e not in model.effects and not follows_temperature(e))


@dataclass
class Signatures:
    """The whitened least-squares view of the filter at its estimates (module doc): r (3m,) the
    navigation-only filter's whitened innovations, A (3m, k) the model's parameters' columns (eta's
    last), B {candidate id: (3m,)}, and per update its time (s) and innovation nu (m/s) with the std
    of each axis."""
    r: np.ndarray
    A: np.ndarray
    B: dict
    t_s: np.ndarray
    nu: np.ndarray
    nu_std: np.ndarray


def signatures(result, ids=None) -> Signatures:
    """The signatures of the model's parameters and of the candidates ids (default candidate_ids) over
    the last pass's steps, about the estimates of result (calibrate.run_filter's)."""
    s = result.sensors
    ids = candidate_ids(s) if ids is None else tuple(ids)
    acc_c, gyro_c = (tuple(e for e in ids if EFFECTS[e].sensor == x) for x in ("acc", "gyro"))
    big = Sensors(AugmentedModel(s.acc.base, s.acc.effects + acc_c),
                  AugmentedModel(s.gyro.base, s.gyro.effects + gyro_c),
                  np.r_[s.p_acc, np.zeros(len(acc_c))], np.r_[s.p_gyro, np.zeros(len(gyro_c))], s.eta)
    steps, q, w_ie, g0 = result.setting
    aux = AuxInputs({"t_s": steps.t})
    # the candidates at 0 add nothing to the inputs: the model's own inversion gives big's, bit for bit, at a
    # fraction of its cost; the candidates' regressors (lever arms) still read the motion
    f_b, w_b, aux_a = s.compensate(steps.N_a, steps.N_g, aux, aux, steps.dt)
    aux_a = aux.with_values(**motion(w_b, steps.dt)) if reads_motion(big.acc) else aux_a
    f_smooth, w_smooth = smoothed((f_b, w_b), steps.dt)
    factors = _factored(big, f_smooth, w_smooth, aux_a, aux)
    Cs, v_at = nominal(result.C, w_b * units.RAD_S_PER_DPH * steps.dt[:, None], f_b, steps.dt, steps.zupt, w_ie, g0)
    na, ng = len(s.p_acc), len(s.p_gyro)
    k = len(big.p_acc) + len(big.p_gyro)  # the columns: big's acc, gyro, then eta's 3
    own = list(range(na)) + [len(big.p_acc) + j for j in range(ng)] + list(range(k, k + 3))
    cand = [na + j for j in range(len(acc_c))] + [len(big.p_acc) + ng + j for j in range(len(gyro_c))]
    out = _navigation_pass(steps, Cs, v_at, f_b, factors, q, w_ie, g0, result.prior_var[:6])
    r, cols = out[0], out[1]
    return Signatures(r, cols[:, own], {e: cols[:, k] for e, k in zip(acc_c + gyro_c, cand)}, steps.t[steps.zupt],
                      out[2], out[3])


def _factored(sensors, f_b, w_b, aux_a, aux_g):
    """Sensors.sensitivities factored, D_a = M_a J_a and D_g = M_g J_g: (M_a, J_a, M_g, J_g), M (n, 3, 3) the inverted
    models' -A^-1 (the gyro's turned by C_b_d^T) and J their parameters' Jacobians (the gyro's with the frame angles'
    A S: -C^T A^-1 A S = -C^T S), so that the candidates' many columns are multiplied by a 3 x 3 once per step
    (`_summed`) rather than each solved."""
    _, Ju, J_a = sensors.acc.jacobians(f_b, sensors.p_acc, aux_a)
    M_a = -inverse_rows(Ju)
    C_b_d = table.mounting(sensors.eta)
    f_d = f_b @ C_b_d.T
    _, Ju, Jp = sensors.gyro.jacobians(w_b @ C_b_d.T, sensors.p_gyro,
                                       aux_g.with_values(f_x=f_d[:, 0], f_y=f_d[:, 1], f_z=f_d[:, 2]))
    S = gen.frame_rate_sensitivity(np.broadcast_to(sensors.eta, w_b.shape), w_b)
    return M_a, J_a, -C_b_d.T @ inverse_rows(Ju), np.concatenate([Jp, Ju @ S], axis=-1)


def _navigation_pass(steps, Cs, v_at, f_b, factors, q, w_ie, g0, P0_diag):
    """The filter of phi and dv alone (the parameters held) with every column's signature carried along (module
    doc), the sensitivities as `_factored`'s (M_a, J_a, M_g, J_g): (r (3m,), columns (3m, k), nu (m, 3), its std
    (m, 3)). The steps between two updates are composed into one transition: its A and Q from the steps'
    (filter.transitions), each column's Gamma the sum over the interval's steps of E_k B_k M_k J_k (`_to_update`,
    `_summed`), B_k the step's input matrix with the sensitivities factored out (transitions at unit
    sensitivities), so that the columns pass through one product per step rather than through compose's tree."""
    ends = np.flatnonzero(steps.zupt)
    k = slice(0, ends[-1] + 1)  # the steps after the last update see no data
    unit = np.broadcast_to(np.eye(3), (ends[-1] + 1, 3, 3))
    A, B, Q = transitions(Cs[k], f_b[k], unit, unit, steps.dt[k], q, w_ie, g0)
    E = _to_update(A, ends)
    W = E @ B
    starts = np.r_[0, ends[:-1] + 1]
    Phis = E[starts] @ A[starts]
    Qs = np.add.reduceat(E @ Q @ np.swapaxes(E, 1, 2), starts, axis=0)
    M_a, J_a, M_g, J_g = factors
    Gams = np.concatenate([_summed(W[..., :3] @ M_a[k], J_a[k], starts, ends),
                           _summed(W[..., 3:] @ M_g[k], J_g[k], starts, ends)], -1)
    r2 = ZUPT_STD_MPS ** 2
    R, I6 = np.eye(3) * r2, np.eye(6)
    x, P, mu, IKH = np.zeros(6), np.diag(P0_diag), np.zeros(Gams.shape[1:]), np.eye(6)
    S, nu, g = np.empty((len(ends), 3, 3)), np.empty((len(ends), 3)), np.empty((len(ends), 3, Gams.shape[-1]))
    for u, (Phi, Gk, Qk, v) in enumerate(zip(Phis, Gams, Qs, v_at[ends])):
        x, P, mu = Phi @ x, Phi @ P @ Phi.T + Qk, Phi @ mu + Gk
        S[u], nu[u], g[u] = P[3:, 3:] + R, v - x[3:], mu[3:]  # g: mu's dv rows, whitened at once after the loop
        K = lapack_solve(S[u], P[3:]).T
        IKH[:, 3:] = I6[:, 3:] - K
        x, P, mu = x + K @ nu[u], IKH @ P @ IKH.T + r2 * (K @ K.T), mu - K @ g[u]
        x[3:] -= v
    L = np.linalg.cholesky(S)
    return (np.linalg.solve(L, nu[..., None]).ravel(), np.concatenate(np.linalg.solve(L, g)), nu,
            np.sqrt(np.diagonal(S, axis1=1, axis2=2)))


def _to_update(A, ends):
    """E_k = A_j ... A_k+1 of every step k (m, n, n): the transition from the end of step k to the end of step j,
    the last of its interval (j = ends' next at or after k; the identity at j), by prefix products reversed."""
    E = np.empty_like(A)
    E[ends] = np.eye(A.shape[-1])
    starts = np.r_[0, ends[:-1] + 1]
    for i, j in zip(starts[starts < ends], ends[starts < ends]):
        E[i:j] = prefix_products(A[j:i:-1])[::-1]
    return E


def _summed(W, D, starts, ends):
    """Sum over each interval [start, end] of the steps' W_k D_k (W (m, a, b), D (m, b, c)): (intervals, a, c);
    a one-step interval (a rest's block) batched, a longer one (a move) one matrix product over its steps."""
    out = np.empty((len(ends), W.shape[1], D.shape[-1]))
    one = starts == ends
    out[one] = W[ends[one]] @ D[ends[one]]
    for u in np.flatnonzero(~one):
        i, j = starts[u], ends[u] + 1
        out[u] = np.tensordot(W[i:j], D[i:j], axes=([0, 2], [0, 1]))
    return out


class InnovationsProblem:
    """The filter's innovations as a ranking Problem (fit/ranking.py; module doc)."""
    span = "the filter's states (the model's parameters and the frame angles)"

    def __init__(self, sig: Signatures):
        self.sig = sig
        self.Q = np.linalg.qr(sig.A)[0]
        self.r = sig.r - self.Q @ (self.Q.T @ sig.r)

    def info(self, eid):
        return EFFECTS[eid].parameter, EFFECTS[eid].unit, EFFECTS[eid].meaning

    def basis(self):
        return self.Q

    def residual(self):
        return self.r, 1.0  # the noise is known (the rests' white noise, the filter's S)

    def column(self, eid):
        return self.sig.B[eid]

    def fit_with(self, eid):
        col = self.sig.B[eid]
        perp = col - self.Q @ (self.Q.T @ col)
        n2, g = float(perp @ perp), float(perp @ self.r)
        stat = g * g / n2
        # the column is the innovations' sensitivity to the state's error (estimate - truth), at an estimate of 0
        rms = float(np.sqrt(max(self.r @ self.r - stat, 0.0) / len(self.r)))
        return Trial(-g / n2, 1 / np.sqrt(n2), stat, float(chi2_sf(stat, 1)), stat - 2.0, rms)

    def to_see(self, eid):
        return "a sequence whose rests and moves vary its input: " + SEPARATE[eid.split(".")[1]]

    def to_separate(self, eid, twin):
        return to_separate(eid, twin)


def ranked(test, sig: Signatures) -> list:
    """The candidates (fit/results.Candidate) ranked on the innovations (fit/ranking.rank), with the
    signatures and test of family_test: diagnose's and --add auto's one ranking on a sequence."""
    return rank(InnovationsProblem(sig), list(sig.B), ModelTest(test["nis"], test["dof"], test["p_value"]).fails,
                "candidates on the innovations")


def to_separate(eid: str, twin: str) -> str:
    """What a sequence must hold to tell two candidates apart on the innovations (the ranking's twins
    and --add auto's twin choice)."""
    return f"a sequence whose rests and moves give {eid} and {twin} different signatures"
