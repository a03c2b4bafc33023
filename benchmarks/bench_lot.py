"""Benchmark: a production lot end to end, `simucal calibrate DIR1 DIR2 ... -o FOLDER --scheduler S` then
`simucal lot FOLDER --limits ... --html ...`, and the lot report's outlier and drift rules.

A lot of N simulated units (simucal/turntable/lot.py: each unit's parameters drawn about the design's,
the paper's Table 1 plan, one averaged row per position); every 20th unit from the 6th carries a planted
outlier (one parameter off by 5, 7, 10 or 15 times the lot's spread of units); a tenth of the units is
recorded a second time (the same unit, other noise; the first of them with the gyro's b_z moved by 0.05
deg/h, 7 stds of the drift). Simulating is not timed; calibrate and lot are, as processes, on one process
(`--scheduler local`, no Dask) and on a Dask LocalCluster of 1 and 2 single-threaded workers (started
before the clock). Prints the speed table (files per second) and, from the lot's report: the planted
outliers found, false alarms among the other units, the z tails of their parameters against a normal's,
the drift tests; then over SEEDS lots simulated at the level of the estimates (each unit's value its
truth drawn with the lot's spread plus its calibration's noise, the stds of this lot), the outlier rule's
false-alarm rate per unit (its goal 1e-3) and its power on one planted unit per lot.

    python3 benchmarks/bench_lot.py [N] [--seeds 100] [--workers 1,2]
"""
import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from simucal.api import lot_reporting
from simucal.report import lot_figures
from simucal.turntable.lot import SPREAD, write_lot

SIMUCAL = str(Path(sys.executable).with_name("simucal"))
OFFSETS = (5, 7, 10, 15)  # planted outliers, in the lot's spread of units
PARAMS = ("acc.b_x", "acc.dK_y", "acc.theta_zx", "gyro.b_z", "gyro.dK_x", "gyro.phi_zy")


def _row(group, name):
    """The lot's row of a planted parameter, named as the method names it (acc.b_x): the one vocabulary's entry
    whose own name it is (acc.bias_x)."""
    sensor, param = name.split(".")
    return next(r for r in group["parameters"] if r["name"].startswith(sensor + ".") and r["own_name"] == param)


def _spread(name):
    sensor, param = name.split(".")
    return SPREAD[sensor][param.split("_")[0]]


def planted(n):
    """{unit: {param: offset}}: every 20th unit from the 6th, the offsets and parameters in turn."""
    out = {}
    for k, i in enumerate(range(5, n, 20)):
        name = PARAMS[k % len(PARAMS)]
        out[i] = {name: OFFSETS[k % len(OFFSETS)] * _spread(name)}
    return out


def run(*args):
    t = time.perf_counter()
    r = subprocess.run([SIMUCAL, *map(str, args)], capture_output=True, text=True)
    if r.returncode not in (0,):
        raise SystemExit(f"simucal {' '.join(map(str, args[:3]))} ...: {(r.stdout + r.stderr)[-2000:]}")
    return time.perf_counter() - t


def timed(root, sets, limits, scheduler, label):
    cals = root / f"cals_{label}"
    t_cal = run("calibrate", *sets, "-o", cals, "--scheduler", scheduler)
    t_lot = run("lot", cals, "-o", root / f"lot_{label}.json", "--html", root / f"lot_{label}.html", "--limits", limits)
    return t_cal, t_lot, json.loads((root / f"lot_{label}.json").read_text())


def speed(root, sets, limits, cluster_sizes):
    rows, report = [], None
    t_cal, t_lot, report = timed(root, sets, limits, "local", "local")
    rows.append(("local (one process, no Dask)", "-", t_cal, t_lot))
    from dask.distributed import LocalCluster
    for workers in cluster_sizes:
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=None) as cluster:
            t_cal, t_lot, _ = timed(root, sets, limits, cluster.scheduler_address, f"dask{workers}")
        rows.append(("Dask LocalCluster", workers, t_cal, t_lot))
    print(f"| scheduler | workers | calibrate {len(sets)} sets (s) | lot (s) | total (s) | sets / s |")
    print("|---|---|---|---|---|---|")
    for name, w, c, lt in rows:
        print(f"| {name} | {w} | {c:.1f} | {lt:.2f} | {c + lt:.1f} | {len(sets) / (c + lt):.2f} |")
    return report


