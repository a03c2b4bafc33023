"""Benchmark: the long-recording and lot figures in one run, an earlier commit's code (--before, default
a0d9eae: before the chunked readers) beside this checkout's, each figure's runs alternating between the two.

- `simucal calibrate` of the clean raw turntable set at 400 Hz in counts (bench_raw400.make_set,
  1,590,400 rows): wall, CPU and peak memory (goals: <= 1 s wall, <= 3x the file);
- `simucal calibrate A B C --thermal` on three wandering plateaus at 20 Hz
  (simucal.bench.write_plateaus): wall (goal <= 1 s) and its spread from run to run;
- `simucal noise` of a still recording of --hours at 200 Hz (bench_long_noise.still_chunks, CSV):
  wall and peak memory (goals at 24 h: <= 60 s, <= 2 GB);
- a lot of --lot units (simucal.turntable.lot.write_lot): `calibrate ... -o FOLDER --scheduler processes`
  (a Dask LocalCluster of one single-threaded worker a core, running the command's revision), then
  (now only: the command is new) `simucal lot`, units per second;
- with --suite, the README's test command in a fresh clone of each commit (../shared beside it),
  wall seconds (goal <= 120 s).

Each run is a whole process measured by bench_raw400.measure (its own wall, CPU, peak memory). The
machine's load average is printed before and after: on a loaded machine compare the ratios.

    python3 benchmarks/bench_scale.py [--before a0d9eae] [--repeats 3] [--hours 24] [--lot 200] [--suite]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_long_noise import NAMES, still_chunks
from bench_raw400 import ROOT, alternate, make_set, measure, old_tree

from simucal.bench import write_plateaus
from simucal.io import columnar, outputs
from simucal.report.markdown import header
from simucal.turntable.lot import write_lot


def span(values, unit, fmt=".3g") -> str:
    return f"{min(values):{fmt}}-{max(values):{fmt}} {unit}" if len(values) > 1 else f"{values[0]:{fmt}} {unit}"


def still_set(folder: Path, hours: float, rate_hz: float) -> Path:
    folder.mkdir()
    outputs.write_text(folder / "meta.json", json.dumps({"format": "simucal.measurements/1", "acc_unit": "g",
                                                        "gyro_unit": "deg/h", "latitude_deg": 45.0}))
    columnar.write_samples(folder / "samples.csv", still_chunks(int(hours * 3600 * rate_hz), rate_hz), NAMES)
    return folder


def suite_seconds(rev: str, tmp: Path) -> float:
    """The README's test command (its set-up not timed) in a fresh clone of rev with ../shared beside."""
    clone = tmp / "suite" / rev / "repo"
    clone.parent.mkdir(parents=True)
    (clone.parent / "shared").symlink_to(ROOT.parent / "shared")
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    subprocess.run(["git", "-C", str(clone), "checkout", "-q", rev], check=True)
    readme = (clone / "README.md").read_text()
    cmd = next(line for line in readme.splitlines() if "python3 -m pytest" in line)
    test = cmd[cmd.index("python3 -m pytest"):].strip().strip("`")
    t = time.perf_counter()
    r = subprocess.run(test.replace("python3", sys.executable, 1), shell=True, cwd=clone, capture_output=True,
                       text=True)
    wall = time.perf_counter() - t
    if r.returncode:
        print(f"{rev}: the suite failed: {r.stdout[-500:]}", file=sys.stderr)
    return wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="a0d9eae", help="the earlier commit (default a0d9eae)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="whole processes per code and figure after a first (default 3; 0: the first alone)")
    ap.add_argument("--rate-hz", type=float, default=400.0, help="the raw set's sample rate, Hz (default 400)")
    ap.add_argument("--thermal-rate-hz", type=float, default=20.0, help="the plateaus' sample rate, Hz (default 20)")
    ap.add_argument("--hours", type=float, default=24.0, help="the still recording for noise, h at 200 Hz (default 24)")
    ap.add_argument("--lot", type=int, default=200, help="units in the lot (default 200)")
    ap.add_argument("--suite", action="store_true", help="also time the README's test command in fresh clones")
    a = ap.parse_args()
    print(f"{os.cpu_count()} cores; load average before {os.getloadavg()[0]:.2f}; before = {a.before}, now = "
          f"{subprocess.run(['git', '-C', str(ROOT), 'describe', '--always', '--dirty'], capture_output=True, text=True).stdout.strip()}\n")  # noqa: E501
    print(header(["figure", f"before ({a.before})", "now", "goal", "met"]), flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-scale-") as tmp:
        tmp = Path(tmp)
        old = str(old_tree(a.before, tmp / "old"))
        raw = make_set(tmp / "raw", a.rate_hz)
        mb = (raw / "samples.csv").stat().st_size / 2 ** 20
        r = alternate(["calibrate", raw, "-o", str(tmp / "raw_{name}.json")], old, raw, a.repeats)
        full = a.rate_hz == 400 and a.hours == 24 and a.thermal_rate_hz == 20  # the goals are for these sizes
        row(f"calibrate, raw set at {a.rate_hz:g} Hz ({mb:.0f} MB), wall", r, 0, "s", 1.0 if full else None)
        row("the same, CPU (user + system)", r, 1, "s", None)
        row("the same, peak memory", r, 2, "MB", 3 * mb if full else None)
        plateaus = write_plateaus(tmp / "thermal", a.thermal_rate_hz)
        r = alternate(["calibrate", *plateaus, "--thermal", "-o", str(tmp / "th_{name}.json")], old, tmp,
                      a.repeats + 2 if a.repeats else 0)
        row("calibrate --thermal, 3 plateaus, wall", r, 0, "s", 1.0 if full else None)
        still = still_set(tmp / "still", a.hours, 200.0)
        r = alternate(["noise", still, "-o", str(tmp / "n_{name}.json")], old, tmp, min(a.repeats, 1))
        row(f"noise, {a.hours:g} h at 200 Hz (CSV), wall", r, 0, "s", 60.0 if full else None)
        row("the same, peak memory", r, 2, "MB", 2048.0 if full else None)
        lot(tmp, a.lot, old, 2 if a.repeats else 1)
        if a.suite:  # the goal holds at any size: the suite is the same
            walls = {rev: suite_seconds(rev, tmp) for rev in (a.before, "HEAD")}
            cells = [f"{walls[a.before]:.0f} s", f"{walls['HEAD']:.0f} s"]
            print(f"| the suite, the README's command | {cells[0]} | {cells[1]} | <= 120 s | "
                  f"{'yes' if walls['HEAD'] <= 120 else 'no'} |")
    print(f"\nload average after {os.getloadavg()[0]:.2f}")


def row(what, runs, i, unit, goal):
    """One figure: its range before and now, and whether now's worst run meets the goal (None: the
    goal is for other sizes)."""
    now = [m[i] for m in runs["now"]]
    met = "" if goal is None else "yes" if max(now) <= goal else "no"
    print(f"| {what} | {span([m[i] for m in runs['before']], unit)} | {span(now, unit)} | "
          f"{'' if goal is None else f'<= {goal:.3g} {unit}'} | {met} |", flush=True)


def lot(tmp: Path, n: int, old: str, runs: int):
    """A lot of n units on Dask: units per second of `calibrate ... --scheduler processes` (a LocalCluster of
    one single-threaded worker a core, started by the command, its start counted), before and now
    (alternating, runs each: 1 where --repeats is 0, a check that the commands run), and of the lot report (now only:
    the command is new). Each command starts its own cluster, whose workers inherit its PYTHONPATH and so run its
    revision's code: a cluster started here ran this checkout's code for both (sweeps sends the function by
    reference)."""
    sets = write_lot(tmp / "lot", n, seed=0)
    cal = {"before": [], "now": []}
    for k in range(runs):
        for name, path in (("before", old), ("now", None)):
            out = tmp / f"cals_{name}{k}"
            cal[name].append(n / measure(["calibrate", *sets, "-o", out, "--scheduler", "processes"], path, tmp)[0])
    report = n / measure(["lot", tmp / "cals_now0", "-o", tmp / "lot.json"], None, tmp)[0]
    print(f"| a lot of {n} units, calibrate on Dask ({os.cpu_count()} workers, their start counted) | "
          f"{span(cal['before'], 'units/s')} | {span(cal['now'], 'units/s')} | | |", flush=True)
    print(f"| the lot report of those {n} calibrations (simucal lot) | | {report:.3g} units/s | | |", flush=True)


if __name__ == "__main__":
    main()
