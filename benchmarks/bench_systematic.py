"""Systematic calibration: the filter's stds against its errors over seeds, and the
whole process's time on a long sequence (docs/systematic.md).

    python3 benchmarks/bench_systematic.py [--seeds 50] [--rest-s 30] [--speed-hours 1] [--compare-seeds 10]

Part 1: psins19 with rests of --rest-s, seeds 0..N-1 of the default unit (simulate --sequence):
rms of (estimate - truth) / std per parameter and over all, the largest |error / std|, the mean
NIS per update (3 for a consistent filter). Part 2 (--speed-hours > 0): psins19 with its rests
stretched to fill that many hours at 100 Hz, `simucal calibrate --method systematic` timed as a
whole process (reading the set, every pass, writing the file): wall and CPU (user + sys; the wall
of a shared machine is its load's). Part 3 (--compare-seeds): the same unit by exact and
multiposition (table1 with its rate runs, 10 s per position at 100 Hz) and systematic (psins19, 30 s
rests, and a sequence designed for the unit in the same table time against the built-ins' best
stds, plan --sequence best --design), tables
of angle errors 1, 10 and 60 arcsec (uniform +- each, each axis, each position) and poor ones, 60
arcsec with its rate off by 10 or 100 ppm in the rate runs or with 600 arcsec of tilt and
non-perpendicular axes; a MEMS unit on a good and a poor table; lever arms of 1-5 cm and a 1-5 ms
delay: per group (M, bias of each sensor) the rms error against the truth over the seeds, the rms
stated std and the rms error / std.
"""
import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import simucal
from simucal.errors import CalibrationError
from simucal.generated import table
from simucal.io import MeasurementSet
from simucal.systematic.calibrate import run_filter
from simucal.turntable.sequence import duration_s, psins19, simulate_sequence
from simucal.turntable.simulate import ARCSEC, Scenario, lever_arms_and_delay, mems_unit
from simucal.turntable.simulate import simulate as simulate_table


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
    t0, cpu0 = time.perf_counter(), _children_cpu()
    r = subprocess.run([sys.executable, "-m", "simucal", "calibrate", str(folder / "long"), "--method", "systematic",
                        "-o", str(folder / "long.json")], capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    assert r.returncode == 0, r.stderr
    rows = sum(1 for _ in open(folder / "long" / "samples.csv")) - 1
    print("\n| length | rows | rests | simucal calibrate --method systematic, whole process |\n|---|---|---|---|")
    print(f"| {hours:g} h at 100 Hz | {rows} | {rest_s:.0f} s | {wall:.1f} s wall, {cpu:.1f} s CPU, load "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores |")


def _children_cpu():
    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return u.ru_utime + u.ru_stime


GROUPS = {"acc M": ("acc", 1e6, "ppm"), "gyro M": ("gyro", 1e6, "ppm"), "acc bias": ("acc", 1e6, "ug"),
          "gyro bias": ("gyro", 1.0, "deg/h")}
# (unit, angle error arcsec, rate error, tilt and non-perpendicularity arcsec: 5 the simulator's default); the
# units: the default (navigation grade), a MEMS unit (simulate.mems_unit, one per seed), the default with
# lever arms of 1-5 cm and a 1-5 ms accelerometer delay (simulate.lever_arms_and_delay, the filter given their
# states; a turntable test's accelerometers rest, so exact and multiposition do not see them)
TABLES = [("default", 1.0, 0.0, 5.0), ("default", 10.0, 0.0, 5.0), ("default", 60.0, 0.0, 5.0),
          ("default", 60.0, 1e-5, 5.0), ("default", 60.0, 1e-4, 5.0), ("default", 60.0, 0.0, 600.0),
          ("MEMS", 1.0, 0.0, 5.0), ("MEMS", 60.0, 0.0, 600.0), ("lever arms", 1.0, 0.0, 5.0)]
METHODS = ("exact", "multiposition", "systematic psins19", "systematic designed")


def _group_errors(cal, truth):
    """{group: (errors, stds)} of one calibration against the truth, each in the frame the method
    calibrates in: exact and systematic the models' parameters in b (scale factors and misalignments
    for M), multiposition the entries of its affine M in the table's frame k (the truth's M_b C_b^k)."""
    out = {}
    for group, (s, _, _) in GROUPS.items():
        block, t = getattr(cal, s), truth[s]
        if block.params:
            names = [k for k in block.params if (k.startswith("b_") == group.endswith("bias"))]
            err = np.array([block.params[k] - t["params"][k] for k in names])
            std = np.array([block.std[k] for k in names])
        elif group.endswith("bias"):
            err, std = block.bias - np.array(t["bias"]), np.array(block.std["bias"])
        else:
            mount = truth["mounting"]["theta4_rad" if s == "acc" else "lambda4_rad"]
            M_d = np.array(t["M"] if s == "acc" else t["M_in_d"])
            err = (block.M - M_d @ table.mounting(np.array(mount)).T).ravel()
            std = np.array(block.std["M"]).ravel()
        out[group] = (err, std)
    return out


def _unit(kind, seed):
    """(the unit's scenario, the effects the filter is given) of a TABLES row's unit at seed."""
    if kind == "MEMS":
        return mems_unit(seed), ()
    sc = Scenario()
    if kind == "lever arms":
        sc.acc_effects = lever_arms_and_delay(seed)
    return sc, tuple(sc.acc_effects)


def _sets(seed, row, sequences):
    """The same unit on one table (TABLES' row): Table 1 with its rate runs (10 s per position at
    100 Hz) and each sequence. meta.json states the table's levelling (table_tilt_arcsec), as a user
    of a levelled table does: the outer axis's tilt turns the Earth rate's horizontal part into the
    rate runs' norm, a common gyro scale (7e-9 at 5 arcsec) that exact's stds hold only where stated."""
    kind, arcsec, rate_error, geometry = row
    sc, added = _unit(kind, seed)
    sc.rate_hz, sc.position_error_rad, sc.rate_error = 100.0, arcsec * ARCSEC, rate_error
    sc.tilt_rad = sc.nonperp_rad = (geometry * ARCSEC,) * 2
    sc.tilt_stated_arcsec = geometry
    sets = {}
    for name, (meta, samples, segments, truth) in [("table1", simulate_table(sc, seed))] + [
            (name, simulate_sequence(sc, steps, seed)) for name, steps in sequences[kind].items()]:
        ms = MeasurementSet(Path(f"{name}_seed{seed}"), meta, samples, segments)
        ms.truth = truth
        sets[name] = ms
    return sets, added


def _designed(sc, steps):
    """A sequence designed for the unit sc in the table time of `steps`, each parameter's target the best
    std of the built-ins in that time (plan --sequence best --design)."""
    from simucal.api.planning import reference_stds, sequence_stds
    from simucal.turntable import sequence_design

    def stds_of(s):
        return np.array([r["std"] for r in sequence_stds(sc, s)])
    minutes = duration_s(steps) / 60.0
    target = np.array([r["std"] for r in reference_stds(sc, "best", minutes)[2]])
    return list(sequence_design.design(stds_of, minutes, target, 60.0, 600).best.steps)


def comparison(seeds, units=("default", "MEMS", "lever arms")):
    """exact, multiposition and systematic (psins19 with 30 s rests, and a sequence designed for the unit in
    the same table time) on the same unit under each table of TABLES: per group, the rms error over the
    seeds and the group's entries, the rms of the stated stds and the rms of error / std."""
    psins = psins19(rest_s=30.0)
    sequences = {kind: {"systematic psins19": psins, "systematic designed": _designed(_unit(kind, 0)[0], psins)}
                 for kind in ("default", "MEMS")}
    sequences["lever arms"] = sequences["default"]
    print(f"\n{seeds} seeds per cell; per group: rms error / rms std (rms of error / std); the designed sequences "
          f"last psins19's {duration_s(psins) / 60:.3g} min ({len(sequences['default']['systematic designed'])} "
          f"moves for the default unit, {len(sequences['MEMS']['systematic designed'])} for a MEMS unit)\n")
    print("| unit | angle error | rate error (ppm) | tilt, non-perp. | method | "
          + " | ".join(f"{g} ({u})" for g, (_, _, u) in GROUPS.items()) + " |\n|---|---|---|---|---|"
          + "---|" * len(GROUPS))
    for row in [r for r in TABLES if r[0] in units]:
        cells = {m: {g: [] for g in GROUPS} for m in METHODS}
        refused = {m: 0 for m in METHODS}
        for seed in range(seeds):
            sets, added = _sets(seed, row, sequences)
            for method in METHODS:
                name = "table1" if method in ("exact", "multiposition") else method
                kwargs = {"add": list(added)} if name != "table1" and added else {}
                try:
                    cal = simucal.calibrate(sets[name], method=method.split()[0], **kwargs)
                except CalibrationError:  # counted and said: a refusal is the method's answer on that set
                    refused[method] += 1
                    continue
                for g, e in _group_errors(cal, sets[name].truth).items():
                    cells[method][g].append(e)
        for method, groups in cells.items():
            if refused[method]:
                method = f"{method} ({refused[method]} of {seeds} refused)"
            if not groups["acc M"]:
                print("| {} | {:g}\" | {:g} | {:g}\" | ".format(row[0], row[1], 1e6 * row[2], row[3]) + f"{method} |"
                      + " - |" * len(GROUPS))
                continue
            out = []
            for g, (_, k, _) in GROUPS.items():
                err, std = (np.concatenate([e[i] for e in groups[g]]) for i in (0, 1))
                rms = np.sqrt(np.mean(err ** 2))
                out.append(f"{k * rms:.3g} / {k * np.sqrt(np.mean(std ** 2)):.3g} "
                           f"({np.sqrt(np.mean((err / std) ** 2)):.2g})")
            print("| {} | {:g}\" | {:g} | {:g}\" | ".format(row[0], row[1], 1e6 * row[2], row[3])
                  + f"{method} | " + " | ".join(out) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50, help="seeds of part 1 (default 50)")
    ap.add_argument("--rest-s", type=float, default=30.0, help="part 1's rests, s (default 30)")
    ap.add_argument("--speed-hours", type=float, default=1.0, help="part 2's length, h; 0 leaves it out (default 1)")
    ap.add_argument("--compare-seeds", type=int, default=10, help="part 3's seeds per table (default 10; 0: none)")
    ap.add_argument("--compare-units", default="default,MEMS,lever arms", help="part 3's units (default all three)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if a.seeds > 0:
            consistency(a.seeds, a.rest_s, Path(tmp))
        if a.speed_hours > 0:
            speed(a.speed_hours, Path(tmp))
        if a.compare_seeds > 0:
            comparison(a.compare_seeds, a.compare_units.split(","))


if __name__ == "__main__":
    main()
