"""Systematic calibration (issue 42): the filter's stds against its errors over seeds, and the
whole process's time on a long sequence (docs/systematic.md).

    python3 benchmarks/bench_systematic.py [--seeds 50] [--rest-s 30] [--speed-hours 1] [--compare-seeds 2]

Part 1: psins19 with rests of --rest-s, seeds 0..N-1 of the default unit (simulate --sequence):
rms of (estimate - truth) / std per parameter and over all, the largest |error / std|, the mean
NIS per update (3 for a consistent filter). Part 2 (--speed-hours > 0): psins19 with its rests
stretched to fill that many hours at 100 Hz, `simucal calibrate --method systematic` timed as a
whole process (reading the set, every pass, writing the file). Part 3 (--compare-seeds): the same
unit by exact and multiposition (table1, 10 s per position at 100 Hz) and systematic (psins19, 30 s
rests) with table angle errors of 1, 10 and 60 arcsec: the largest error of M and bias per sensor.
"""
import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import simucal
from simucal.systematic.calibrate import run_filter
from simucal.turntable.sequence import psins19


def sequence_file(path, rest_s):
    path.write_text("axis,angle_deg,rate_dps,rest_s\n" + "".join(
        f"{s.axis},{s.angle_deg!r},{s.rate_dps!r},{rest_s!r}\n" for s in psins19()))
    return path


def consistency(seeds, rest_s, folder):
    path = sequence_file(folder / f"psins19_{rest_s:g}s.csv", rest_s)
    z, nis = [], []
    for seed in range(seeds):
        ms = simucal.simulate(sequence=path, seed=seed)
        r = run_filter(ms)
        truth = np.r_[[ms.truth["acc"]["params"][k] for k in r.sensors.acc.params],
                      [ms.truth["gyro"]["params"][k] for k in r.sensors.gyro.params]]
        z.append((r.sensors.vector()[:-3] - truth) / np.sqrt(np.diag(r.cov))[:-3])
        nis.append(np.mean([e.nu @ np.linalg.solve(e.S, e.nu) for e in r.epochs[1:]]))
        names = [f"acc.{k}" for k in r.sensors.acc.params] + [f"gyro.{k}" for k in r.sensors.gyro.params]
    z = np.array(z)
    print(f"psins19, rests {rest_s:g} s, 100 Hz, {seeds} seeds, {r.sensors.n} states\n")
    print("| parameter | rms(error/std) | max abs(error/std) |\n|---|---|---|")
    for name, v, w in zip(names, np.sqrt((z ** 2).mean(0)), np.abs(z).max(0)):
        print(f"| {name} | {v:.2f} | {w:.2f} |")
    print(f"| all {z.size} | {np.sqrt((z ** 2).mean()):.3f} | {np.abs(z).max():.2f} |\n")
    print(f"NIS per update {np.mean(nis):.3f} (3 if consistent)")


def speed(hours, folder):
    steps = psins19()
    moving_s = 18 * 10.0  # about: 18 turns of 90 deg at 10 deg/s
    rest_s = (hours * 3600.0 - moving_s) / (len(steps) + 1)
    path = sequence_file(folder / "long.csv", rest_s)
    simucal.simulate(sequence=path, seed=0).write(folder / "long")
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "simucal", "calibrate", str(folder / "long"), "--method", "systematic",
                        "-o", str(folder / "long.json")], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    assert r.returncode == 0, r.stderr
    rows = sum(1 for _ in open(folder / "long" / "samples.csv")) - 1
    print("\n| length | rows | rests | simucal calibrate --method systematic, whole process |\n|---|---|---|---|")
    print(f"| {hours:g} h at 100 Hz | {rows} | {rest_s:.0f} s | {wall:.1f} s wall |")


def _errors(cal, truth):
    """The largest |error| of M (ppm) and of the bias (ug, deg/h) of each sensor against the truth."""
    return [f"{1e6 * np.abs(getattr(cal, s).M - np.array(truth[s]['M'])).max():.1f}" for s in ("acc", "gyro")] + [
        f"{k * np.abs(getattr(cal, s).bias - np.array(truth[s]['bias'])).max():.3g}" for s, k in (("acc", 1e6), ("gyro", 1))]


def comparison(seeds, arcsecs, folder):
    """exact, multiposition and systematic on the same unit (per-sample noise 1e-5 g, 0.01 deg/h at 100 Hz)
    with the table's angular position errors uniform within +- each of arcsecs."""
    path = sequence_file(folder / "psins19_30s.csv", 30.0)
    print("\n| table error | method | seed | acc M err (ppm) | gyro M err (ppm) | acc bias err (ug) | gyro bias err "
          "(deg/h) |\n|---|---|---|---|---|---|---|")
    for arcsec in arcsecs:
        for seed in range(seeds):
            plan = simucal.simulate(seed=seed, rate_hz=100, position_error_arcmin=arcsec / 60)
            seq = simucal.simulate(seed=seed, sequence=path, position_error_arcmin=arcsec / 60)
            for method, ms in (("exact", plan), ("multiposition", plan), ("systematic", seq)):
                cal = simucal.calibrate(ms, method=method)
                print(f"| {arcsec:g}\" | {method} | {seed} | " + " | ".join(_errors(cal, ms.truth)) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50, help="seeds of part 1 (default 50)")
    ap.add_argument("--rest-s", type=float, default=30.0, help="part 1's rests, s (default 30)")
    ap.add_argument("--speed-hours", type=float, default=1.0, help="part 2's length, h; 0 leaves it out (default 1)")
    ap.add_argument("--compare-seeds", type=int, default=2, help="part 3's seeds per table error (default 2; 0: none)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if a.seeds > 0:
            consistency(a.seeds, a.rest_s, Path(tmp))
        if a.speed_hours > 0:
            speed(a.speed_hours, Path(tmp))
        if a.compare_seeds > 0:
            comparison(a.compare_seeds, (1.0, 10.0, 60.0), Path(tmp))


if __name__ == "__main__":
    main()
