"""Remainders of every linearisation, their size, and a second-order check.

For a first-order formula F1 of an exact quantity F, the remainder is
R = F - F1. Its size is the largest |R| over random draws of the small
quantities within their bounds (and of the other inputs over their ranges);
the order check halves every small quantity: a second-order remainder falls
about fourfold.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

# Default bounds on small quantities, by the prefix of the symbol's name.
# Angles in rad, biases in the sensor's unit (g or deg/h).
DEFAULT_BOUNDS = {
    "dK": 1e-2, "theta": 1e-3, "phi": 1e-3, "lambda": 1e-3, "tilt": 1e-4,
    "nonperp": 1e-4, "d_": 1e-3, "b_": None,  # b_ depends on the sensor
}
BIAS_BOUND = {"acc": 1e-2, "gyro": 1.0}


def bound_for(sym: sp.Symbol, sensor: str, bounds=None) -> float:
    bounds = {**DEFAULT_BOUNDS, **(bounds or {})}
    name = str(sym)
    for prefix, b in bounds.items():
        if name.startswith(prefix):
            return BIAS_BOUND[sensor] if b is None else b
    return 1e-5  # any other error term: a conservative small coefficient


def remainder_size(exact, first, small, sample_other, bounds, n=400, seed=0):
    """Largest |exact - first| over n draws; and the ratio when small halves.

    exact, first: SymPy scalars or matrices; small: symbols drawn uniformly in
    +-bounds[s]; sample_other(rng, n) -> {symbol: array} for everything else.
    """
    exact, first = sp.Matrix([exact]), sp.Matrix([first])
    rem = exact - first
    other_syms = sorted((rem.free_symbols - set(small)), key=str)
    fs = [sp.lambdify([list(small), other_syms], e, "numpy") for e in rem]
    rng = np.random.default_rng(seed)
    draws = rng.uniform(-1, 1, (n, len(small))) * np.array([bounds[s] for s in small])
    others = sample_other(rng, n)
    missing = [s for s in other_syms if s not in others]
    if missing:
        raise ValueError(f"no values given for {missing}")

    def worst(scale):
        args = ([draws[:, j] * scale for j in range(len(small))], [others[s] for s in other_syms])
        return max(float(np.max(np.abs(np.broadcast_to(np.asarray(f(*args), float), (n,))))) for f in fs)

    full, half = worst(1.0), worst(0.5)
    return {"max_abs": full, "max_abs_half": half, "ratio": full / half if half > 0 else float("inf")}