def rules(report, plants, n):
    """The outlier and drift rules on this lot: planted found, false alarms, z tails, drift tests."""
    g = report["groups"][0]
    flagged = {u["file"]: u["outliers"] for u in report["units"] if u["outliers"]}
    # each unit's file in the lot: its second recording where it has one (the last calibration counts)
    names = [f"unit{i:04d}_b.json" if f"unit{i:04d}_b.json" in g["units"] else f"unit{i:04d}.json" for i in range(n)]
    print(f"\noutlier rule: {g['outlier_rule']}\n")
    print("| planted unit | parameter | offset (spread of units) | z | flagged |")
    print("|---|---|---|---|---|")
    for i, p in plants.items():
        name = next(iter(p))
        row = _row(g, name)
        z = row["z"][g["units"].index(names[i])]
        print(f"| {names[i]} | {name} | {p[name] / _spread(name):.0f} | {z:.3g} | {names[i] in flagged} |")
    clean = [j for j, u in enumerate(g["units"]) if u in names and names.index(u) not in plants]
    z = np.array([[r["z"][j] for r in g["parameters"]] for j in clean])
    false = sorted(g["units"][j] for j in clean if g["units"][j] in flagged)
    print(f"\nfalse alarms among {len(clean)} units without a planted outlier: {len(false)} {false} (expected "
          f"{len(clean) * lot_reporting.OUTLIER_P:.2g}); their {z.size} |z|: > 2 in {np.mean(np.abs(z) > 2):.2%}, "
          f"> 3 in {np.mean(np.abs(z) > 3):.2%} (a normal's 4.55 %, 0.27 %)")
    print("\n| drift | sensor | chi2 / dof | p | verdict |\n|---|---|---|---|---|")
    planted_drift, rest = report["drift"][:1], report["drift"][1:]
    for d in planted_drift:
        for s, v in d["sensors"].items():
            print(f"| {d['earlier']} -> {d['later']} (gyro b_z moved) | {s} | {v['chi2'] / v['dof']:.3g} | "
                  f"{v['p_value']:.2g} | {v['verdict']} |")
    for s in ("acc", "gyro"):
        v = [d["sensors"][s] for d in rest]
        mean = np.mean([x["chi2"] / x["dof"] for x in v])
        print(f"| {len(v)} units recorded again, nothing moved | {s} | mean {mean:.3g} | lowest "
              f"{min(x['p_value'] for x in v):.2g} | {sum(x['verdict'] == 'drifted' for x in v)} drifted |")
    # each entry's spread of units: the design's for the method's own parameter, else the lot's estimate (a gyro's
    # M entry that the frames' unification moves)
    tau = [_spread(f"{r['name'].split('.')[0]}.{r['own_name']}") if r["own_name"] else r["spread_of_units"]
           for r in g["parameters"]]
    return np.array([r["stds"] for r in g["parameters"]]).T, np.array(tau)


def at_estimates(stds, tau, seeds):
    """The rule over seeds on lots simulated at the level of the estimates: false alarms per unit, and
    the power on one planted unit per lot at each offset (in sqrt(tau^2 + std^2))."""
    rng = np.random.default_rng(2026)
    n, k = stds.shape
    alarms, found = 0, {d: 0 for d in OFFSETS}
    for seed in range(seeds):
        s = stds[rng.integers(0, n, n)]
        x = tau * rng.standard_normal((n, k)) + s * rng.standard_normal((n, k))
        z_max = lot_reporting.threshold(lot_reporting._z(x, s)[3][0], s, seed=seed)
        alarms += int((np.abs(lot_reporting._z(x, s)[0]).max(axis=1) > z_max).sum())
        j = rng.integers(0, k)
        for d in OFFSETS:
            y = x.copy()
            y[0, j] += d * np.sqrt(tau[j] ** 2 + s[0, j] ** 2)
            found[d] += bool(abs(lot_reporting._z(y, s)[0][0, j]) > z_max)
    units = seeds * n
    lo, hi = (max(alarms - 2 * np.sqrt(alarms), 0) / units, (alarms + 2 * np.sqrt(alarms) + 2) / units)
    print(f"\n{seeds} lots of {n} units at the level of the estimates: false alarms {alarms} of {units} units = "
          f"{alarms / units:.2g} per unit (about {lo:.2g} to {hi:.2g}; goal {lot_reporting.OUTLIER_P:g})\n")
    print("| planted offset (sqrt(tau^2 + std^2)) | " + " | ".join(str(d) for d in OFFSETS) + " |")
    print("|---|" + "---|" * len(OFFSETS))
    print(f"| found in {seeds} lots | " + " | ".join(f"{found[d] / seeds:.0%}" for d in OFFSETS) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("n", nargs="?", type=int, default=200, help="units in the lot (default 200)")
    ap.add_argument("--seeds", type=int, default=100, help="lots simulated at the level of the estimates (default 100)")
    ap.add_argument("--workers", default="1,2", help="the LocalClusters' worker counts, comma-separated (default 1,2)")
    a = ap.parse_args()
    plants = planted(a.n)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        sets = write_lot(root / "sets", a.n, seed=0, planted=plants, again=max(2, a.n // 10),
                         drift={0: {"gyro.b_z": 0.05}})
        limits = root / "limits.json"
        limits.write_text(json.dumps({"format": lot_figures.LIMITS_FORMAT, "limits": {
            "acc.b_x": {"min": 0.0002, "max": 0.0014, "unit": "g"},
            "gyro.b_z": {"min": -0.08, "max": 0.04, "unit": "deg/h"}}}))
        report = speed(root, sets, limits, [int(w) for w in a.workers.split(",")])
        print("\n" + "\n".join(report["verdict"][:1]) + " (limits: acc.b_x and gyro.b_z at the design's +- 3 "
              "spreads of units)")
        stds, tau = rules(report, plants, a.n)
    at_estimates(stds, tau, a.seeds)


if __name__ == "__main__":
    main()
