"""Benchmark: time to derive and regenerate one model, and one exact solve.

Prints a table. Goal: under 10 s to derive and regenerate one model.
Solve times compare the generated exact solver (compiled CasADi C and the
numpy fallback), the paper's linear method, and scipy.optimize.least_squares
on the same exact problem.
Usage: python3 benchmarks/bench_derive_and_solve.py [--quick] (--quick: one model derived, solves timed twice)
"""
import argparse
import time

import numpy as np
from scipy.optimize import least_squares
from simucal.derive import codegen
from simucal.derive.registry import ACC_BASELINE, ACC_EXTENDED, GYRO_BASELINE
from simucal.generated import table

from simucal.fit.catalog import load
from simucal.fit.norm_fit import Observations, fit_exact, fit_linear
from simucal.turntable import plans


def best(f, reps):
    ts = []
    for _ in range(reps):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return min(ts)


def main(quick=False):
    print("| step | model | seconds |\n|---|---|---|")
    for model in (ACC_BASELINE,) if quick else (ACC_BASELINE, GYRO_BASELINE, ACC_EXTENDED):
        t = time.perf_counter()
        codegen.model_module(model)
        codegen.c_source(model)
        extra = len(model.terms) - 9
        print(f"| derive + regenerate | {model.name} ({extra} extra terms) | {time.perf_counter() - t:.2f} |")

    rng = np.random.default_rng(0)
    ang = np.radians(np.array(plans.TABLE1))
    u = table.C_k_n(ang[:, 0], ang[:, 1], ang[:, 2], np.zeros(7))[:, 2, :]
    p = np.array([0.002, 0.008, 0.006, 1e-4, 1e-4, 1e-4, 8e-4, -1e-3, -3.2e-3])
    c, n = load("acc_baseline", True), load("acc_baseline", False)
    N = c.output(u, p) + rng.normal(0, 1e-5, (12, 3))
    obs = Observations(N, np.ones(12), np.full((12, 3), 1e-5))

    def scipy_fit():
        # unknowns: p and two spherical angles per position (same exact problem)
        d0 = N / np.linalg.norm(N, axis=1, keepdims=True)
        x0 = np.r_[np.zeros(9), np.arctan2(d0[:, 1], d0[:, 0]), np.arcsin(d0[:, 2])]

        def res(x):
            az, el = x[9:21], x[21:]
            d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
            return ((N - n.output(d, x[:9])) / 1e-5).ravel()
        return least_squares(res, x0, method="lm", xtol=1e-14, ftol=1e-14)

    ref = scipy_fit().x[:9]
    ex = fit_exact(c, obs).vector(c.params)
    rows = [("exact, generated CasADi C", lambda: fit_exact(c, obs)),
            ("exact, generated numpy", lambda: fit_exact(n, obs)),
            ("linear (paper eq. 8)", lambda: fit_linear(n, obs)),
            ("scipy least_squares, same exact problem", scipy_fit)]
    print("\n| solve (12 positions, acc_baseline) | ms per fit |\n|---|---|")
    for name, f in rows:
        print(f"| {name} | {best(f, 2 if quick else 20) * 1e3:.2f} |")
    print(f"\nexact vs scipy: largest parameter difference {np.max(np.abs(ex - ref)):.2e} "
          f"(noise 1e-5 g, parameter std ~ {np.sqrt(np.diag(fit_exact(c, obs).cov)).max():.1e})")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="one model derived, each solve timed twice")
    main(ap.parse_args().quick)
