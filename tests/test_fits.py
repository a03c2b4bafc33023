"""Exact and linear norm fits against noise-free data made with exact rotations."""
import os

import numpy as np
import pytest
import sympy as sp
from simucal.derive import norm
from simucal.derive.frames import N_out
from simucal.derive.models.baseline import ACC_BASELINE
from simucal.generated import table

from simucal.errors import CalibrationError
from simucal.fit.aux_inputs import AuxInputs
from simucal.fit.catalog import load
from simucal.fit.norm_fit import Observations, fit_exact, fit_linear
from simucal.turntable import plans

P_ACC = np.array([0.002, 0.008, 0.006, 1e-4, 1e-4, 1e-4, 8e-4, -1e-3, -3.2e-3])


def directions(plan, errors=None, seed=0):
    """Gravity directions in k from the exact table with random errors."""
    ang = np.radians(np.array(plan))
    err = np.random.default_rng(seed).normal(size=(len(plan), 7)) * 1e-3 if errors is None else errors
    C = table.C_k_n(ang[:, 0], ang[:, 1], ang[:, 2], err)
    return C[:, 2, :]


def test_exact_recovers_baseline_to_1e10():
    m = load("acc_baseline")
    u = directions(plans.TABLE1)
    fit = fit_exact(m, Observations(m.output(u, P_ACC), np.ones(12)))
    assert np.max(np.abs(fit.vector(m.params) - P_ACC)) < 1e-10


def test_exact_recovers_model_with_extra_terms_to_1e10():
    m = load("acc_extended")
    u = directions(plans.fibonacci(48))
    t = np.arange(48) * 20.0
    p = np.r_[P_ACC, 3e-5, -2e-5, 4e-7]
    aux = AuxInputs({"t_s": t})
    fit = fit_exact(m, Observations(m.output(u, p, aux), np.ones(48), aux=aux))
    assert np.max(np.abs(fit.vector(m.params) - p)) < 1e-10


def test_linear_error_agrees_with_derived_remainder():
    """The paper's regression is exact but for the derived remainder R(N):
    its K error must equal the least-squares image of R."""
    m = load("acc_baseline")
    reg = norm.derive_norm_regression(ACC_BASELINE)
    u = directions(plans.TABLE1)
    N = m.output(u, P_ACC)
    R = sp.lambdify([list(N_out), list(ACC_BASELINE.params)], reg.norm_sq_exact - reg.norm_sq_first, "numpy")
    rem = np.array([R(list(n), list(P_ACC)) for n in N])
    Psi = m.norm_regressors(N)
    K_true = m.module.K_of_params(P_ACC)
    K_fit, *_ = np.linalg.lstsq(Psi, np.ones(12), rcond=None)
    predicted = np.linalg.lstsq(Psi, rem, rcond=None)[0]
    assert np.max(np.abs(predicted)) > 1e-8  # the remainder is not trivially zero
    np.testing.assert_allclose(K_fit - K_true, predicted, rtol=1e-6, atol=1e-14)
    lin = fit_linear(m, Observations(N, np.ones(12)))
    assert np.max(np.abs(lin.vector(m.params) - P_ACC)) < 1e-4  # first order is close, not exact


def test_refuses_too_few_positions():
    m = load("acc_baseline")
    u = directions(plans.TABLE1[:8])
    try:
        fit_exact(m, Observations(m.output(u, P_ACC), np.ones(8)))
    except CalibrationError as e:
        assert "8 acc positions for 9 parameters" in str(e)
    else:
        raise AssertionError("no refusal")


def test_refuses_coplanar_plan():
    m = load("acc_baseline")
    a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    u = np.stack([np.zeros(16), np.sin(a), np.cos(a)], 1)  # all gravity directions in the y-z plane
    for fit in (fit_linear, fit_exact):
        try:
            fit(m, Observations(m.output(u, P_ACC), np.ones(16)))
        except CalibrationError as e:
            assert "unobservable" in str(e)
        else:
            raise AssertionError(f"{fit.__name__} accepted a coplanar plan")


