"""White-noise level from the data itself."""
import numpy as np


def white_noise_var(x, ddof=0):
    """Per-axis variance of the white noise in rows x (n, k), from first differences:
    var(x[i+1] - x[i]) / 2. Blind to slowly varying signals (motion, a turning Earth rate)."""
    return np.var(np.diff(x, axis=0), axis=0, ddof=ddof) / 2
