"""Designed rotation sequences (docs/systematic.md): what a design promises against what the calibration
achieves on it, for the default, a tactical and a MEMS unit; and (--table) a designed sequence against the
built-in ones at equal table time.

    python3 benchmarks/bench_sequence_design.py [--minutes 8] [--seeds 20] [--evaluations 60]
                                                [--units default,tactical,mems] [--table]
                                                [--table-minutes 10] [--reference-minutes 12.5]
                                                [--table-evaluations 600]

Part 1 (the default): per unit (Scenario(), simulate.tactical_unit(0), simulate.mems_unit(0)), a sequence
designed for --minutes against psins19 in the same minutes (`simucal plan --sequence psins19 --design`, at most
--evaluations candidates), its promise (each parameter's std from one pass of the linearised filter about the
unit's truth, simulated at seed 0) and its calibrations (calibrate --method systematic) at seeds 1..N: per
parameter the reported std's mean over the promised, the errors' rms over the promised, the rms of error/std
with its chi-square p (N dof: the rms of N standard normals itself spreads, 1.25 is its 95th percentile at 20),
and the largest |error/std|; per unit all parameters together, the lowest parameter's p times their number
(Bonferroni), and each sensor's normalised estimation error squared (e^T C^-1 e with the block's covariance,
chi-square with 9 N dof where the stds and their correlations hold).

Part 2 (--table): each parameter's std over the sequence designed for --table-minutes against psins19's stds in
--reference-minutes, beside psins19, sysclbt19 (PSINS' published 19 positions) and dong2018 as written (10 deg/s
moves) with their rests fitted to --table-minutes, and psins19 in --reference-minutes: the table, and each
column's worst std / psins19's in --reference-minutes (the default unit).
"""
import argparse
import time
from pathlib import Path

import numpy as np

from simucal.api.planning import reference_stds, sequence_stds
from simucal.fit.distributions import chi2_sf
from simucal.turntable import sequence as seq
from simucal.turntable import sequence_design as design
from simucal.turntable.simulate import Scenario, mems_unit, tactical_unit

UNITS = {"default": Scenario, "tactical": lambda: tactical_unit(0), "mems": lambda: mems_unit(0)}


def stds_of(sc):
    return lambda steps: np.array([r["std"] for r in sequence_stds(sc, steps)])


def table(minutes, reference_minutes, evaluations, sc=None, label="the default unit"):
    sc = sc or Scenario()
    columns = {"psins19": seq.in_minutes(seq.psins19(), minutes), "sysclbt19": seq.in_minutes(seq.sysclbt19(), minutes),
               "dong2018": seq.in_minutes(seq.dong2018(), minutes),
               f"psins19 {reference_minutes:g} min": seq.in_minutes(seq.psins19(), reference_minutes)}
    std = {k: stds_of(sc)(v) for k, v in columns.items()}
    target, rows = std[f"psins19 {reference_minutes:g} min"], sequence_stds(sc, columns["psins19"])
    t0 = time.perf_counter()
    found = design.design(stds_of(sc), minutes, target, 60.0, evaluations)
    took = time.perf_counter() - t0
    std = {"designed": found.best.std, **std}
    print(f"\n{label}: stds at {minutes:g} min (psins19 also at {reference_minutes:g} min); designed: "
          f"{len(found.best.steps)} moves at 60 deg/s, {found.evaluations} candidates scored in {took:.0f} s, from "
          f"{found.start}\n")
    print("| parameter | unit | " + " | ".join(std) + " |\n|---|---|" + "---|" * len(std))
    for i, r in enumerate(rows):
        print(f"| {r['sensor']} {r['parameter']} | {r['unit']} | " + " | ".join(f"{v[i]:.3g}" for v in std.values())
              + " |")
    print("| worst of the built-ins' moves turned at 60 deg/s, as the design's | | | " + " | ".join(
        f"{c.worst:.3f}" if c else "no fit" for c in (found.built_in[k] for k in ("psins19", "sysclbt19", "dong2018")))
        + " | |")
    print(f"| worst std / psins19's in {reference_minutes:g} min | | "
          + " | ".join(f"{np.max(v / target):.3f} ({rows[int(np.argmax(v / target))]['parameter']})"
                       for v in std.values()) + " |")


def designed(sc, minutes, evaluations):
    """(the steps designed for the unit against psins19 in the same minutes, their promised stds, the rows)."""
    _, _, rows = reference_stds(sc, "psins19", minutes)
    found = design.design(stds_of(sc), minutes, np.array([r["std"] for r in rows]), 60.0, evaluations)
    return found.best.steps, found.best.std, rows


