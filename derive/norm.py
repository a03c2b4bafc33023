"""Norm observation (dong2018 section 1, eq. 3-12), derived for any error model.

The exact principle (eq. 3, 4): the input's norm is known (g at rest; the
table and Earth rate's norm under rotation) while its direction is not, so
|u(N, p)|^2 = rho^2 with u the input recovered from the output N.

The paper's linear method (eq. 6-8 and 10-12) expands |u|^2 keeping the
scale-factor errors exactly and every other parameter to first order, which
makes the norm linear in a new vector K:

    psi(N) . K(p) = rho^2          (eq. 7, 11: one row of N_s per position)

This module computes psi and K from the model, the exact inverse p(K) and its
first-order version, and the remainder the expansion neglects.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from .frames import AXES, N_out
from .models import ErrorModel

EPS = sp.Symbol("epsilon", positive=True)  # bookkeeping for "first order"


class NotIdentifiable(ValueError):
    """Two parameters enter the norm regression only as one combination."""


@dataclass
class NormRegression:
    model: ErrorModel
    K: list[sp.Symbol]          # K_1..K_m symbols
    K_of_p: list[sp.Expr]       # K_j(p)
    psi: list[sp.Expr]          # regressor columns psi_j(N, aux)
    p_of_K: dict                # exact inverse: parameter symbol -> expr in K
    p_of_K_first: dict          # first-order inverse around K(p = 0)
    norm_sq_first: sp.Expr      # psi . K(p): the linearised |u|^2
    norm_sq_exact: sp.Expr | None  # |u|^2 in closed form (models affine in u), else None


def scale_matrix(model: ErrorModel) -> sp.Matrix:
    """D = diag(1 + dK_i): the part of the model kept exactly."""
    D = sp.eye(3)
    for t in model.terms:
        if model.kind(t) == "scale":
            i = AXES.index(t.axis)
            D[i, i] += t.symbol
    return D


def first_order_input(model: ErrorModel, D_inv=None) -> sp.Matrix:
    """u(N) to first order in the non-scale terms (eq. 6, 10, generalised).

    N = D u + eps*s(u) gives u = D^-1 (N - eps*s(D^-1 N)) + O(eps^2).
    D_inv may be given as symbols so that the expansion stays polynomial.
    """
    D_inv = scale_matrix(model).inv() if D_inv is None else D_inv
    u0 = D_inv * N_out
    s = sp.zeros(3, 1)
    for t in model.terms:
        if model.kind(t) != "scale":
            s[AXES.index(t.axis)] += t.symbol * t.regressor
    s0 = s.subs(dict(zip(model.inputs, u0)), simultaneous=True)
    return u0 - EPS * D_inv * s0


def exact_input(model: ErrorModel):
    """u(N) in closed form when the model is affine in u, else None."""
    out = model.output()
    A = out.jacobian(model.inputs)
    if any(s in A.free_symbols for s in model.inputs):
        return None
    c = out.subs({s: 0 for s in model.inputs})
    return A.LUsolve(N_out - c)


def _split(term, N_syms):
    """term = coefficient(p) * basis(N, aux), the numeric factor kept with the basis."""
    coeff, basis = term.as_independent(*N_syms, as_Add=False)
    num, coeff = coeff.as_coeff_Mul()
    return num, coeff, basis


def derive_norm_regression(model: ErrorModel) -> NormRegression:
    N_syms = tuple(N_out) + model.aux
    # D^-1 as symbols r_i = 1/(1 + dK_i) keeps the expansion polynomial.
    D = scale_matrix(model)
    r = sp.symbols("r_x r_y r_z", positive=True)
    back = {r[i]: 1 / D[i, i] for i in range(3)}
    u1 = first_order_input(model, sp.diag(*r))
    full = sp.expand((u1.T * u1)[0])
    sq = full.coeff(EPS, 0) + full.coeff(EPS, 1)
    groups: dict = {}
    for term in sp.Add.make_args(sq):
        num, coeff, basis = _split(term, N_syms)
        groups.setdefault(basis, []).append((num, coeff))

    scale = [t.symbol for t in model.terms if model.kind(t) == "scale"]
    order = {p: i for i, p in enumerate(model.params)}
    rows = []
    for basis, parts in groups.items():
        # One numeric factor per basis goes into the regressor column, as the
        # paper writes -2 N_x N_y into N_s and keeps K_4 free of it.
        num0 = parts[0][0]
        K_expr = sp.Add(*[(num / num0) * c for num, c in parts]).subs(back)
        small = sorted((K_expr.free_symbols - set(scale)), key=order.get)
        if len(small) > 1:
            raise NotIdentifiable(
                f"model {model.name}: parameters {[str(s) for s in small]} enter the norm "
                f"regression only through one column ({basis}); the norm cannot separate them")
        lead = small[0] if small else min(K_expr.free_symbols, key=order.get)
        rows.append((order[lead], num0 * basis, sp.factor(K_expr), lead))
    rows.sort(key=lambda r: r[0])
    leads = [r[3] for r in rows]
    missing = [p for p in model.params if p not in leads]
    if missing:
        raise NotIdentifiable(f"model {model.name}: {[str(p) for p in missing]} do not appear "
                              "in the norm to first order; the norm cannot see them")
    K = list(sp.symbols(f"K_1:{len(rows) + 1}", real=True))
    K_of_p = [r[2] for r in rows]
    psi = [r[1] for r in rows]

    p_of_K = _exact_inverse(model, K, K_of_p, leads, scale)
    p_of_K_first = _first_order_inverse(model, K, K_of_p, p_of_K)
    exact_u = exact_input(model)
    return NormRegression(
        model=model, K=K, K_of_p=K_of_p, psi=psi, p_of_K=p_of_K, p_of_K_first=p_of_K_first,
        norm_sq_first=sum(k * c for k, c in zip(K_of_p, psi)),
        norm_sq_exact=None if exact_u is None else (exact_u.T * exact_u)[0])


def _exact_inverse(model, K, K_of_p, leads, scale):
    """Solve K_j = K_j(p) for p: scale errors first (K = (1+dK)^-2), then the
    first-order parameters, each linear in its own K_j."""
    sol = {}
    at_zero = {p: 0 for p in model.params}
    for Kj, expr, p in zip(K, K_of_p, leads):
        if p in scale:
            k0 = expr.subs(at_zero)
            roots = sp.solve(sp.Eq(Kj, expr), p)
            good = [r for r in roots if sp.simplify(r.subs(Kj, k0)) == 0]
            if len(good) != 1:
                raise NotIdentifiable(f"model {model.name}: no unique inverse for {p} from {Kj} = {expr}")
            sol[p] = good[0]
    for Kj, expr, p in zip(K, K_of_p, leads):
        if p not in scale:
            slope = sp.diff(expr, p)
            if sp.diff(slope, p) != 0:
                raise NotIdentifiable(f"model {model.name}: {Kj} is not linear in {p}")
            sol[p] = sp.simplify((Kj / slope).subs(sol))
    return {p: sol[p] for p in model.params}


def _first_order_inverse(model, K, K_of_p, p_of_K):
    K0 = {k: e.subs({p: 0 for p in model.params}) for k, e in zip(K, K_of_p)}
    out = {}
    for p, e in p_of_K.items():
        lin = e.subs(K0)
        for k in K:
            lin += sp.diff(e, k).subs(K0) * (k - K0[k])
        out[p] = sp.nsimplify(sp.expand(lin))
    return out
