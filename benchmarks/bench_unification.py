"""Benchmark: frame unification against the table's position errors.

Per plan and position error, over seeds: the largest error of the gyro matrix in b
(M_d C_b^d against truth) for the three ways of tying the frames: the rate runs'
mean specific force and mean rate (the default), the static pairs (each rate run's
axis with the gravity of the static position at the same commanded angles) and the
paper's eq. 25-27 (--method linear, Table 2 positions); and for the default, the rms
of error / stated std over the 9 entries (1 when the std is right).
Usage: python3 benchmarks/bench_unification.py [--seeds 10]
"""
import argparse
import tempfile
from pathlib import Path

import numpy as np

from simucal.api.calibrating import calibrate
from simucal.fit.rotations import exp_so3
from simucal.report.markdown import header
from simucal.turntable.simulate import ARCMIN, Scenario, write


def main(seeds: int):
    print(header(["plan", "position error", "max err M_b, rate-run means (median over seeds)", "static pairs",
                  "paper eq. 25-27", "rms error/std, rate-run means"]))
    with tempfile.TemporaryDirectory() as tmp:
        for plan, arcmin in (("table1", 1.0), ("table1", 60.0), ("fibonacci48", 1.0), ("fibonacci48", 60.0)):
            e_rate, e_static, e_paper, z = [], [], [], []
            for seed in range(seeds):
                folder = Path(tmp) / f"{plan}-{arcmin}-{seed}"
                truth = np.array(write(folder, Scenario(plan=plan, position_error_rad=arcmin * ARCMIN),
                                       seed)["gyro"]["M"])
                cal = calibrate(folder)
                M = cal.gyro.M
                e_rate.append(np.abs(M - truth).max())
                z.append(((M - truth) / np.array(cal.gyro.details["std_M"])).ravel())
                u = cal.unification
                M_static = np.array(cal.gyro.details["M_in_d"]) @ np.array(u["C_b_d"]) @ exp_so3(
                    np.array(u["cross_check"]["difference_rad"]))
                e_static.append(np.abs(M_static - truth).max())
                e_paper.append(np.abs(calibrate(folder, method="linear").gyro.M - truth).max())
            print(f"| {plan} | {arcmin:g}' | {np.median(e_rate):.2g} | {np.median(e_static):.2g} | "
                  f"{np.median(e_paper):.2g} | {np.sqrt(np.mean(np.square(z))):.2f} |")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    main(ap.parse_args().seeds)
