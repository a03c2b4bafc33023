"""The derivations checked by a second route.

tests/test_generated.py holds generated/ equal to the SymPy expressions it was printed from: that
catches printing, not derivation. Here each derived quantity is computed another way, with numpy and
scipy alone, and each check is shown failing on one planted derivation error (the `mutated` tests):
- the table's C_k^n by elementary rotations composed in the gimbals' order (scipy.spatial.transform),
  and its outer axis by averaging a vector fixed in n over a whole revolution;
- the filter's F (nav_F, nav_B) by finite differences of two strapdown mechanisations, the true and
  the computed, whose attitude and velocity differences are the error states;
- the RTS smoother (systematic/filter.smooth) against the batch least-squares solution of the same
  linear problem (initial state and process noises as unknowns);
- the norm regressors psi(N) . K(p) against |h^-1(N)|^2, the input recovered from the output by
  Newton's method: equal to first order in p, so their difference falls 4x when p is halved;
- the models' outputs against the simulators' own forward model, written by hand from the physics
  (turntable/forward.py), which the turntable's and the sequences' simulators write their sets with.
"""
from dataclasses import replace

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

from simucal.derive import systematic as dsys
from simucal.derive import table as dtable
from simucal.derive.frames import N_out
from simucal.derive.norm import derive_norm_regression
from simucal.derive.registry import BUILTIN
from simucal.fit.catalog import load
from simucal.generated import systematic as gsys
from simucal.generated import table as gtable
from simucal.systematic.filter import kalman, smooth

# --- the table ---------------------------------------------------------------------------------

def _about(axis, angle):
    return Rotation.from_rotvec(angle * np.eye(3)["xyz".index(axis)])


def table_by_rotations(gamma, alpha, beta, errors):
    """C_k^n composed from elementary rotations (derive/table.py's module doc, in words): the tilt
    about n's x then y, the outer axis about z, the middle gimbal's non-perpendicularity about y, the
    middle axis about x, the inner gimbal's about z, the inner axis about y."""
    tx, ty, om, mi, dg, da, db = errors
    R = (_about("x", tx) * _about("y", ty) * _about("z", gamma + dg) * _about("y", om) * _about("x", alpha + da)
         * _about("z", mi) * _about("y", beta + db))
    return R.as_matrix()


def table_error(C_k_n, outer_axis_k) -> float:
    """The largest difference between a derivation's C_k^n and outer axis and the second route's, over
    random angles and errors (errors up to 0.05 rad: large, so that a wrong order shows)."""
    worst, rng = 0.0, np.random.default_rng(7)
    for _ in range(20):
        g, a, b = rng.uniform(-np.pi, np.pi, 3)
        e = rng.normal(scale=0.05, size=7)
        worst = max(worst, np.abs(C_k_n(g, a, b, e) - table_by_rotations(g, a, b, e)).max())
        # over a whole revolution of the outer axis a vector fixed in n averages, in k, to the outer axis
        # times the vector's component along it (the rate runs' mean input direction)
        v = rng.normal(size=3)
        turns = np.linspace(0, 2 * np.pi, 64, endpoint=False)
        mean_k = np.mean([table_by_rotations(t, a, b, e).T @ v for t in turns], axis=0)
        up_n = _about("x", e[0]).as_matrix() @ _about("y", e[1]).as_matrix() @ [0, 0, 1]
        worst = max(worst, np.abs(outer_axis_k(a, b, e) * (up_n @ v) - mean_k).max())
    return worst


def _generated_table():
    return (lambda g, a, b, e: gtable.C_k_n(g, a, b, np.asarray(e)),
            lambda a, b, e: np.ravel(gtable.outer_axis_k(a, b, np.asarray(e))))


def _derived_table():
    """C_k_n and outer_axis_k lambdified from derive/table.py as it stands (patched in a mutation test)."""
    args = (dtable.gamma, dtable.alpha, dtable.beta, dtable.TABLE_ERRORS)
    C = sp.lambdify(args, dtable.C_k_n(), "numpy")
    axis = sp.lambdify(args[1:], dtable.outer_axis_k(), "numpy")
    return (lambda g, a, b, e: np.array(C(g, a, b, e), float),
            lambda a, b, e: np.array(axis(a, b, e), float).ravel())


