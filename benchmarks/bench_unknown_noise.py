"""Benchmark: the turntable calibration with and without the noise stated (items 1-2).

Per plan and table position error, over seeds, on sets of one averaged row per segment: with
the noise stated in meta.json and without it (the fits' variance components then stand in), the
median over seeds of the error of C_b^d (|phi|, rad) and the largest error of the gyro M in b,
the rms of error / std over the 9 entries of M and the 3 of phi (1 when the stds are right), the
unification's method, and the share of sets whose static-pair cross-check raised its alarm
(nominal 1e-3) and whose cross-check p fell below 0.1 (nominal 0.1).
Usage: python3 benchmarks/bench_unknown_noise.py [--seeds 50]
"""
import argparse
import tempfile
from pathlib import Path

import numpy as np

from simucal.api.calibrating import calibrate
from simucal.fit.rotations import log_so3
from simucal.generated import table
from simucal.report.markdown import header
from simucal.turntable.simulate import ARCMIN, Scenario, write


def run(folder, sc, seed):
    truth = write(folder, sc, seed)
    cal = calibrate(folder)
    u = cal.unification
    C_true = table.mounting(np.array(sc.lambda4_rad)).T @ table.mounting(np.array(sc.theta4_rad))
    phi = log_so3(np.array(u["C_b_d"]).T @ C_true)
    err_M = cal.gyro.M - np.array(truth["gyro"]["M"])
    z = np.r_[(err_M / np.array(cal.gyro.details["std_M"])).ravel(), phi / np.array(u["std_rad"])]
    cc = u.get("cross_check", {})
    return np.linalg.norm(phi), np.abs(err_M).max(), z, u["method"], not cc.get("agree", True), cc.get("p_value", 1.0)


def main(seeds: int):
    print(header(["plan", "position error", "noise", "|phi| err C_b^d (median)", "max err M_b (median)",
                  "rms error/std", "method", "cross-check alarms", "p < 0.1"]))
    with tempfile.TemporaryDirectory() as tmp:
        for plan in ("table1", "fibonacci48"):
            for arcmin in (1.0, 60.0):
                for stated in (True, False):
                    rows = [run(Path(tmp) / f"{plan}-{arcmin}-{stated}-{seed}",
                                Scenario(plan=plan, position_error_rad=arcmin * ARCMIN, state_noise=stated), seed)
                            for seed in range(seeds)]
                    phi, M, z, method, alarm, p = zip(*rows)
                    methods = "/".join(sorted(set(method)))
                    print(f"| {plan} | {arcmin:g}' | {'stated' if stated else 'estimated'} | {np.median(phi):.2g} | "
                          f"{np.median(M):.2g} | {np.sqrt(np.mean(np.square(z))):.2f} | {methods} | "
                          f"{sum(alarm)}/{seeds} | {np.mean(np.array(p) < 0.1):.2f} |")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=50)
    main(ap.parse_args().seeds)
