"""Tail probabilities of the chi-square, F and t distributions, in plain Python.

The tests' p-values need only these few functions; scipy.special costs 0.12 s
to import, a third of the command's budget. Regularized incomplete
gamma and beta functions by their series and continued fractions (Numerical
Recipes, 3rd ed., 6.2 and 6.4), computed from their logarithms so tiny tails stay
positive; relative error below 1e-9 down to 1e-100, 1e-2 down to 1e-250
(tests/test_distributions.py holds them against scipy).
"""
from __future__ import annotations

import math

_EPS, _TINY = 1e-15, 1e-300


def _gamma_series(a, x):
    """P(a, x) by its series (x < a + 1)."""
    s = term = 1.0 / a
    ap = a
    for _ in range(10000):
        ap += 1
        term *= x / ap
        s += term
        if abs(term) < abs(s) * _EPS:
            break
    return s * math.exp(-x + a * math.log(x) - math.lgamma(a))


def _gamma_cf(a, x):
    """Q(a, x) by its continued fraction (x >= a + 1), modified Lentz."""
    b = x + 1 - a
    c, d = 1 / _TINY, 1 / b
    h = d
    for i in range(1, 10000):
        an = -i * (i - a)
        b += 2
        d = an * d + b
        d = _TINY if abs(d) < _TINY else d
        c = b + an / c
        c = _TINY if abs(c) < _TINY else c
        d = 1 / d
        h *= d * c
        if abs(d * c - 1) < _EPS:
            break
    return math.exp(-x + a * math.log(x) - math.lgamma(a)) * h


def chi2_sf(x, k) -> float:
    """P(X > x) for X ~ chi-square with k degrees of freedom (scipy.special.chdtrc(k, x))."""
    x, a = float(x), k / 2.0
    if x <= 0:
        return 1.0
    y = x / 2.0
    return 1.0 - _gamma_series(a, y) if y < a + 1 else _gamma_cf(a, y)


def _beta_cf(a, b, x):
    """The continued fraction of the incomplete beta function (modified Lentz)."""
    qab, qap, qam = a + b, a + 1, a - 1
    c, d = 1.0, 1 - qab * x / qap
    d = 1 / (_TINY if abs(d) < _TINY else d)
    h = d
    for m in range(1, 10000):
        m2 = 2 * m
        for aa in (m * (b - m) * x / ((qam + m2) * (a + m2)), -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))):
            d = 1 + aa * d
            d = 1 / (_TINY if abs(d) < _TINY else d)
            c = 1 + aa / c
            c = _TINY if abs(c) < _TINY else c
            h *= d * c
        if abs(d * c - 1) < _EPS:
            break
    return h


def _betainc(a, b, x):
    """I_x(a, b), the regularized incomplete beta function."""
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    lbt = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    if x < (a + 1) / (a + b + 2):
        return math.exp(lbt) * _beta_cf(a, b, x) / a
    return 1.0 - math.exp(lbt) * _beta_cf(b, a, 1 - x) / b


F_AS_CHI2_DOF = 1e7  # d2 beyond which F(d1, d2) is chi-square(d1) / d1 (to 1e-7), and lgamma(d2 / 2)'s
# differences lose every digit (a Satterthwaite dof of 1e15 gave p = -12.8 on numpy 2.0's sums)


def f_sf(F, d1, d2) -> float:
    """P(X > F) for X ~ F(d1, d2) (scipy.special.fdtrc(d1, d2, F)); chi-square's limit for d2 beyond F_AS_CHI2_DOF."""
    F = float(F)
    if F <= 0:
        return 1.0
    if d2 > F_AS_CHI2_DOF:
        return chi2_sf(d1 * F, d1)
    return _betainc(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * F))


def _inverse_sf(sf, p, hi) -> float:
    """x >= 0 with sf(x) = p for a falling tail sf, by bisection on log p (tiny tails stay exact)."""
    lo = 0.0
    while sf(hi) > p:
        hi *= 2
    target = math.log(p)
    for _ in range(200):
        mid = (lo + hi) / 2
        if math.log(max(sf(mid), 1e-320)) > target:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12 * hi:
            break
    return (lo + hi) / 2


def chi2_isf(p, k) -> float:
    """x with chi2_sf(x, k) = p (scipy.special.chdtri(k, p))."""
    return _inverse_sf(lambda x: chi2_sf(x, k), p, max(1.0, 2.0 * k))


def chi2_sf_estimated(x, k, nu) -> float:
    """P(X > x) for a quadratic form X = d^T S^-1 d in k dimensions whose covariance S is estimated
    with nu degrees of freedom: X / k ~ F(k, nu); chi-square(k) where nu is infinite (S known)."""
    return chi2_sf(x, k) if math.isinf(nu) else f_sf(float(x) / k, k, nu)


def t_isf(p, nu) -> float:
    """t with P(T > t) = p for Student's t with nu degrees of freedom (the normal quantile where
    nu is infinite): P(T > t) = f_sf(t^2, 1, nu) / 2."""
    if math.isinf(nu):
        return math.sqrt(chi2_isf(2 * p, 1))
    return _inverse_sf(lambda t: f_sf(t * t, 1, nu) / 2, p, 1.0)
