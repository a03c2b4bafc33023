"""The speed guard: the headline commands run by an earlier revision's code and by this
working tree's, side by side in one run, alternating, each a whole process; each figure's ratio
now / before (wall, and CPU: on two cores a command's second thread makes its wall time the noisier),
and a verdict on the wall: a figure more than 10 % slower is to be fixed or explained in docs/benchmarks.md.

The commands (docs/benchmarks.md, Speed): the Monte Carlo of dong2018's section 4 with and without an
effect, calibrate and diagnose of imu_tk's Xsens session (../shared/data), diagnose of a rich turntable
set (fibonacci48: 102 segments), calibrate of a raw turntable set (fibonacci24 at 250 Hz: 304,000
rows), the systematic calibration of a psins19 sequence (100 Hz) and the import of a PX4 ULog (a still
board's sensor_accel and sensor_gyro, 10 minutes at 200 and 400 Hz, tests/log_writers.py), which every
revision since the readers came can read. The sets are written once by this checkout; the earlier code is REV's
simucal/, generated/ and derive/ from git, laid out as installed and run with PYTHONPATH. Each figure is the median of
--repeats runs after one that warms the caches (bytecode, compiled models); its spread is printed
beside it, so that a ratio inside the spread reads as noise.

    python3 benchmarks/bench_compare.py [REV] [--repeats 3] [--quick] [--only TEXT]

REV defaults to HEAD (the working tree's change against its commit). --quick: every command at a
size of seconds (a check that the guard runs; its ratios measure little).
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_raw400 import ROOT, alternate, measure, old_tree

from simucal.io.importers import import_imu_tk
from simucal.report.markdown import header

XSENS = ROOT.parent / "shared" / "data" / "imu_tk-xsens"
SLOWER = 1.10  # the guard's threshold: now / before above it is a regression to fix or explain


def sets(tmp: Path, quick: bool) -> dict:
    """The measurement sets the commands read, written once by this checkout."""
    out = {}
    if XSENS.is_dir():
        out["xsens"] = tmp / "xsens"
        import_imu_tk(XSENS / "xsens_acc.mat", XSENS / "xsens_gyro.mat", out["xsens"], 4096.0, 6258 * 3.141592653589793
                      / 180, 45.4, 9.81744)
    for name, args in (("rich", ["--plan", "fibonacci24" if quick else "fibonacci48"]),
                       ("raw", ["--plan", "fibonacci24", "--rate-hz", "20" if quick else "250"])):
        out[name] = tmp / name
        subprocess.run(["simucal", "simulate", "-o", str(out[name]), "--seed", "1", *args], check=True,
                       capture_output=True)
    out["sequence"] = tmp / "sequence"
    subprocess.run(["simucal", "simulate", "-o", str(out["sequence"]), "--seed", "1", "--sequence", "psins19"],
                   check=True, capture_output=True)
    out["ulog"] = tmp / "still.ulg"
    write_still_ulog(out["ulog"], 60.0 if quick else 600.0)
    return out


def write_still_ulog(path: Path, seconds: float) -> None:
    """A still board's ULog, each sensor at its own rate (tests/test_logs.py's board)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from log_writers import write_ulog
    from test_logs import still_board
    write_ulog(path, *still_board(seconds=seconds, acc_hz=200.0, gyro_hz=400.0))


