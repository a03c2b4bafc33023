"""Benchmark: `simucal noise` of a long still recording, the whole-file path beside the chunked one
(goal: 24 h at 200 Hz, 17.3 million rows, in at most 60 s and 2 GB peak).

Generates (a chunk at a time, into a temporary folder removed at the end; never committed) a still
recording of `--hours` at `--rate-hz`: white noise and a gyro rate random walk on six channels,
g and deg/h, written as samples.csv, then `simucal convert --to parquet`. Each run is its own
process, timed whole (wall clock, from start to exit) with its peak resident memory (the process's
own; Dask's workers are not counted), and its CPU time (user + system: on a loaded machine the
wall clock waits for the cores). Rows: the whole-file path (io.read_set then
fit/allan_noise.characterise, as `simucal noise` ran before chunks), `simucal noise` (chunked), and
`simucal noise --scheduler processes` (chunked, theta on disk, the sums on a Dask LocalCluster),
on samples.csv and on samples.parquet; each run's Allan deviations against the whole-file path's
on samples.csv (the largest relative difference over every channel and tau). Rows print as they end.
Usage: python3 benchmarks/bench_long_noise.py [--hours 24] [--rate-hz 200] [--old-max-hours 24]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from simucal.io import columnar, outputs
from simucal.report.markdown import header

NAMES = ["t_s", "ax", "ay", "az", "gx", "gy", "gz"]
OLD = ("import json, sys; from simucal import io, methods; from simucal.fit.allan_noise import characterise; "
       "ms = io.read_set(sys.argv[1]); open(sys.argv[2], 'w').write(json.dumps(characterise(ms, methods.kind_of(ms))))")


def still_chunks(rows, rate_hz, seed=0, chunk=1 << 20):
    """The recording a chunk at a time: gyro 0.1 deg/sqrt(h) white noise and a 0.5 deg/h/sqrt(h) rate
    random walk on biases of 1-3 deg/h, accelerometer 50 ug/sqrt(Hz) on [0, 0, 1] g. (A walk of 10
    deg/h/sqrt(h) over 24 h once broke the positive definiteness of simucal.fit.allan_cov's covariance,
    cancellation in its walk term, since evaluated without it: tests/test_noise.py checks that case.)"""
    rng, dt, walk = np.random.default_rng(seed), 1.0 / rate_hz, np.zeros(3)
    for k0 in range(0, rows, chunk):
        n = min(chunk, rows - k0)
        steps = np.cumsum(0.5 / 60 * np.sqrt(dt) * rng.standard_normal((n, 3)), axis=0) + walk
        walk = steps[-1]
        w = 6.0 / np.sqrt(dt) * rng.standard_normal((n, 3)) + steps + [1.0, 2.0, 3.0]
        f = 50e-6 / np.sqrt(dt) * rng.standard_normal((n, 3)) + [0.0, 0.0, 1.0]
        yield {"t_s": (k0 + np.arange(n)) * dt, **{c: f[:, j] for j, c in enumerate(NAMES[1:4])},
               **{c: w[:, j] for j, c in enumerate(NAMES[4:])}}


def run(cmd) -> tuple[float, float, float, int]:
    """(wall s, CPU s, peak RSS GB, exit status) of one process (CPU and RSS its own, not its children's)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode()[-500:]
    proc.stderr.close()
    if proc.returncode:
        print(f"{' '.join(map(str, cmd))}: exit {proc.returncode}: {err}", file=sys.stderr)
    return time.perf_counter() - t0, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 2 ** 20, proc.returncode


def adev(path) -> np.ndarray:
    report = json.loads(Path(path).read_text())
    return np.concatenate([report[s]["axes"][a]["adev"] for s in ("acc", "gyro") for a in "xyz"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=24.0, help="length of the recording, h (default 24)")
    ap.add_argument("--rate-hz", type=float, default=200.0, help="sample rate, Hz (default 200)")
    ap.add_argument("--old-max-hours", type=float, default=24.0,
                    help="run the whole-file path only up to this length, h (it needs about 0.5 GB per hour at "
                         "200 Hz; default 24)")
    args = ap.parse_args()
    rows = int(args.hours * 3600 * args.rate_hz)
    with tempfile.TemporaryDirectory(prefix="bench-long-noise-") as tmp:
        tmp = Path(tmp)
        csv_set, pq_set = tmp / "csv", tmp / "parquet"
        t0 = time.perf_counter()
        csv_set.mkdir()
        outputs.write_text(csv_set / "meta.json", json.dumps({"format": "simucal.measurements/1", "acc_unit": "g",
                                                             "gyro_unit": "deg/h", "latitude_deg": 45.0}))
        columnar.write_samples(csv_set / "samples.csv", still_chunks(rows, args.rate_hz), NAMES)
        made_s = time.perf_counter() - t0
        convert = run([sys.executable, "-m", "simucal", "convert", str(csv_set), "-o", str(pq_set), "--to", "parquet"])
        size = {s: (s / f"samples.{s.name}").stat().st_size / 1e9 for s in (csv_set, pq_set)}
        print(f"{rows} rows ({args.hours:g} h at {args.rate_hz:g} Hz), generated as CSV in {made_s:.1f} s: "
              f"samples.csv {size[csv_set]:.2f} GB, samples.parquet {size[pq_set]:.2f} GB (convert {convert[0]:.1f} s, "
              f"{convert[1]:.2f} GB peak); {os.cpu_count()} cores, load average before the runs "
              f"{os.getloadavg()[0]:.2f}\n")
        noise = [sys.executable, "-m", "simucal", "noise"]
        runs, ref = {}, None
        print(header(["path", "samples", "wall (s)", "CPU (s)", "peak RSS (GB)",
                      "max rel. diff. of the Allan deviations"]),
              flush=True)
        for name, cmd in (("whole file (before)", None), ("chunked", []), ("chunked, Dask processes",
                                                                            ["--scheduler", "processes"])):
            for s in (csv_set, pq_set):
                out = tmp / f"{len(runs)}.json"
                if cmd is None and args.hours > args.old_max_hours:
                    continue
                full = ([sys.executable, "-c", OLD, str(s), str(out)] if cmd is None
                        else noise + [str(s), "-o", str(out)] + cmd)
                wall, cpu, rss, code = runs[(name, s.name)] = run(full)
                ref = adev(out) if ref is None and not code and cmd is None else ref
                diff = "failed" if code else "-" if ref is None else f"{np.max(np.abs(adev(out) / ref - 1)):.1e}"
                print(f"| {name} | {s.name} | {wall:.1f} | {cpu:.1f} | {rss:.2f} | {diff} |", flush=True)
        chunked = [v for k, v in runs.items() if k[0] == "chunked"]
        met = all(w <= 60 and r <= 2 and not c for w, _, r, c in chunked)
        print(f"\ngoal (chunked, both formats: <= 60 s and <= 2 GB): {'met' if met else 'NOT met'}; "
              f"load average after {os.getloadavg()[0]:.2f}")
        if any(v[3] for v in runs.values()):
            sys.exit(1)


if __name__ == "__main__":
    main()
