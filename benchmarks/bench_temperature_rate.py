"""Benchmark: a still warm-up's model test against a die that lags its thermistor (handheld/warmup.py, the
temperature-rate effect) over seeds, on tests/test_temperature_rate.py's forward model (a board warming from
15 to 55 degC under a chamber's 30-minute cycle, the sensor's temperature lagging by dT_s/dt = (T - T_s) / tau,
a quadratic bias in it, white noise and a random walk; 1 h at 10 Hz):

- clean warm-ups (no lag), at the unit's walk (0.05 (deg/h)/sqrt(s)) and at 30 times it: how often each
  sensor's model fails (at ALPHA each: over 200 seeds 0.2 on average), the temperature rate's targeted chi2
  (chi-square on 1 dof: mean 1) and the walk check's z (a standard normal);
- 30 s of lag on gyro x: how often the model fails there and names gyro.temperature_rate.x, beside the model
  test before (the powers beyond each axis's degree alone: the block's chi2 on its dof), and with --add auto
  that axis's residual against the other two's, the rate's error / std against -tau b'(T_ref), and the bias at
  T_ref's error with and without it;
- a slow misfit outside the library (a 30 deg/h sinusoid of 400 s on gyro x, no lag): how often the walk
  check or the whole family fails.

    python3 benchmarks/bench_temperature_rate.py [--seeds 200] [--lag-seeds 50]
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_temperature_rate import GYRO_DPH, LAG_S, T_REF, warmup  # noqa: E402 (the suite's forward model)

import simucal  # noqa: E402
from simucal.fit.distributions import chi2_sf  # noqa: E402
from simucal.fit.family import ALPHA, OMNIBUS_SHARE  # noqa: E402
from simucal.handheld.warmup import calibrate_warmup  # noqa: E402


def clean(seeds, walk):
    fails, chi2, z = {"acc": 0, "gyro": 0}, [], []
    for seed in range(seeds):
        cal = calibrate_warmup(warmup(seed, walk=walk), t_ref_c=T_REF)
        for s, b in cal.blocks():
            fails[s] += b.p_value < ALPHA
            for a in "xyz":
                f = b.thermal["parameters"][f"b_{a}"]
                chi2.append(f["targeted"]["statistic"])
                z.append(f["walk_check"]["z"])
    case = f"clean, walk {walk:g} (deg/h)/sqrt(s)"
    return [(case, seeds, "acc sensors failing", fails["acc"], f"{seeds * ALPHA:.2g}"),
            (case, seeds, "gyro sensors failing", fails["gyro"], f"{seeds * ALPHA:.2g}"),
            (case, seeds, "rate's targeted chi2 mean", f"{np.mean(chi2):.3f}", "1"),
            (case, seeds, "rate's chi2 beyond chi2(1)'s 1e-2 tail", f"{np.mean(np.array(chi2) > 6.63):.4f}", "0.01"),
            (case, seeds, "walk check z mean, std", f"{np.mean(z):.3f}, {np.std(z):.3f}", "0, 1"),
            (case, seeds, "walk check z beyond 2.33", f"{np.mean(np.array(z) > 2.33):.4f}", "0.01")]


def lagged(seeds):
    named, before, ratio_plain, ratio_auto, z_rate, err_plain, err_auto, walk = 0, 0, [], [], [], [], [], []
    for seed in range(seeds):
        ms = warmup(seed, (LAG_S, 0, 0))
        cal = calibrate_warmup(ms, t_ref_c=T_REF)
        named += cal.gyro.p_value < ALPHA and cal.gyro.details.get("advice") == "gyro.temperature_rate.x"
        before += chi2_sf(cal.gyro.chi2, cal.gyro.dof) < ALPHA
        auto = calibrate_warmup(ms, t_ref_c=T_REF, add=("auto",))
        for block, out in ((cal.gyro, ratio_plain), (auto.gyro, ratio_auto)):
            r = [block.thermal["parameters"][f"b_{a}"]["residual_rms"] for a in "xyz"]
            out.append(r[0] / np.mean(r[1:]))
        walk.append([b.thermal["parameters"]["b_x"]["noise"]["random_walk_per_sqrt_s"] for b in (cal.gyro, auto.gyro)])
        e = auto.gyro.effects.get("gyro.temperature_rate.x")
        if e is not None:
            z_rate.append((e.value + LAG_S * GYRO_DPH[0, 1]) / e.std)
        err_plain.append(cal.gyro.thermal["parameters"]["b_x"]["coefficients"][0] - GYRO_DPH[0, 0])
        err_auto.append(auto.gyro.thermal["parameters"]["b_x"]["coefficients"][0] - GYRO_DPH[0, 0])
    case, rms = f"lag {LAG_S:g} s on gyro x", lambda v: np.sqrt(np.mean(np.square(v)))
    return [(case, seeds, "model fails naming gyro.temperature_rate.x", named, seeds),
            (case, seeds, "the test before fails (powers beyond the degree alone)", before, "-"),
            (case, seeds, "--add auto adds it", len(z_rate), seeds),
            (case, seeds, "x residual / other axes', without, with", f"{np.median(ratio_plain):.2f}, "
             f"{np.median(ratio_auto):.2f}", "1"),
            (case, seeds, "walk fitted on x, median without, with", f"{np.median([w[0] for w in walk]):.3f}, "
             f"{np.median([w[1] for w in walk]):.3f}", "0.05"),
            (case, seeds, "rate error/std rms, mean", f"{rms(z_rate):.2f}, {np.mean(z_rate):.2f}", "1, 0"),
            (case, seeds, "b_x(T_ref) error rms deg/h, without, with", f"{rms(err_plain):.2f}, {rms(err_auto):.2f}",
             "-")]


def outside(seeds):
    walk_fails, fails = 0, 0
    for seed in range(seeds):
        ms = warmup(seed)
        t = np.asarray(ms.samples["t_s"])
        g = ms.raw("gyro").copy()
        g[:, 0] += 30.0 * np.sin(2 * np.pi * t / 400.0)
        ms = simucal.MeasurementSet.from_arrays(ms.raw("acc"), g, acc_unit="g", gyro_unit="deg/h", t_s=t,
                                                temp_c=ms.samples["temp_c"], meta={"latitude_deg": 47.0})
        f = calibrate_warmup(ms, t_ref_c=T_REF).gyro.thermal["parameters"]["b_x"]
        walk_fails += f["walk_check"]["p_value"] < ALPHA * OMNIBUS_SHARE / 2
        fails += f["p_value"] < ALPHA
    case = "a 30 deg/h sinusoid of 400 s on gyro x"
    return [(case, seeds, "walk check fails", walk_fails, "-"), (case, seeds, "the axis's family fails", fails, "-")]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--lag-seeds", type=int, default=50)
    args = ap.parse_args()
    start = time.perf_counter()
    with threadpool_limits(1, "blas"):
        rows = (clean(args.seeds, 0.05) + clean(max(args.seeds // 2, 1), 1.5) + lagged(args.lag_seeds)
                + outside(max(args.lag_seeds // 2, 1)))
    print("| case | seeds | figure | value | expected |\n|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(map(str, row)) + " |")
    print(f"\n{time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
