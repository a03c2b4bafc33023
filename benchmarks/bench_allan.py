"""Benchmark: the Allan terms `simucal noise` reports on still recordings of white noise and a
random walk only.

Per seed, six channels (gyro and accelerometer, three axes each) of white noise plus a random walk
at the sizes below, through the command's own path (the Allan variance, the covariance of its
grid, the GLS fit and the term test: simucal.fit.allan_terms.axis_report). Prints, per sensor: the share of
(axis, term) pairs where a term that is not in the data (quantisation, bias instability, ramp) is
reported (the goal: at most 5 %), and for the white noise N and random walk K the rms and mean of
(estimate - truth) / std (1 and 0 when the stds are right; the goal 0.8-1.25), with how often K
was seen.
Usage: python3 benchmarks/bench_allan.py [--seeds 20] [--hours 2] [--rate-hz 50]
"""
import argparse
import time

import numpy as np

from simucal.fit.allan_terms import axis_report, taus
from simucal.fit import allan_cov
from simucal.report.markdown import header

# (unit, white noise N in unit sqrt(s), random walk K in unit / sqrt(s)): 0.1 deg/sqrt(h) and
# 10 deg/h/sqrt(h); 50 ug/sqrt(Hz) and 1 ug/sqrt(s)
SIZES = {"gyro": ("deg/h", 6.0, 10.0 / 60), "acc": ("g", 50e-6, 1e-6)}
ABSENT = ("Q", "B", "R")


def still_channel(rng, n, dt, white, walk):
    """n samples of white noise (N = white) plus a random walk (K = walk), one channel."""
    return white / np.sqrt(dt) * rng.standard_normal(n) + np.cumsum(walk * np.sqrt(dt) * rng.standard_normal(n))


def run(seeds, hours, rate_hz):
    dt = 1.0 / rate_hz
    n = int(round(hours * 3600 * rate_hz))
    m = taus(n)
    mats = allan_cov.basis(m, dt, [n])
    out = {s: {"false": 0, "pairs": 0, "N": [], "K": [], "K_seen": 0, "axes": 0} for s in SIZES}
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        for sensor, (unit, white, walk) in SIZES.items():
            o = out[sensor]
            for _ in range(3):
                ax = axis_report(sensor, [still_channel(rng, n, dt, white, walk)], dt, m, mats, unit)
                o["axes"] += 1
                o["pairs"] += len(ABSENT)
                o["false"] += sum(ax["sheet"][t]["status"] == "seen" for t in ABSENT)
                for t, truth in (("N", white), ("K", walk)):
                    sheet = ax["sheet"][t]
                    if sheet["status"] == "seen":
                        o[t].append((ax["terms"][t] - truth) / (sheet["std"] / sheet["value"] * ax["terms"][t]))
                o["K_seen"] += ax["sheet"]["K"]["status"] == "seen"
    return out, len(m)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=20, help="recordings (default 20)")
    p.add_argument("--hours", type=float, default=2.0, help="length of each recording, h (default 2)")
    p.add_argument("--rate-hz", type=float, default=50.0, help="sample rate, Hz (default 50)")
    a = p.parse_args()
    t0 = time.perf_counter()
    out, n_tau = run(a.seeds, a.hours, a.rate_hz)
    print(f"{a.seeds} seeds of {a.hours:g} h at {a.rate_hz:g} Hz, {n_tau} taus, "
          f"{time.perf_counter() - t0:.1f} s")
    print(header(["sensor", "absent terms reported", "N: rms z", "N: mean z", "K: rms z", "K: mean z", "K seen"]))
    for sensor, o in out.items():
        zn, zk = np.array(o["N"]), np.array(o["K"])
        print(f"| {sensor} | {o['false']} of {o['pairs']} ({100 * o['false'] / o['pairs']:.1f} %) | "
              f"{np.sqrt(np.mean(zn ** 2)):.2f} | {np.mean(zn):+.2f} | {np.sqrt(np.mean(zk ** 2)):.2f} | "
              f"{np.mean(zk):+.2f} | {o['K_seen']} of {o['axes']} |")


if __name__ == "__main__":
    main()
