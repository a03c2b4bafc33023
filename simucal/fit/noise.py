"""White-noise level from the data itself."""
import numpy as np


def white_noise_var(x, ddof=0):
    """Per-axis variance of the white noise in rows x (n, k), from first differences:
    var(x[i+1] - x[i]) / 2. Blind to slowly varying signals (motion, a turning Earth rate)."""
    return np.var(np.diff(x, axis=0), axis=0, ddof=ddof) / 2


def quantization_step(x, whole=None):
    """Per column, the smallest step between distinct values of x (n, k): the LSB of
    quantised data (tiny for unquantised floats). A column that is constant in x (a
    rest quieter than one LSB) takes it from the same column of `whole` (the stream).
    When the noise is below it, the noise a still sensor shows is not the noise a
    moving one has (q^2/12 per sample), and averaging a still sensor does not shrink
    its error below about q/sqrt(12)."""
    steps = []
    for j, col in enumerate(np.asarray(x, float).T):
        d = np.diff(np.unique(col))
        if not np.any(d > 0) and whole is not None:
            d = np.diff(np.unique(np.asarray(whole, float)[:, j]))
        steps.append(float(d[d > 0].min()) if np.any(d > 0) else 0.0)
    return np.array(steps)