def test_the_table_by_elementary_rotations():
    assert table_error(*_generated_table()) < 1e-12


def test_the_table_check_fails_on_a_planted_derivation_error(monkeypatch):
    """The middle gimbal's non-perpendicularity applied after its axis instead of before."""
    assert table_error(*_derived_table()) < 1e-12
    monkeypatch.setattr(dtable, "gimbals", lambda: dtable.rot_x(dtable.alpha + dtable.d_alpha) * dtable.rot_y(
        dtable.nonperp_om) * dtable.rot_z(dtable.nonperp_mi) * dtable.rot_y(dtable.beta + dtable.d_beta))
    assert table_error(*_derived_table()) > 1e-3


# --- the filter's F ----------------------------------------------------------------------------

RAD_S_PER_DPH = np.pi / 180 / 3600


def mechanised(C0, v0, w_b_dph, f_b_g, w_ie, g0, h):
    """Attitude C_b^n and velocity after h seconds of a strapdown mechanisation at a fixed place (the
    rates constant): dC/dt = C [w_b x] - [w_ie x] C, dv/dt = C f_b g0 - 2 w_ie x v + g^n, by the exact
    rotations and a midpoint step for v (h small)."""
    turn_n = Rotation.from_rotvec(-np.asarray(w_ie) * h).as_matrix()
    turn_b = Rotation.from_rotvec(np.asarray(w_b_dph) * RAD_S_PER_DPH * h).as_matrix()
    C = turn_n @ C0 @ turn_b
    C_mid = Rotation.from_rotvec(-np.asarray(w_ie) * h / 2).as_matrix() @ C0 @ Rotation.from_rotvec(
        np.asarray(w_b_dph) * RAD_S_PER_DPH * h / 2).as_matrix()
    v_mid = v0 + h / 2 * (C0 @ f_b_g * g0 - 2 * np.cross(w_ie, v0) - [0, 0, g0])
    return C, v0 + h * (C_mid @ f_b_g * g0 - 2 * np.cross(w_ie, v_mid) - [0, 0, g0])


def error_rates(C, f_b, w_b, w_ie, g0, x, e, h=1e-4) -> np.ndarray:
    """d[phi, dv]/dt at t = 0 by central differences in time of the computed navigation (started at
    C_computed = exp(-[phi x]) C_true, v + dv, reading the sensors with errors e = [dw (deg/h), df (g)])
    against the true one (no errors): C_computed C_true^T = exp(-[phi x]), dv = v_computed - v_true."""
    phi, dv = x[:3], x[3:]
    Cc0 = Rotation.from_rotvec(-phi).as_matrix() @ C

    def errors_at(t):
        Ct, vt = mechanised(C, np.zeros(3), w_b, f_b, w_ie, g0, t)
        Cc, vc = mechanised(Cc0, dv, w_b + e[:3], f_b + e[3:], w_ie, g0, t)
        return np.r_[-Rotation.from_matrix(Cc @ Ct.T).as_rotvec(), vc - vt]
    return (errors_at(h) - errors_at(-h)) / (2 * h)


