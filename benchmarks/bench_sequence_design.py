"""Designed rotation sequences (docs/systematic.md): a designed sequence against the
built-in ones at equal table time, and its stds checked against its errors over seeds.

    python3 benchmarks/bench_sequence_design.py [--minutes 10] [--reference-minutes 12.5] [--seeds 20]
                                                [--evaluations 600] [--mems]

Part 1: each parameter's std (one pass of the linearised filter, the default unit, 100 Hz) over the
sequence designed for --minutes against psins19's stds in --reference-minutes (`simucal plan --sequence
--design`), and over psins19, sysclbt19 (PSINS' published 19 positions) and dong2018 as written (10 deg/s
moves) with their rests fitted to --minutes, and psins19 in --reference-minutes: the table, and each
column's worst std / psins19's in --reference-minutes. Part 2: the designed sequence simulated and
calibrated (calibrate --method systematic) at seeds 0..N-1: rms and largest |error / std| per sensor and
the model tests passed. Part 3 (--mems): the same design for a MEMS unit (simulate.mems_unit(0))
at equal table time, its worst ratio against the built-ins'.
"""
import argparse
import time

import numpy as np

from simucal.api.planning import sequence_stds
from simucal.turntable import sequence as seq
from simucal.turntable import sequence_design as design
from simucal.turntable.simulate import Scenario, mems_unit


def table(minutes, reference_minutes, evaluations, sc=None, label="the default unit"):
    sc = sc or Scenario()
    columns = {"psins19": seq.in_minutes(seq.psins19(), minutes), "sysclbt19": seq.in_minutes(seq.sysclbt19(), minutes),
               "dong2018": seq.in_minutes(seq.dong2018(), minutes),
               f"psins19 {reference_minutes:g} min": seq.in_minutes(seq.psins19(), reference_minutes)}

    def stds_of(steps):
        return np.array([r["std"] for r in sequence_stds(sc, steps)])
    std = {k: stds_of(v) for k, v in columns.items()}
    target, rows = std[f"psins19 {reference_minutes:g} min"], sequence_stds(sc, columns["psins19"])
    t0 = time.perf_counter()
    found = design.design(stds_of, minutes, target, 60.0, evaluations)
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
    return found.best


def honest(best, seeds, sc=None):
    """The designed sequence calibrated at seeds 0..N-1: its stds against its errors."""
    from pathlib import Path

    from simucal.io import MeasurementSet
    from simucal.systematic.method import calibrate_systematic
    z, passed = {"acc": [], "gyro": []}, 0
    for seed in range(seeds):
        meta, samples, segments, truth = seq.simulate_sequence(sc or Scenario(), list(best.steps), seed)
        cal = calibrate_systematic(MeasurementSet(Path(f"designed_seed{seed}"), meta, samples, segments))
        passed += cal.acc.p_value > 1e-3
        for s in z:
            block = getattr(cal, s)
            z[s] += [(block.params[k] - truth[s]["params"][k]) / block.std[k] for k in block.params]
    print(f"\ndesigned sequence calibrated at seeds 0-{seeds - 1}: " + "; ".join(
        f"{s} rms error/std {np.sqrt(np.mean(np.square(v))):.2f}, largest {np.max(np.abs(v)):.2f}" for s, v in z.items())
        + f"; model test passed in {passed} of {seeds}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--reference-minutes", type=float, default=12.5)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--evaluations", type=int, default=600)
    ap.add_argument("--mems", action="store_true", help="part 3: a MEMS unit")
    a = ap.parse_args()
    best = table(a.minutes, a.reference_minutes, a.evaluations)
    if a.seeds:
        honest(best, a.seeds)
    if a.mems:
        sc = mems_unit(0)
        best = table(a.minutes, a.minutes, a.evaluations, sc, "a MEMS unit (simulate.mems_unit(0))")
        if a.seeds:
            honest(best, min(a.seeds, 10), sc)


if __name__ == "__main__":
    main()