def test_generated_plans_hit_their_directions():
    u = directions(plans.dodecahedron(), errors=np.zeros((20, 7)))
    cosines = u @ u.T
    nearest = np.sort(cosines, axis=1)[:, -2]  # each vertex's nearest neighbour
    assert np.allclose(nearest, nearest[0]) and np.isclose(np.arccos(nearest[0]), np.arccos(np.sqrt(5) / 3))
    m = load("acc_baseline")
    fit = fit_exact(m, Observations(m.output(u, P_ACC), np.ones(20)))
    assert np.max(np.abs(fit.vector(m.params) - P_ACC)) < 1e-10


def test_exact_fit_starts_from_raw_count_offsets():
    """Offsets of 8 g and scale errors of 5 % (raw counts over a nominal scale):
    the paper's first-order regression cannot start this, the quadric can."""
    m = load("acc_baseline")
    rng = np.random.default_rng(0)
    u = rng.normal(size=(30, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    p = np.array([0.05, -0.03, 0.02, 0.01, -0.02, 0.015, 8.1, 8.2, 7.9])
    fit = fit_exact(m, Observations(m.output(u, p), np.ones(30)))
    assert np.max(np.abs(fit.vector(m.params) - p)) < 1e-9


@pytest.mark.parametrize("name,sensor", [("acc_baseline", "acc"), ("gyro_baseline", "gyro")])
def test_compiled_whole_fit_matches_the_python_solver(tmp_path, name, sensor):
    """One compiled call (derive/templates/exact_fit.c) gives the Python Gauss-Newton's solution
    (to 1e-5 of each std: both stop within 1e-6 std of the optimum) and its covariance, for one
    set and for a batch."""
    from simucal import io
    from simucal.fit.catalog import load
    from simucal.fit.norm_fit import fit_exact
    from simucal.turntable.observations import segment_observations
    from simucal.turntable.simulate import Scenario, write
    c, py = load(name), load(name, compiled=False)
    if os.environ.get("SIMUCAL_NO_COMPILE"):  # the fallback by request: no compiled fit, the Python one
        assert c.backend == "numpy" and c.fit_compiled(None, None, None, None, None) is None
        return
    assert c.backend == "casadi-c"
    sets = []
    for seed in range(3):
        write(tmp_path / str(seed), Scenario(plan="fibonacci24"), seed)
        sets.append(segment_observations(io.read_set(tmp_path / str(seed)), sensor)[0])
    for obs in sets:  # both stop within 1e-6 std of the optimum (the convergence test): agree to 1e-5 std
        a, b = fit_exact(c, obs), fit_exact(py, obs)
        assert np.all(np.abs(a.vector(c.params) - b.vector(py.params)) < 1e-5 * np.sqrt(np.diag(b.cov)))
        assert np.allclose(a.cov, b.cov, rtol=1e-8, atol=0) and a.chi2 == pytest.approx(b.chi2, rel=1e-8)
    n = len(sets[0].N)
    batch_args = lambda sets: (np.array([o.N for o in sets]), np.array([o.rho for o in sets]),
                               np.array([np.broadcast_to(o.sigma, (n, 3)) for o in sets]),
                               np.array([c.aux_array(o.aux, (n,)) for o in sets]))
    batch = c.fit_compiled(*batch_args(sets), np.zeros((3, len(c.params))))
    assert np.all(batch[5] == 0)
    for k, obs in enumerate(sets):  # another start (zeros): the same optimum, to 1e-5 of each std
        ref = fit_exact(py, obs)
        assert np.all(np.abs(batch[0][k] - ref.vector(py.params)) < 1e-5 * np.sqrt(np.diag(ref.cov)))
    # the paper's linear start computed in the same call (p0 None), the estimates alone, one thread
    alone = c.fit_compiled(*batch_args(sets), None, covariance=False, threads=1)
    assert alone[1] is None and alone[3] is None and np.all(alone[5] == 0)
    for k, obs in enumerate(sets):
        ref = fit_exact(py, obs)
        assert np.all(np.abs(alone[0][k] - ref.vector(py.params)) < 1e-5 * np.sqrt(np.diag(ref.cov)))


def test_numpy_batch_equals_one_set_at_a_time(tmp_path):
    """gauss_newton.fit_batch on several sets at once gives each set's fit_exact (the numpy path)."""
    from simucal import io
    from simucal.fit.catalog import load
    from simucal.fit.norm_fit import fit_batch, fit_exact
    from simucal.turntable.observations import segment_observations
    from simucal.turntable.simulate import Scenario, write
    py = load("gyro_baseline", compiled=False)
    sets = []
    for seed in range(3):
        write(tmp_path / str(seed), Scenario(), seed)
        sets.append(segment_observations(io.read_set(tmp_path / str(seed)), "gyro")[0])
    n = len(sets[0].N)
    p, u, cost, H, it, status = fit_batch(py, np.array([o.N for o in sets]), np.array([o.rho for o in sets]),
                                          np.array([np.broadcast_to(o.sigma, (n, 3)) for o in sets]),
                                          np.zeros((3, len(py.params))))
    assert np.all(status == 0)
    for k, obs in enumerate(sets):
        ref = fit_exact(py, obs)
        assert np.all(np.abs(p[k] - ref.vector(py.params)) < 1e-5 * np.sqrt(np.diag(ref.cov)))
        assert cost[k] == pytest.approx(ref.chi2, rel=1e-8)


def test_a_large_offset_never_leaves_fit_exact_at_a_spurious_point():
    """Raw outputs with offsets of several g: the paper's linear start can be far off (or not finite), and a
    fit from it alone stops at a spurious point (chi2 1e6 dof); fit_exact then takes its other starts
    (a review once found 8 % of such sets failing)."""
    from simucal.fit.catalog import load
    from simucal.fit.norm_fit import Observations, fit_exact
    am = load("acc_baseline")
    rng = np.random.default_rng(7)
    for _ in range(60):
        n = int(rng.integers(12, 31))
        u = rng.normal(size=(n, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        p = np.r_[rng.normal(0, 0.2, 3), rng.normal(0, 0.02, 3), rng.normal(0, 8.0, 3)]
        obs = Observations(am.output(u, p) + rng.normal(0, 1e-3, (n, 3)), np.ones(n), np.full((n, 3), 1e-3))
        fit = fit_exact(am, obs)
        assert fit.chi2 < 3 * fit.dof + 20, (fit.chi2, fit.dof)


def test_a_solve_per_row_is_numpy_s_whether_the_rows_share_their_matrix_or_not():
    from simucal.fit.row_solve import inverse_rows, solve_rows
    rng = np.random.default_rng(3)
    M = np.eye(3) + 1e-2 * rng.standard_normal((3, 3))
    for shape in ((50,), (4, 50)):  # rows, and a batch of sets' rows
        shared = np.broadcast_to(M, (*shape, 3, 3)).copy()
        varied = shared + 1e-3 * rng.standard_normal(shared.shape)
        for B in (rng.standard_normal((*shape, 3, 12)), rng.standard_normal((*shape, 3, 1))):
            for A in (shared, varied):
                X = solve_rows(A, B)
                assert X.shape == B.shape
                np.testing.assert_allclose(X, np.linalg.solve(A, B), rtol=0, atol=1e-13)
                np.testing.assert_allclose(inverse_rows(A), np.linalg.inv(A), rtol=0, atol=1e-13)
    with pytest.raises(np.linalg.LinAlgError):  # a singular shared matrix is refused as numpy refuses it
        solve_rows(np.zeros((5, 3, 3)), np.ones((5, 3, 1)))
