"""The covariance of overlapping Allan variance estimates at a grid of cluster sizes (issue 38).

An estimate at cluster size m is S_m / (2 tau^2 n_m), S_m = sum_k d_k^2 over the n_m second
differences d_k = theta_{k+2m} - 2 theta_{k+m} + theta_k of the integrated output (allan.py). Each
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
by 4-point Gauss-Legendre (exact to degree 7) plus the trapezoid's end terms, which leaves a
relative error below 1 / (6 LONG^2). The quantisation filter has nine taps: its terms are
evaluated at those lags. A bias instability (flicker) or a ramp has no finite filter and is not
carried: the covariance is that of white noise, random walk and quantisation.
"""
from __future__ import annotations

import numpy as np

COMPONENTS = ("Q", "N", "K")
LONG = 32  # pieces this long or longer are integrated, shorter ones summed
_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


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
_SUBSET_COUNT = {0: 1.0, 1: 2.0, 2: 1.0}  # ways of taking s of the two equal boxes


def _walk(h, m1, m2):
    """sum_i tri1(i) tri2(i + h) of the triangles: (box_m1^2 * box_m2^2)(h + 2 m1 - 2), a sum over
    the boxes' subsets S of (-1)^|S| C(z + 3, 3), z = h + 2 m1 - 2 - sum S (zero below z = -1)."""
    out = 0.0
    for s1, s2, sign in _SUBSETS:
        z = h + 2 * m1 - 2 - s1 * m1 - s2 * m2
        out = out + sign * _SUBSET_COUNT[s1] * _SUBSET_COUNT[s2] * np.where(
            z >= -1, (z + 1) * (z + 2) * (z + 3) / 6.0, 0.0)
    return out


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
    # long pieces: the integral plus (f(lo) - f(hi)) / 2 (the trapezoid's ends: sum over [lo, hi))
    g = np.nonzero(length >= LONG)[0]
    args = (m1[pair[g], None], m2[pair[g], None], n1[pair[g], None], n2[pair[g], None], dt)
    half = length[g, None] / 2
    x = np.column_stack([lo[g, None] + half * (1 + _GL_X), lo[g], hi[g]])
    f = _products(x, *args)
    f = (f[:, :, :4] * _GL_W).sum(2) * half[:, 0] + (f[:, :, 4] - f[:, :, 5]) / 2
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


def basis(m, dt, stretch_lengths) -> dict:
    """{(a, b): M_ab (len(m), len(m))} with cov(avar_i, avar_j) = sum over a, b in COMPONENTS of
    x_a x_b M_ab[i, j] (module doc; (a, b) and (b, a) both given), for cluster sizes m, sample step
    dt and the still stretches' lengths (samples)."""
    m = np.asarray(m, dtype=float)
    i, j = np.triu_indices(len(m))
    m1, m2 = m[i], m[j]
    sums = {}
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
