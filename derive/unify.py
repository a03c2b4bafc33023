"""Frame unification (dong2018 section 2, eq. 13-27), first order and exact.

The accelerometer model lives in b, the gyro model in d; the table frame k is
the bridge. Static outputs at (gamma, alpha) with the inner axis at zero give
C_b^k and the outer-axis tilt (eq. 17, 25, 26); gyro outputs with the outer
axis turning give C_d^k (eq. 21, 27); then the gyro model in b (eq. 22-24):

    N^g = (I + L^g) C_k^d C_b^k omega^b + b^g   (exact),
    M^g = (I + L^g) C_b^d                        (eq. 23 is its first order).

Differences from the paper, found by deriving (see the audit):
- eq. 20/21 keep the horizontal Earth rate fixed in k; under outer-axis
  rotation it turns with gamma and averages out over whole revolutions, so
  the derived mean gyro input is (w_T + w_e sin L) C_n^k z.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from . import table
from .frames import UP, f_b, lat, skew, w_T, w_e
from .models import ErrorModel
from .norm import EPS

TABLE2 = [  # dong2018 Table 2: (alpha, gamma) in degrees, inner axis at zero
    (0, 0), (90, 0), (0, 180), (90, 180)]
GYRO_ALPHAS = (0, 90)  # the two middle-axis positions of section 3 for eq. 27

ACC_UNIFY_UNKNOWNS = (*table.theta4, table.tilt_x, table.tilt_y)
GYRO_UNIFY_UNKNOWNS = table.lambda4


def acc_input_b():
    """Exact f^b (g) at (gamma, alpha), inner at zero, no gimbal errors but tilt."""
    on_table = {table.beta: 0, table.nonperp_om: 0, table.nonperp_mi: 0,
                table.d_gamma: 0, table.d_alpha: 0, table.d_beta: 0}
    return (table.C_b_k().T * table.specific_force_k()).subs(on_table)


def gyro_mean_input_d():
    """Mean omega^d (deg/h) over whole outer-axis revolutions at middle angle alpha.

    omega^k(t) = C_n^k(t) (omega_ie^n + w_T z): the vertical parts are constant
    and the horizontal Earth rate turns with gamma, averaging to zero. Tilt is
    neglected here (its effect is w_e cos L * tilt, below 1e-3 deg/h).
    """
    axis_k = (table.rot_x(table.alpha)).T * UP
    return table.C_d_k().T * (w_T + w_e * sp.sin(lat)) * axis_k


def _first_order(expr, small):
    sub = {s: EPS * s for s in small}
    e = expr.subs(sub, simultaneous=True)
    return sp.expand(e.subs(EPS, 0) + sp.diff(e, EPS).subs(EPS, 0))


@dataclass
class Linearised:
    exact: sp.Matrix     # exact outputs
    first: sp.Matrix     # first-order outputs (eq. 17 or 21)
    small: tuple         # the quantities treated as small


def _outputs(model: ErrorModel, u, unknowns) -> Linearised:
    exact = model.output().subs(dict(zip(model.inputs, u)), simultaneous=True)
    small = model.params + unknowns
    return Linearised(exact, exact.applyfunc(lambda e: _first_order(e, small)), small)


def acc_outputs(model: ErrorModel) -> Linearised:
    """eq. 17: accelerometer outputs at table angles, exact and first order."""
    return _outputs(model, acc_input_b(), ACC_UNIFY_UNKNOWNS)


def gyro_outputs(model: ErrorModel) -> Linearised:
    """eq. 21 (corrected for the averaging of Earth rate): mean gyro outputs."""
    return _outputs(model, gyro_mean_input_d(), GYRO_UNIFY_UNKNOWNS)


def solve_at_positions(lin: Linearised, positions, unknowns, outputs):
    """Least-squares solution of the first-order outputs for the unknowns.

    positions: list of dicts {symbol: value}; outputs: a 3-vector of symbols
    per position (the measured outputs). Returns {unknown: expression in the
    measured outputs and the model's parameters} (eq. 25-27 when the model's
    other parameters are known from the norm step).
    """
    eqs = []
    for pos, meas in zip(positions, outputs):
        row = lin.first.subs(pos)
        for i in range(3):
            eqs.append(sp.expand(row[i] - meas[i]))
    A, rhs = sp.linear_eq_to_matrix(eqs, unknowns)
    if A.rank() < len(unknowns):
        raise ValueError(f"positions leave some of {unknowns} unobservable")
    # Solve only on the equations that carry the unknowns: the others hold
    # parameters the norm step already fixed.
    keep = [i for i in range(A.rows) if any(A[i, j] != 0 for j in range(A.cols))]
    A, rhs = A.extract(keep, list(range(A.cols))), rhs.extract(keep, [0])
    sol = (A.T * A).LUsolve(A.T * rhs)
    return {u: sp.factor_terms(sp.simplify(s)) for u, s in zip(unknowns, sol)}


def measured(prefix, n):
    return [sp.Matrix(sp.symbols(f"{prefix}{j}_x {prefix}{j}_y {prefix}{j}_z", real=True))
            for j in range(1, n + 1)]


def acc_table2_solution(model: ErrorModel):
    """eq. 25-26: mounting angles theta_4 and outer-axis tilt from Table 2."""
    pos = [{table.alpha: sp.rad(a), table.gamma: sp.rad(c)} for a, c in TABLE2]
    return solve_at_positions(acc_outputs(model), pos, ACC_UNIFY_UNKNOWNS, measured("Na", 4))


def gyro_unify_solution(model: ErrorModel):
    """eq. 27: gyro mounting angles lambda_4 from the alpha = 0 and 90 deg rate runs."""
    pos = [{table.alpha: sp.rad(a)} for a in GYRO_ALPHAS]
    return solve_at_positions(gyro_outputs(model), pos, GYRO_UNIFY_UNKNOWNS, measured("Ng", 2))


def gyro_matrix_in_b(model: ErrorModel):
    """eq. 22-24: M^g such that N^g = M^g omega^b + B^g, exact and first order."""
    A = model.output().jacobian(model.inputs).subs({s: 0 for s in model.inputs})
    C_b_d = table.C_d_k().T * table.C_b_k()
    exact = A * C_b_d
    small = model.params + table.theta4 + table.lambda4
    return exact, exact.applyfunc(lambda e: _first_order(e, small))



# The exact unification's pairs (simucal/turntable/unification.py): each pair joins a direction in b
# (u_b: a calibrated specific force f_b / |f_b|) and one in d (u_d: the gyro fit's), tied by
# C = C0 (I + [phi x]). The derivatives below carry every input's error (the fits' parameters and
# directions, the rate runs' mean outputs) into the pair's misfit and into phi.
u_b = sp.Matrix(sp.symbols("ub_x ub_y ub_z", real=True))
u_d = sp.Matrix(sp.symbols("ud_x ud_y ud_z", real=True))
C0 = sp.Matrix(3, 3, sp.symbols("C_0:3_0:3", real=True))   # C_b^d at the solution, row-major
phi = sp.Matrix(sp.symbols("phi_x phi_y phi_z", real=True))
E_m = sp.Matrix(3, 2, sp.symbols("E_0:3_0:2", real=True))  # row-major


def direction_jacobian():
    """d u_b / d f_b, u_b = f_b / |f_b|: how an error of a calibrated specific force turns its direction
    (the part along f_b changes only its norm)."""
    return sp.simplify((f_b / f_b.norm()).jacobian(f_b))


def _at_zero(expr):
    return expr.subs({s: 0 for s in phi})


def pair_misfit_jacobians():
    """A pair's misfit r = E_m^T (u_d - C0 (I + [phi x]) u_b) and its derivatives in u_b, u_d, phi at
    phi = 0. E_m: two orthonormal columns perpendicular to the bisector m of u_d and C0 u_b. For unit
    vectors u_d - C0 u_b is perpendicular to m exactly, so r holds all of the misfit in 2 components; in
    3 its covariance would be singular along m only to first order (rank 2 plus a sliver of the misfit's
    size, which a pseudo-inverse reads as a third, nearly noiseless component)."""
    r = E_m.T * (u_d - C0 * (sp.eye(3) + skew(phi)) * u_b)
    return tuple(_at_zero(r.jacobian(x)) for x in (u_b, u_d, phi))


def wahba_terms():
    """One pair's share of Wahba's problem min sum_i w_i c_i, c = |u_d - C0 R(phi) u_b|^2 / 2 with R(phi) =
    exp([phi x]) to second order (the Hessian at the misfit's own size needs it): with g = dc/dphi, at
    phi = 0, (dg/dphi, dg/du_b, dg/du_d). At the solution sum_i w_i g_i = 0, so to first order
    dphi = -(sum w dg/dphi)^-1 sum w (dg/du_b du_b + dg/du_d du_d)."""
    v = u_d - C0 * (sp.eye(3) + skew(phi) + skew(phi) ** 2 / 2) * u_b
    g = sp.Matrix([(v.T * v)[0, 0] / 2]).jacobian(phi).T
    return tuple(_at_zero(g.jacobian(x)) for x in (phi, u_b, u_d))