def filter_error(nav_F, nav_B) -> float:
    """The largest difference between a derivation's F and B and their finite differences, each 3 x 3
    block relative to its own largest entry (rates and Earth rate scaled up so that every entry is well
    above round-off)."""
    worst, rng = 0.0, np.random.default_rng(8)
    for _ in range(3):
        C = Rotation.random(random_state=rng.integers(1 << 31)).as_matrix()
        f_b, w_b, w_ie, g0 = rng.normal(size=3), rng.normal(size=3) * 1e4, rng.normal(size=3) * 0.05, 9.8
        eps = 1e-5
        x_cols = [(error_rates(C, f_b, w_b, w_ie, g0, eps * k, np.zeros(6)) -
                   error_rates(C, f_b, w_b, w_ie, g0, -eps * k, np.zeros(6))) / (2 * eps) for k in np.eye(6)]
        e_cols = [(error_rates(C, f_b, w_b, w_ie, g0, np.zeros(6), k * s) -
                   error_rates(C, f_b, w_b, w_ie, g0, np.zeros(6), -k * s)) / (2 * s)
                  for k, s in zip(np.eye(6), [10.0] * 3 + [1e-4] * 3)]
        for derived, numeric in ((nav_F(C, f_b, w_ie, g0), np.array(x_cols).T), (nav_B(C, g0), np.array(e_cols).T)):
            for i in (0, 3):  # each 3 x 3 block against its own scale (the Coriolis block is the smallest)
                for j in (0, 3):
                    d, n = derived[i:i + 3, j:j + 3], numeric[i:i + 3, j:j + 3]
                    worst = max(worst, np.abs(d - n).max() / max(np.abs(n).max(), 1e-6 * np.abs(numeric).max()))
    return worst


def _generated_filter():
    return (lambda C, f_b, w_ie, g0: gsys.nav_F(C.reshape(9), f_b, w_ie, g0),
            lambda C, g0: gsys.nav_B(C.reshape(9), g0))


def _derived_filter(rates):
    C, f_b, w_ie = list(dsys.C), list(dsys.f_b), list(dsys.w_ie)
    F = sp.lambdify((C, f_b, w_ie, dsys.g0), rates.jacobian(sp.Matrix(dsys.NAV_STATES)), "numpy")
    B = sp.lambdify((C, dsys.g0), rates.jacobian(sp.Matrix.vstack(dsys.dw, dsys.df)), "numpy")
    return (lambda C, f_b, w_ie, g0: np.array(F(C.ravel(), f_b, w_ie, g0), float),
            lambda C, g0: np.array(B(C.ravel(), g0), float))


def test_the_filters_F_by_finite_differences_of_the_mechanisation():
    assert filter_error(*_generated_filter()) < 1e-5


def test_the_filter_check_fails_on_a_planted_derivation_error():
    """The Coriolis term's factor 2 taken as 1 (the transport rate's form, wrong at a fixed place)."""
    rates = dsys.navigation_rates()
    assert filter_error(*_derived_filter(rates)) < 1e-5
    planted = rates + sp.Matrix.vstack(sp.zeros(3, 1), dsys.w_ie.cross(dsys.dv))
    assert filter_error(*_derived_filter(planted)) > 0.1


# --- the RTS smoother --------------------------------------------------------------------------

def a_problem(m=6, n_par=3, seed=3):
    """A small random instance of the filter's linear problem: transitions [[A, B], [0, I]] over m
    intervals, process noise Q on the 6 navigation states, zero-velocity measurements v_at with R."""
    r = np.random.default_rng(seed)
    A = np.eye(6) + 0.2 * r.normal(size=(m, 6, 6))
    B = 0.3 * r.normal(size=(m, 6, n_par))
    L = 0.1 * r.normal(size=(m, 6, 6))
    Q = L @ np.swapaxes(L, 1, 2) + 1e-3 * np.eye(6)
    R = np.diag(r.uniform(0.01, 0.05, 3))
    x0, P0 = r.normal(size=6 + n_par), np.diag(r.uniform(0.5, 2.0, 6 + n_par))
    return A, B, Q, R, x0, P0, r.normal(size=(m, 3))


