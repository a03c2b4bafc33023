"""Benchmark: are the turntable calibration's stds right at any sample rate?

Per sample rate, dong2018's test simulated with the noise not stated (`simulate --no-noise-stated`)
and the table's tilt drawn per seed and stated (scenario below),
calibrated raw (every row) and averaged (the same rows, one mean per segment); over seeds, per
sensor, z = (estimate - truth) / std of the 9 parameters: rms(z) (1 when the stds are right) and
mean(z) with its sampling error (the std of the seeds' own means over sqrt(seeds)), chi2 / dof of the
model test, and the share of calibrations that warn about their noise.
Usage: python3 benchmarks/bench_stds_by_rate.py [--seeds 6] [--rates 20,100,400] [--plan fibonacci48]
"""
import argparse
from pathlib import Path

import numpy as np

from simucal import io
from simucal.api.calibrating import calibrate
from simucal.report.markdown import header
from simucal.turntable.simulate import ARCSEC, Scenario, simulate

SENSORS = ("acc", "gyro")


def measurement_set(sc, seed, averaged):
    """The simulated set in memory (no CSV): every row, or one mean per segment."""
    meta, samples, segments, truth = simulate(sc, seed)
    if averaged:
        groups = io.group_rows(samples["segment"])
        samples = {c: np.array([v[groups[s.segment]].mean() for s in segments]) for c, v in samples.items()}
        samples["segment"] = samples["segment"].astype(int)
    return io.MeasurementSet(Path(f"simulated seed {seed}"), meta, samples, segments), truth


def scores(sc, seed, averaged):
    """{sensor: (z of its parameters, chi2, dof, warned)} of one calibration."""
    ms, truth = measurement_set(sc, seed, averaged)
    cal = calibrate(ms)
    out = {}
    for s in SENSORS:
        block = getattr(cal, s)
        z = np.array([(v - truth[s]["params"][k]) / block.std[k] for k, v in block.params.items()])
        out[s] = (z, block.chi2, block.dof, bool(block.details.get("noise_warning")))
    return out


def scenario(plan, rate, seed, tilt_arcsec):
    """dong2018's test without the noise stated, the outer axis's tilt drawn per seed (normal, std
    tilt_arcsec about each horizontal axis) and stated in meta.json (table_tilt_arcsec): one fixed tilt
    would be one draw of a systematic, which no number of seeds averages out."""
    tilt = np.random.default_rng(10_000 + seed).normal(0.0, tilt_arcsec * ARCSEC, 2)
    return Scenario(plan=plan, rate_hz=rate, state_noise=False, tilt_rad=tuple(tilt), tilt_stated_arcsec=tilt_arcsec)


def main(seeds, rates, plan, tilt_arcsec=5.0):
    print(header(["rate", "rows", "sensor", "rms z", "mean z +- its error", "chi2 / dof (mean)", "warnings"]))
    for rate in rates:
        for averaged in (False, True):
            runs = [scores(scenario(plan, rate, seed, tilt_arcsec), seed, averaged) for seed in range(seeds)]
            for s in SENSORS:
                z = np.array([r[s][0] for r in runs])
                per_seed = z.mean(1)
                err = per_seed.std(ddof=1) / np.sqrt(seeds) if seeds > 1 else float("nan")
                tests = [(r[s][1], r[s][2]) for r in runs if r[s][1] is not None]
                chi2 = f"{np.mean([c for c, _ in tests]):.1f} / {np.mean([d for _, d in tests]):.0f}" if tests else \
                    "none (noise estimated)"
                warned = sum(r[s][3] for r in runs)
                print(f"| {rate:g} Hz | {'averaged' if averaged else 'raw'} | {s} | {np.sqrt(np.mean(z ** 2)):.2f} | "
                      f"{z.mean():+.2f} +- {err:.2f} | {chi2} | {warned}/{seeds} |", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=6, help="seeds per rate (default 6)")
    ap.add_argument("--rates", default="20,100,400", help="sample rates, Hz, comma-separated (default 20,100,400)")
    ap.add_argument("--plan", default="fibonacci48", help="the simulated plan (default fibonacci48)")
    a = ap.parse_args()
    main(a.seeds, [float(r) for r in a.rates.split(",")], a.plan)