def commands(s: dict, quick: bool) -> list:
    """(figure, simucal arguments) of every headline command; {name} is before or now."""
    trials = "20000" if quick else "200000"
    rows = [(f"montecarlo --scenario paper --trials {trials} --effect acc.quadratic.z=1e-4",
             ["montecarlo", "--scenario", "paper", "--trials", trials, "--effect", "acc.quadratic.z=1e-4"]),
            (f"montecarlo --scenario paper --trials {trials}",
             ["montecarlo", "--scenario", "paper", "--trials", trials])]
    if "xsens" in s:
        rows += [("calibrate, imu_tk's Xsens session", ["calibrate", s["xsens"], "-o", "xs_{name}.json"]),
                 ("diagnose, imu_tk's Xsens session", ["diagnose", s["xsens"], "-o", "xd_{name}.json"])]
    rows += [(f"diagnose, a rich turntable set ({_segments(s['rich'])} segments)",
              ["diagnose", s["rich"], "-o", "rd_{name}.json"]),
             (f"calibrate, a raw turntable set ({_rows(s['raw']):,} rows)",
              ["calibrate", s["raw"], "-o", "rc_{name}.json"]),
             (f"calibrate --method systematic, psins19 ({_rows(s['sequence']):,} rows)",
              ["calibrate", s["sequence"], "--method", "systematic", "-o", "sc_{name}.json"]),
             ("import ulog, a still board's sensor_accel and sensor_gyro",
              ["import", "ulog", s["ulog"], "-o", "ulog_{name}", "--latitude-deg", "47", "--force"])]
    return rows


def _segments(folder: Path) -> int:
    return sum(1 for _ in (folder / "segments.csv").open()) - 1


def _rows(folder: Path) -> int:
    return sum(1 for _ in (folder / "samples.csv").open()) - 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rev", nargs="?", default="HEAD", help="the earlier revision (default HEAD)")
    ap.add_argument("--repeats", type=int, default=3, help="whole processes per code and command (default 3)")
    ap.add_argument("--quick", action="store_true", help="every command at a size of seconds")
    ap.add_argument("--only", default="", help="only the commands whose figure holds this text (e.g. Xsens)")
    a = ap.parse_args()
    now = subprocess.run(["git", "-C", str(ROOT), "describe", "--always", "--dirty"], capture_output=True,
                         text=True).stdout.strip()
    print(f"{os.cpu_count()} cores; load average before {os.getloadavg()[0]:.2f}; before = {a.rev}, now = {now}; "
          f"median of {a.repeats} whole processes each, alternating\n")
    print(header(["command", f"before ({a.rev}), wall s", "now, wall s", "now / before", "CPU now / before",
                  "verdict"]), flush=True)
    worst = 0.0
    with tempfile.TemporaryDirectory(prefix="bench-compare-") as tmp:
        tmp = Path(tmp)
        old = str(old_tree(a.rev, tmp / "old"))
        for what, args in commands(sets(tmp, a.quick), a.quick):
            if a.only not in what:
                continue
            try:
                runs = alternate(args, old, tmp, a.repeats)
            except subprocess.CalledProcessError as e:  # a command the earlier revision does not have;
                # this tree's own run must still succeed (it raises here otherwise: a failure is never excused)
                measure([x.replace("{name}", "now") if isinstance(x, str) else x for x in args], None, tmp)
                said = (e.stderr or "").strip().splitlines() or [f"exit {e.returncode}"]
                print(f"| {what} | cannot run it: {said[-1][:90]} | | | | not compared |", flush=True)
                continue
            walls = {k: [m[0] for m in v] for k, v in runs.items()}
            cpus = {k: statistics.median(m[1] for m in v) for k, v in runs.items()}
            before, after = statistics.median(walls["before"]), statistics.median(walls["now"])
            ratio = after / before
            worst = max(worst, ratio)
            verdict = "SLOWER: fix or explain" if ratio > SLOWER else "faster" if ratio < 1 / SLOWER else "same"
            print(f"| {what} | {_cell(walls['before'])} | {_cell(walls['now'])} | {ratio:.2f} | "
                  f"{cpus['now'] / cpus['before']:.2f} | {verdict} |", flush=True)
    print(f"\nworst ratio {worst:.2f}; load average after {os.getloadavg()[0]:.2f}")


def _cell(walls: list) -> str:
    return f"{statistics.median(walls):.3g} ({min(walls):.3g}-{max(walls):.3g})"


if __name__ == "__main__":
    main()
