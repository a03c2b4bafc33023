"""Benchmark: `simucal noise BAG` of a long still recording as Kalibr's and imu_utils' users have it, a ROS bag
of sensor_msgs/Imu, beside `simucal noise SET` of the same samples as a measurement set (samples.csv):
the same terms, the time and the peak memory of each whole process.

The bag: white noise and a bias random walk on every axis at --rate-hz for --hours, written by rosbags'
writer (tests/log_writers.py), ROS 1 (--ros 1) or ROS 2 (sqlite3, --ros 2).

    python3 benchmarks/bench_bag_noise.py [--hours 3] [--rate-hz 200] [--ros 1]
"""
import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from bench_raw400 import measure  # noqa: E402
from log_writers import write_bag  # noqa: E402 (the suite's bag writer: rosbags')

from simucal import io  # noqa: E402
from simucal.report.markdown import header  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=3.0)
    ap.add_argument("--rate-hz", type=float, default=200.0)
    ap.add_argument("--ros", type=int, choices=(1, 2), default=1)
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    n = int(round(a.hours * 3600 * a.rate_hz))
    t = np.arange(n) / a.rate_hz
    acc = np.array([0.0, 0.0, 9.80665]) + rng.normal(0, 0.02, (n, 3)) + np.cumsum(rng.normal(0, 1e-5, (n, 3)), 0)
    gyro = rng.normal(0, 2e-3, (n, 3)) + np.cumsum(rng.normal(0, 1e-6, (n, 3)), 0)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bag = tmp / ("still.bag" if a.ros == 1 else "still_bag")
        t0 = time.perf_counter()
        write_bag(bag, t + 1.7e9, acc, gyro, ros=a.ros)
        wrote = time.perf_counter() - t0
        io.write_set(tmp / "set", {"acc_unit": "m/s^2", "gyro_unit": "rad/s", "latitude_deg": 0.0},
                     {"t_s": t, **{c: acc[:, j] for j, c in enumerate(("ax", "ay", "az"))},
                      **{c: gyro[:, j] for j, c in enumerate(("gx", "gy", "gz"))}})
        size = sum(p.stat().st_size for p in ([bag] if bag.is_file() else bag.iterdir())) / 2 ** 20
        runs = {name: measure(["noise", str(src), "-o", str(tmp / f"{name}.json")], None, tmp)
                for name, src in (("bag", bag), ("set", tmp / "set"))}
        reports = {name: json.loads((tmp / f"{name}.json").read_text()) for name in runs}
    same = max(abs(reports["bag"][s]["axes"][x]["terms"][k] - reports["set"][s]["axes"][x]["terms"][k])
               / max(abs(reports["set"][s]["axes"][x]["terms"][k]), 1e-300)
               for s in ("acc", "gyro") for x in "xyz" for k in reports["set"][s]["axes"][x]["terms"])
    print(f"{n:,} messages ({a.hours:g} h at {a.rate_hz:g} Hz), a ROS {a.ros} bag of {size:.0f} MB written in "
          f"{wrote:.1f} s; the terms of the bag and of its samples as a set differ by {same:.2g} (relative, at most)\n")
    print(header(["`simucal noise`, whole process", "wall (s)", "CPU (s)", "peak memory (MB)"]))
    for name, what in (("bag", "the bag"), ("set", "the same samples as a measurement set (samples.csv)")):
        wall, cpu, mb = runs[name]
        print(f"| {what} | {wall:.3g} | {cpu:.3g} | {mb:.0f} |")


if __name__ == "__main__":
    main()
