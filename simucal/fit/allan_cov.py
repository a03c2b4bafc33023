"""The covariance of overlapping Allan variance estimates at a grid of cluster sizes.

An estimate at cluster size m is S_m / (2 tau^2 n_m), S_m = sum_k d_k^2 over the n_m second
differences d_k = theta_{k+2m} - 2 theta_{k+m} + theta_k of the integrated output (fit/allan_terms.py). Each
d is a finite filter of the noise: of a white rate y (N^2 = var(y) dt) the Haar wavelet g_m = dt
(-1 on [0, m), +1 on [m, 2m)); of a rate random walk y_i = sum_{l<=i} e_l (K^2 = var(e) / dt) the
triangle dt min(i, 2m - i) on [0, 2m]; of a white angle (velocity) error q (quantisation, Q^2 =
var(q)) the taps (1, -2, 1) at (0, m, 2m). For Gaussian noise (Isserlis)

    cov(S_m1, S_m2) = 2 sum_h n(h) c(h)^2,   c(h) = sum_a x_a phi_a(h),

c(h) = cov(d_k(m1), d_{k-h}(m2)), phi_a the cross-correlation of the two filters of component a
(x_a = Q^2, N^2, K^2), n(h) the number of index pairs at lag h, summed over still stretches. So the
covariance is sum_ab x_a x_b M_ab with six basis matrices that depend only on the cluster sizes,
dt and the stretch lengths: computed once per sensor, then combined for each axis's model.

The sums are exact in closed form: phi_N is a sum of overlaps of integer intervals (piecewise
linear in h), phi_K a four-fold convolution of boxcars (piecewise cubic, sums of binomials
C(h + 3, 3)), n(h) an overlap count; their real extensions are polynomials between integer
breakpoints, so each piece is summed directly where it is short and, where it is long (>= LONG),
by Euler-Maclaurin, exact for these degree-7 pieces: the integral plus the end terms up to B_6,
from the piece's Chebyshev interpolant at 8 points (_euler_maclaurin_weights). The old form
(Gauss-Legendre plus the trapezoid's ends, relative error 1 / (6 LONG^2)) broke the positive
definiteness of the strongly correlated random-walk covariance. The quantisation filter has nine taps: its terms are
evaluated at those lags. A bias instability (flicker) or a ramp has no finite filter and is not
carried: the covariance is that of white noise, random walk and quantisation.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

COMPONENTS = ("Q", "N", "K")
LONG = 32  # pieces this long or longer are integrated, shorter ones summed
_CHEB_T = np.cos(np.pi * (np.arange(8) + 0.5) / 8)  # Chebyshev nodes on [-1, 1]: the interpolant is exact to degree 7
_BERNOULLI = ((1, 1.0 / 6.0 / 2.0), (3, -1.0 / 30.0 / 24.0), (5, 1.0 / 42.0 / 720.0))  # (2k - 1, B_2k / (2k)!)


def _euler_maclaurin_weights(length):
    """(P, 8) weights w with sum_{j=0}^{L-1} f(lo + j) = sum_i w_i f(lo + L (1 + t_i) / 2) for every
    polynomial f of degree <= 7 (t_i = _CHEB_T): Euler-Maclaurin, int f + (f(lo) - f(hi)) / 2 +
    sum_k B_2k / (2k)! (f^(2k-1)(hi) - f^(2k-1)(lo)), all read off the Chebyshev coefficients."""
    cheb = np.polynomial.chebyshev
    to_coef = np.linalg.inv(cheb.chebvander(_CHEB_T, 7))  # values at the nodes -> coefficients
    eye = np.eye(8)
    integral = np.array([cheb.chebval(1.0, cheb.chebint(e, lbnd=-1.0)) for e in eye]) @ to_coef
    ends = (cheb.chebvander(-1.0, 7)[0] - cheb.chebvander(1.0, 7)[0]) / 2 @ to_coef
    half = np.asarray(length, dtype=float)[:, None] / 2  # d/dh = d/dt / half
    w = half * integral + ends
    for order, coef in _BERNOULLI:
        jump = np.array([cheb.chebval(1.0, cheb.chebder(e, order)) - cheb.chebval(-1.0, cheb.chebder(e, order))
                         for e in eye]) @ to_coef
        w = w + coef * jump / half ** order
    return w


def _overlap(a0, a1, b0, b1):
    return np.maximum(0.0, np.minimum(a1, b1) - np.maximum(a0, b0))


def _white(h, m1, m2):
    """sum_j g1[j] g2[j + h] of the Haar filters (without dt): signed overlaps of their halves."""
    out = 0.0
    for a, sa in ((0, -1.0), (m1, 1.0)):
        for b, sb in ((0, -1.0), (m2, 1.0)):
            out = out + sa * sb * _overlap(a, a + m1, b - h, b - h + m2)
    return out


_SUBSETS = [(s1, s2, (-1.0) ** (s1 + s2)) for s1 in range(3) for s2 in range(3)]
_SECOND_DIFFERENCE = ((0, 1.0), (1, -2.0), (2, 1.0))  # (s, (-1)^s C(2, s)): the two equal boxes' subsets


def _ramp(y, m):
    """(box_m^2 * step^2)(y) = sum_s (-1)^s C(2, s) C(y - s m + 3, 3) (zero below y - s m = -1).
    Where all three terms are on (y >= 2 m - 1) their cubics cancel to the line m^2 (y - m + 2)
    (the second difference of (u^3 - u) / 6, u = z + 2, is m^2 u at the centre): evaluated so, not
    as the difference of three cubics of size y^3, which at y ~ 1e7 loses every digit."""
    y = np.asarray(y, dtype=float)
    on = y >= 2 * m - 1
    y_low = np.where(on, 0.0, y)  # the cubics only where they are of the size of the result
    cubic: np.ndarray | float = 0.0
    for s, weight in _SECOND_DIFFERENCE:
        z = y_low - s * m
        cubic = cubic + weight * np.where(z >= -1, (z + 1) * (z + 2) * (z + 3) / 6.0, 0.0)
    return np.where(on, m * m * (y - m + 2), cubic)


def _walk(h, m1, m2):
    """sum_i tri1(i) tri2(i + h) of the triangles: (box_m1^2 * box_m2^2)(h + 2 m1 - 2), the second
    difference at the larger cluster size's step of the smaller one's _ramp (box^2 * step^2)."""
    small, big = np.minimum(m1, m2), np.maximum(m1, m2)
    x = h + 2 * m1 - 2
    return sum(weight * _ramp(x - s * big, small) for s, weight in _SECOND_DIFFERENCE)


def _pairs_weight(h, n1, n2):
    """Number of k with 0 <= k < n1 and 0 <= k - h < n2."""
    return _overlap(0.0, n1, h, h + n2)


def _breaks(m1, m2, n1, n2):
    """(P, B) integer breakpoints of phi_N, phi_K and n(h) for each pair."""
    cols = []
    for a in (0, m1):
        for b in (0, m2):
            cols += [b - a, b - a + m2 - m1, b - a + m2, b - a - m1]
    cols += [s1 * m1 + s2 * m2 + 1 - 2 * m1 for s1, s2, _ in _SUBSETS]
    cols += [0 * n1, n1 - n2, -n2, n1]
    return np.sort(np.column_stack(np.broadcast_arrays(*cols)).astype(float), axis=1)


def _products(h, m1, m2, n1, n2, dt):
    """(n phi_N^2, n phi_N phi_K, n phi_K^2) at lags h, with the dt of each filter."""
    pw = _pairs_weight(h, n1, n2)
    w, k = _white(h, m1, m2) * dt, _walk(h, m1, m2) * dt ** 3
    return np.stack([pw * w * w, pw * w * k, pw * k * k])


SMOOTH_KEYS = (("N", "N"), ("N", "K"), ("K", "K"))


def _smooth_sums(m1, m2, n1, n2, dt) -> dict:
    """sum_h n(h) phi_a phi_b for the piecewise-polynomial components (module doc), per pair."""
    bp = _breaks(m1, m2, n1, n2)
    lo, hi = bp[:, :-1].ravel(), bp[:, 1:].ravel()
    pair = np.repeat(np.arange(len(m1)), bp.shape[1] - 1)
    length = hi - lo
    total = np.zeros((3, len(m1)))
    # short pieces: every integer lag in [lo, hi)
    s = np.nonzero((length > 0) & (length < LONG))[0]
    j = np.arange(LONG)
    args = (m1[pair[s], None], m2[pair[s], None], n1[pair[s], None], n2[pair[s], None], dt)
    f = np.where(j < length[s, None], _products(lo[s, None] + j, *args), 0.0).sum(2)
    for i in range(3):
        total[i] += np.bincount(pair[s], f[i], len(m1))
    # long pieces: Euler-Maclaurin over [lo, hi), exact for the degree-7 products
    g = np.nonzero(length >= LONG)[0]
    args = (m1[pair[g], None], m2[pair[g], None], n1[pair[g], None], n2[pair[g], None], dt)
    f = _products(lo[g, None] + length[g, None] * (1 + _CHEB_T) / 2, *args)
    f = (f * _euler_maclaurin_weights(length[g])).sum(2)
    for i in range(3):
        total[i] += np.bincount(pair[g], f[i], len(m1))
    return dict(zip(SMOOTH_KEYS, total))


def _quantisation_sums(m1, m2, n1, n2, dt) -> dict:
    """sum_h n(h) phi_Q phi_b for b in (Q, N, K): phi_Q has taps at h = b - a, a in {0, m1, 2 m1},
    b in {0, m2, 2 m2} (the same lag may come twice, so phi_Q is the taps summed at each lag)."""
    taps = [(a, b, wa * wb) for a, wa in ((0, 1.0), (1, -2.0), (2, 1.0)) for b, wb in ((0, 1.0), (1, -2.0), (2, 1.0))]
    lags = np.column_stack([b * m2 - a * m1 for a, b, _ in taps]).astype(float)
    weights = np.array([w for _, _, w in taps])
    # phi_Q at each tap's lag: all taps at that same lag summed
    phi = ((lags[:, :, None] == lags[:, None, :]) * weights[None, None, :]).sum(2)
    first = ~((lags[:, :, None] == lags[:, None, :]) & np.tri(9, k=-1, dtype=bool)[None]).any(2)
    args = (m1[:, None], m2[:, None], n1[:, None], n2[:, None], dt)
    pw = _pairs_weight(lags, *args[2:4]) * first
    w, k = _white(lags, *args[:2]) * dt, _walk(lags, *args[:2]) * dt ** 3
    return {("Q", "Q"): (pw * phi * phi).sum(1), ("Q", "N"): (pw * phi * w).sum(1), ("Q", "K"): (pw * phi * k).sum(1)}


def basis(m, dt, stretch_lengths) -> dict[tuple[str, str], NDArray[np.float64]]:
    """{(a, b): M_ab (len(m), len(m))} with cov(avar_i, avar_j) = sum over a, b in COMPONENTS of
    x_a x_b M_ab[i, j] (module doc; (a, b) and (b, a) both given), for cluster sizes m, sample step
    dt and the still stretches' lengths (samples)."""
    m = np.asarray(m, dtype=float)
    i, j = np.triu_indices(len(m))
    m1, m2 = m[i], m[j]
    sums: dict[tuple[str, str], np.ndarray] = {}
    lengths, counts = np.unique(np.asarray(stretch_lengths, dtype=float), return_counts=True)
    for length, count in zip(lengths, counts):
        n1, n2 = np.maximum(length - 2 * m1, 0.0), np.maximum(length - 2 * m2, 0.0)
        for part in (_smooth_sums(m1, m2, n1, n2, dt), _quantisation_sums(m1, m2, n1, n2, dt)):
            for key, v in part.items():
                sums[key] = sums.get(key, 0.0) + count * v
    total = np.array([sum(c * max(L - 2 * mm, 0.0) for L, c in zip(lengths, counts)) for mm in m])
    tau = m * dt
    norm = 2.0 / (4 * tau[i] ** 2 * tau[j] ** 2 * total[i] * total[j])
    out = {}
    for (a, b), v in sums.items():
        mat = np.zeros((len(m), len(m)))
        mat[i, j] = v * norm
        mat[j, i] = v * norm
        out[(a, b)] = mat
        out[(b, a)] = mat
    return out


def covariance(mats: dict, x: dict) -> np.ndarray:
    """cov of the Allan variance estimates for component sizes x = {Q: Q^2, N: N^2, K: K^2}."""
    return sum(max(x.get(a, 0.0), 0.0) * max(x.get(b, 0.0), 0.0) * mats[(a, b)]
               for a in COMPONENTS for b in COMPONENTS)