def by_batch_least_squares(A, B, Q, R, x0, P0, v_at) -> np.ndarray:
    """Every epoch's state, after its update and before its reset, from one least-squares solve over the
    unknowns [x_start, w_1 .. w_m]: x_k = Phi_k (x_k-1 - reset_k-1) + [w_k, 0], each measurement
    v_k = dv_k + noise (H = [0 I 0]); the reset after each update subtracts v_k from dv (filter.update)."""
    m, n = len(A), len(x0)
    Phi = np.broadcast_to(np.eye(n), (m, n, n)).copy()
    Phi[:, :6, :6], Phi[:, :6, 6:] = A, B
    k_unknowns = n + 6 * m
    lin, off = np.zeros((n, k_unknowns)), np.zeros(n)  # x as a linear function of the unknowns
    lin[:, :n] = np.eye(n)
    rows, rhs, states = [np.linalg.cholesky(np.linalg.inv(P0)).T @ np.eye(n, k_unknowns)], \
        [np.linalg.cholesky(np.linalg.inv(P0)).T @ x0], []
    for k in range(m):
        lin, off = Phi[k] @ lin, Phi[k] @ off
        lin[:6, n + 6 * k:n + 6 * k + 6] += np.eye(6)
        W = np.linalg.cholesky(np.linalg.inv(Q[k])).T
        rows.append(W @ np.eye(6, k_unknowns, n + 6 * k))
        rhs.append(np.zeros(6))
        S = np.linalg.cholesky(np.linalg.inv(R)).T
        rows.append(S @ lin[3:6])
        rhs.append(S @ (v_at[k] - off[3:6]))
        states.append((lin.copy(), off.copy()))
        off = off.copy()
        off[3:6] -= v_at[k]
    u = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    return np.array([L @ u + o for L, o in states])


def smoother_error(smoother) -> float:
    A, B, Q, R, x0, P0, v_at = a_problem()
    epochs = []
    kalman(x0.copy(), P0.copy(), A, B, Q, v_at, R, np.arange(len(A), dtype=float), epochs)
    x_s = smoother(epochs)
    return float(np.abs(x_s - by_batch_least_squares(A, B, Q, R, x0, P0, v_at)).max())


def test_the_rts_smoother_equals_batch_least_squares():
    assert smoother_error(lambda ep: smooth(ep, covariance=False)[0]) < 1e-9


def test_the_smoother_check_fails_on_a_planted_error():
    """The smoother's gain with Phi_k (the interval before the epoch) in place of Phi_k+1."""
    wrong = lambda ep: smooth([replace(e, Phi=ep[max(k - 1, 0)].Phi) for k, e in enumerate(ep)], covariance=False)[0]
    assert smoother_error(wrong) > 1e-3


# --- the norm regressors -----------------------------------------------------------------------

def inverse(output, N, p, aux):
    """u with output(u, p) = N, by Newton's method from u = N (the output's Jacobian in u by differences)."""
    u = N.copy()
    for _ in range(30):
        J = np.column_stack([(output(u + 1e-7 * k, p, aux) - output(u - 1e-7 * k, p, aux)) / 2e-7 for k in np.eye(3)])
        du = np.linalg.solve(J, N - output(u, p, aux))
        u = u + du
        if np.abs(du).max() < 1e-15:
            break
    return u


def regression_orders(gen, psi, K_of_p) -> list[float]:
    """For each of 5 random outputs and parameter vectors p: err(p) / err(p / 2), err the difference
    between psi(N) . K(p) and |h^-1(N)|^2. The regression holds to first order in p, so a right
    derivation gives about 4 (the error is second order); a wrong column leaves a first-order error (2)."""
    ratios, rng = [], np.random.default_rng(9)
    for _ in range(5):
        N, p = rng.normal(size=3), rng.normal(size=len(gen.params)) * 1e-3
        aux = np.zeros(len(gen.aux))
        err = [abs(psi(N, aux) @ K_of_p(q) - np.sum(inverse(gen.module.output, N, q, aux) ** 2)) for q in (p, p / 2)]
        ratios.append(err[0] / err[1])
    return ratios


def _derived_norm(model, reg):
    psi = sp.lambdify((N_out, model.aux), reg.psi, "numpy")
    K = sp.lambdify((model.params,), reg.K_of_p, "numpy")
    return lambda N, aux: np.array(psi(N, aux), float).ravel(), lambda p: np.array(K(p), float).ravel()


