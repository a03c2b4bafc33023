"""`simucal calibrate` of a clean raw turntable set at 400 Hz in counts, this
checkout's code beside an earlier commit's, measured in one run, alternating.

The set: `simucal simulate --plan PLAN.csv --rate-hz RATE` (pulse/s, the paper's counts) over 84
Fibonacci positions (1,590,400 rows at 400 Hz), its outputs then written to 0.001 pulse/s and its
times to 0.1 ms as a logger writes fixed-point numbers (the simulator's 17 digits make a file 1.8
times larger). Each run is a whole process; its wall time, CPU time (user + system) and peak
resident memory are those of the command alone (measured in a wrapper process around it). The
earlier commit's code (--before, default a0d9eae: before the chunked readers) is its `simucal/` package from
git, run with PYTHONPATH. Goals: <= 1 s whole process, <= 3x the file in peak memory.

    python3 benchmarks/bench_raw400.py [--rate-hz 400] [--repeats 3] [--before a0d9eae]
"""
import argparse
import json
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SIMUCAL = [sys.executable, "-m", "simucal"]
# the wrapper: the command's own wall time, CPU time and peak memory (its only child)
WRAP = ("import resource, subprocess, sys, time; t = time.perf_counter(); "
        "r = subprocess.run(sys.argv[1:], capture_output=True); w = time.perf_counter() - t; "
        "r.returncode and sys.exit(r.stderr.decode()); "  # the command's own message where it fails
        "u = resource.getrusage(resource.RUSAGE_CHILDREN); print(w, u.ru_utime + u.ru_stime, u.ru_maxrss)")


def make_set(folder: Path, rate_hz: float) -> Path:
    """The 400 Hz set (see the docstring), written by simucal simulate and rounded as a logger writes."""
    from simucal.turntable import plans
    folder.mkdir(parents=True)
    plan = folder / "fibonacci84.csv"
    np.savetxt(plan, plans.fibonacci(84), delimiter=",", header="outer_deg,middle_deg,inner_deg", comments="",
               fmt="%.6f")
    out = folder / "set"
    subprocess.run([*SIMUCAL, "simulate", "-o", str(out), "--plan", str(plan), "--rate-hz", str(rate_hz), "--seed",
                    "1"], check=True, capture_output=True)
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    table = pa_csv.read_csv(out / "samples.csv")
    cols = {c: np.round(np.asarray(table.column(c)), 0 if c == "segment" else 4 if c == "t_s" else 3)
            for c in table.column_names}
    cols["segment"] = cols["segment"].astype(np.int64)
    with (out / "samples.csv").open("wb") as fh:  # the header unquoted, the numbers by Arrow's writer
        fh.write((",".join(table.column_names) + "\n").encode())
        pa_csv.write_csv(pa.table(cols), fh, pa_csv.WriteOptions(include_header=False))
    return out


def old_tree(rev: str, into: Path) -> Path:
    """The simucal package of commit rev, unpacked under into as pyproject.toml installs it: simucal/,
    with the top-level generated/ and derive/ as simucal.generated and simucal.derive (so the earlier
    code runs its own generated modules, not this checkout's)."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "simucal", "generated", "derive"], check=True,
                             capture_output=True)
    with tarfile.open(fileobj=BytesIO(archive.stdout)) as tar:
        tar.extractall(into, filter="data")
    for name in ("generated", "derive"):
        (into / name).rename(into / "simucal" / name)
    return into


def measure(args: list, pythonpath: str | None, cwd: Path) -> tuple:
    """(wall s, CPU s, peak resident MB) of one whole `simucal ARGS` process: this checkout's code,
    or the code under pythonpath (run from cwd, since -m imports from the cwd first)."""
    import os
    # PYTHONDONTWRITEBYTECODE dropped: the runs after the first import the bytecode a user's installation has
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONDONTWRITEBYTECODE")}
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    r = subprocess.run([sys.executable, "-c", WRAP, *SIMUCAL, *map(str, args)], check=True, capture_output=True,
                       text=True, env=env, cwd=cwd)
    wall, cpu, kb = r.stdout.split()
    return float(wall), float(cpu), int(kb) / 1024


def alternate(args, old: str, cwd: Path, repeats: int) -> dict:
    """{"before": [(wall, CPU, MB)], "now": [...]} of `simucal ARGS` ("{name}" in an argument replaced by
    before/now), run by the code under old and by this checkout's, alternating: repeats runs each after
    one that writes the bytecode (repeats 0: that one alone, a check that the command runs)."""
    runs = {"before": [], "now": []}
    for k in range(repeats + 1):
        for name, path in (("before", old), ("now", None)):
            m = measure([a.replace("{name}", name) if isinstance(a, str) else a for a in args], path, cwd)
            if k or not repeats:
                runs[name].append(m)
    return runs


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate-hz", type=float, default=400.0, help="the set's sample rate, Hz (default 400)")
    ap.add_argument("--repeats", type=int, default=3, help="whole processes per code, alternating (default 3)")
    ap.add_argument("--before", default="a0d9eae", help="the earlier commit to run beside (default a0d9eae)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        folder = make_set(tmp / "raw", a.rate_hz)
        rows = sum(1 for _ in (folder / "samples.csv").open()) - 1
        mb = (folder / "samples.csv").stat().st_size / 2 ** 20
        old = str(old_tree(a.before, tmp / "old"))
        runs = alternate(["calibrate", folder, "-o", str(tmp / "{name}.json")], old, folder, a.repeats)
        same = json.loads((tmp / "before.json").read_text())["acc"]["params"].keys() == \
            json.loads((tmp / "now.json").read_text())["acc"]["params"].keys()
    print(f"{rows:,} rows at {a.rate_hz:g} Hz, samples.csv {mb:.0f} MB; {a.repeats} runs each, alternating; "
          f"the same parameters fitted: {same}\n")
    print(f"| `simucal calibrate`, whole process | before ({a.before}) | now | goal |\n|---|---|---|---|")
    for i, (what, unit, goal) in enumerate((("wall", "s", "<= 1 s"), ("CPU (user + system)", "s", ""),
                                            ("peak resident memory", "MB", f"<= {3 * mb:.0f} MB (3x the file)"))):
        cells = []
        for name in ("before", "now"):
            v = [m[i] for m in runs[name]]
            cells.append(f"{min(v):.3g}-{max(v):.3g} {unit}" + (f" ({max(v) / mb:.2g}x the file)" if i == 2 else ""))
        print(f"| {what} | {cells[0]} | {cells[1]} | {goal} |")


if __name__ == "__main__":
    main()