def achieved(sc, steps, rows, seeds):
    """Per seed the reported stds and errors (rows' order), each sensor's NEES and dof, the model test's p."""
    from simucal.io import MeasurementSet
    from simucal.systematic.method import calibrate_systematic
    from simucal.systematic.observability import against_truth
    out = []
    for seed in seeds:
        meta, samples, segments, truth = seq.simulate_sequence(sc, list(steps), seed)
        cal = calibrate_systematic(MeasurementSet(Path(f"designed_seed{seed}"), meta, samples, segments))
        out.append((*against_truth(cal, truth, rows), cal.acc.p_value))
    return out


def promise_kept(name, minutes, evaluations, seeds):
    """Part 1 for one unit: the table and the summary (module doc)."""
    sc = UNITS[name]()
    t0 = time.perf_counter()
    steps, promised, rows = designed(sc, minutes, evaluations)
    runs = achieved(sc, steps, rows, seeds)
    std, err = np.array([r[0] for r in runs]), np.array([r[1] for r in runs])
    z, n = err / std, len(runs)
    p = np.array([chi2_sf(float(np.sum(np.square(z[:, i]))), n) for i in range(len(rows))])
    print(f"\n{name} unit: {len(steps)} moves designed for {minutes:g} min ({evaluations} candidates at most), "
          f"calibrated at seeds {seeds[0]}-{seeds[-1]} ({time.perf_counter() - t0:.0f} s)\n")
    print("| parameter | promised std | reported / promised | error rms / promised | rms error/std | "
          f"p (chi-square, {n} dof) | largest abs(error/std) (seed) |\n|---|---|---|---|---|---|---|")
    for i, r in enumerate(rows):
        k = int(np.argmax(np.abs(z[:, i])))
        print(f"| {r['sensor']} {r['parameter']} | {promised[i]:.3g} | {np.mean(std[:, i]) / promised[i]:.3f} | "
              f"{np.sqrt(np.mean(np.square(err[:, i]))) / promised[i]:.3f} | "
              f"{np.sqrt(np.mean(np.square(z[:, i]))):.2f} | {p[i]:.3g} | {abs(z[k, i]):.2f} ({seeds[k]}) |")
    nees = "; ".join(
        f"{s} NEES {np.mean([r[2][s][0] for r in runs]):.2f} per seed on {runs[0][2][s][1]} dof (p "
        f"{chi2_sf(float(sum(r[2][s][0] for r in runs)), n * runs[0][2][s][1]):.3g})" for s in ("acc", "gyro"))
    ratio = np.mean(std, axis=0) / promised
    print(f"\n{name}: reported / promised {ratio.min():.3f}-{ratio.max():.3f}; rms error/std "
          f"{np.sqrt(np.mean(np.square(z))):.3f} over all {z.size} "
          f"(p {chi2_sf(float(np.sum(np.square(z))), z.size):.3g}, parameters correlated); "
          f"the lowest parameter's p {p.min():.3g} ({rows[int(np.argmin(p))]['parameter']}), "
          f"x {len(p)} = {min(1.0, len(p) * p.min()):.3g}; {nees}; "
          f"model test passed in {sum(r[3] > 1e-3 for r in runs)} of {n}")
    return p


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=8.0)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--evaluations", type=int, default=60)
    ap.add_argument("--units", default="default,tactical,mems")
    ap.add_argument("--table", action="store_true", help="part 2: the design beside the built-ins")
    ap.add_argument("--table-minutes", type=float, default=10.0)
    ap.add_argument("--reference-minutes", type=float, default=12.5)
    ap.add_argument("--table-evaluations", type=int, default=600)
    a = ap.parse_args()
    units = a.units.split(",")
    if a.seeds:
        seeds = list(range(1, a.seeds + 1))  # seed 0 is the design's own simulation
        p = np.concatenate([promise_kept(u, a.minutes, a.evaluations, seeds) for u in units])
        at = 1.3 ** 2 * len(seeds)
        print(f"\n'every rms error/std <= 1.3' at {len(seeds)} seeds: a filter whose stds are exact meets it with "
              f"probability {1 - chi2_sf(at, len(seeds)):.3f} per parameter, "
              f"{(1 - chi2_sf(at, len(seeds))) ** len(p):.3f} for all {len(p)}; here the lowest p is {p.min():.3g}, "
              f"x {len(p)} = {min(1.0, len(p) * p.min()):.3g}")
    if a.table:
        table(a.table_minutes, a.reference_minutes, a.table_evaluations)


if __name__ == "__main__":
    main()