@pytest.mark.parametrize("model", [m for m in BUILTIN if m.name.endswith("baseline")], ids=lambda m: m.name)
def test_the_norm_regressors_against_the_inverted_output(model):
    gen = load(model.name, compiled=False)
    assert min(regression_orders(gen, gen.module.norm_regressors, gen.module.K_of_params)) > 3.5


def test_the_norm_check_fails_on_a_planted_derivation_error():
    """The cross term N_x N_y's sign reversed in psi."""
    model = next(m for m in BUILTIN if m.name == "acc_baseline")
    gen, reg = load(model.name, compiled=False), derive_norm_regression(model)
    assert min(regression_orders(gen, *_derived_norm(model, reg))) > 3.5
    planted = list(reg.psi)
    planted[3] = -planted[3]
    assert max(regression_orders(gen, *_derived_norm(model, replace(reg, psi=planted)))) < 2.5


# --- the simulators' forward model -------------------------------------------------------------

def forward_error(derived_output, model_name="acc_baseline", effects=()) -> float:
    """The largest relative difference between the simulators' hand-written forward model
    (turntable/forward.py) and a derivation's output, at random inputs, parameters and auxiliary inputs."""
    from simucal.fit.augmented import AugmentedModel
    from simucal.fit.aux_inputs import AuxInputs
    from simucal.turntable import forward
    rng, n = np.random.default_rng(11), 9
    aux = AuxInputs({"t_s": rng.uniform(0, 100, n), "temp_c": rng.uniform(10, 40, n), "t_ref_c": 25.0,
                     "temp_rate_c_s": rng.normal(0, 0.05, n), "w2": rng.uniform(0, 0.1, n),
                     **{f"f_{c}": rng.normal(size=n) for c in "xyz"},
                     **{f"{q}_{c}": rng.normal(size=n) for q in ("wb", "dwb") for c in "xyz"}})  # lever arms, delay
    m = AugmentedModel(model_name, tuple(effects))
    worst = 0.0
    for _ in range(5):
        p = rng.normal(size=len(m.params)) * 1e-2
        u = rng.normal(size=(n, 3)) * (1.0 if m.sensor == "acc" else 36000.0)
        mine, theirs = forward.output(m, p, u, aux), derived_output(m, p, u, aux)
        worst = max(worst, float(np.abs(mine - theirs).max() / np.abs(theirs).max()))
    return worst


@pytest.mark.parametrize("sensor", ["acc", "gyro"])
def test_the_simulators_forward_model_is_their_own_and_equals_the_derivation(sensor):
    """The turntable's and the sequences' simulators write the outputs with a forward model written
    by hand (turntable/forward.py), not the fit's generated one; the two agree on every library effect."""
    from simucal.generated.effects import EFFECTS
    ids = [e for e in EFFECTS if EFFECTS[e].sensor == sensor]
    for chunk in (ids[i:i + 8] for i in range(0, len(ids), 8)):
        for base in (f"{sensor}_baseline", f"{sensor}_extended"):
            assert forward_error(lambda m, p, u, aux: m.output(u, p, aux), base, chunk) < 1e-12


def test_the_forward_check_fails_on_a_planted_derivation_error():
    """The misalignment theta_yx read off the wrong input (u_y for u_x) in the accelerometer's model."""
    from simucal.derive.models.baseline import ACC_BASELINE

    def derived(model, mutate=False):
        terms = list(model.terms)
        if mutate:
            k = next(i for i, t in enumerate(terms) if t.name == "theta_yx")
            terms[k] = replace(terms[k], regressor=model.inputs[1])
        out = sp.lambdify((model.inputs, model.params), replace(model, terms=tuple(terms)).output(), "numpy")
        return lambda m, p, u, aux: np.column_stack([np.broadcast_to(np.asarray(c, float).ravel(), (len(u),))
                                                     for c in out(u.T, p)])
    assert forward_error(derived(ACC_BASELINE)) < 1e-12
    assert forward_error(derived(ACC_BASELINE, mutate=True)) > 1e-4
