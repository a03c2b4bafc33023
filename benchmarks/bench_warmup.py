"""Benchmark: a still warm-up (15 -> 60 degC, a cubic bias on every axis, white noise and a wandering bias) as
a PX4 ULog, calibrated by simucal (`import ulog`, `calibrate --thermal`) and by the two autopilots' methods
on the same samples, each curve's error against the planted truth over seeds.

The autopilots' tools are not vendored here (their code is theirs); their methods are run as their
documentation and source describe them (docs/temperature.md), and where a copy of a tool is given
(--px4-tool FILE: PX4's Tools/process_sensor_caldata.py; --ardupilot-tool FILE: ArduPilot's
Tools/scripts/tempcal_IMU.py) the tool itself runs too, on the same samples (the ULog, with a still
barometer, which PX4's script needs; for ArduPilot the same samples as a DataFlash log of IMU
messages), and its parameter file is read back: PX4's Tools/process_sensor_caldata.py takes
a 31-sample median filter, means over 2,000 equal temperature bins and a cubic in (T - T_ref), T_ref the
middle of the range, the accelerometer less its median reading; ArduPilot's Tools/scripts/tempcal_IMU.py a
2 s moving mean and a cubic in (T - 35), its constant dropped. Errors: the rms over the temperature range
of each axis's curve less the truth, the gyro's whole bias (simucal, PX4) and every sensor's change from
35 degC (all three: ArduPilot keeps no constant, the accelerometer's is gravity's).

    python3 benchmarks/bench_warmup.py [--seeds 5] [--minutes 30] [--px4-tool FILE] [--ardupilot-tool FILE]
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.signal import medfilt

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from log_writers import write_dataflash, write_ulog  # noqa: E402 (the suite's writers, by the formats' specifications)

from simucal.io import calibration  # noqa: E402
from simucal.report.markdown import header  # noqa: E402

G = 9.80665
ACC = np.array([[0.02, 4e-4, -2e-5, 1e-6], [-0.01, -3e-4, 1e-5, 2e-6], [0.015, 2e-4, 3e-5, -1.5e-6]])  # m/s^2
GYRO = np.array([[2e-3, 3e-5, -6e-7, 2e-8], [-1e-3, -2e-5, 4e-7, 1.5e-8], [5e-4, 1.5e-5, 3e-7, -2e-8]])  # rad/s
T_MID = 37.5


def log(path: Path, seed: int, minutes: float, hz=100.0):
    """The ULog of one warm-up, each sensor at hz with its own jittered stamps (tests/test_logs.py's board)."""
    rng = np.random.default_rng(seed)

    def topic(truth, white, walk, device_id):
        t = np.arange(0, minutes * 60, 1 / hz) + rng.uniform(0, 0.1 / hz, int(round(minutes * 60 * hz)))
        T = 15 + 45 * (1 - np.exp(-t / (minutes * 60 / 3.0)))
        xyz = ((T - T_MID)[:, None] ** np.arange(4)) @ truth.T + rng.normal(0, white, (len(t), 3)) \
            + np.cumsum(rng.normal(0, walk, (len(t), 3)), axis=0)
        return {"t_us": np.round(t * 1e6), "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "temperature": T,
                "device_id": device_id}
    acc = topic(ACC + np.array([[0, 0, 0, 0], [0, 0, 0, 0], [-G, 0, 0, 0]]), 0.02, 2e-5, 1442826)
    gyro = topic(GYRO, 2e-3, 2e-7, 2490378)
    baro = {"t_us": gyro["t_us"][::4], "pressure": np.full(len(gyro["t_us"][::4]), 1013.25),
            "temperature": gyro["temperature"][::4], "device_id": 4653065}
    write_ulog(path, acc, gyro, baro=baro)
    # the same samples as ArduPilot logs them: one IMU message holds both sensors (at the gyro's stamps)
    write_dataflash(path.with_suffix(".bin"), {"t_us": gyro["t_us"], "temperature": gyro["temperature"],
                                               "acc": np.c_[acc["x"], acc["y"], acc["z"]],
                                               "gyro": np.c_[gyro["x"], gyro["y"], gyro["z"]]})
    return acc, gyro


def tool_params(cmd, cwd: Path, out: Path) -> dict:
    """Run an autopilot's own script and read the parameter file it writes ({name: value})."""
    subprocess.run(cmd, cwd=cwd, check=True, capture_output=True, env={**os.environ, "MPLBACKEND": "Agg"})
    params = {}
    for line in out.read_text().splitlines():
        f = line.split()
        if len(f) >= 2 and not line.startswith("#"):
            name, value = (f[2], f[3]) if len(f) >= 5 else (f[0], f[1])  # QGC's .params, or NAME VALUE
            params[name] = float(value)
    return params


def px4_tool_curve(params, sensor, i):
    """A TC_* curve of PX4's own .params: (coefficients in T - T_ref, T_ref), in the log's units."""
    p = f"TC_{'G' if sensor == 'gyro' else 'A'}0"
    return np.array([params[f"{p}_X{k}_{i}"] for k in range(4)]), params[f"{p}_TREF"]


def ardupilot_tool_curve(params, sensor, i):
    """An INS_TCAL1_* curve of ArduPilot's own .parm: (coefficients in T - 35, 35), its constant 0."""
    p = f"INS_TCAL1_{'GYR' if sensor == 'gyro' else 'ACC'}"
    return np.r_[0.0, [params[f"{p}{k}_{'XYZ'[i]}"] * 1e-6 for k in (1, 2, 3)]], 35.0


def px4(T, y, accel):
    """PX4's process_sensor_caldata.py, as its source describes it: (coefficients in T - T_ref, T_ref)."""
    t_ref = (T.min() + T.max()) / 2
    v = medfilt(y, 31)
    if accel:
        v = v - np.median(v)
    edges = np.linspace(T.min(), T.max(), 2001)
    k = np.clip(np.digitize(T, edges) - 1, 0, 1999)
    n = np.bincount(k, minlength=2000)
    keep = n > 0
    Tb, vb = np.bincount(k, T, 2000)[keep] / n[keep], np.bincount(k, v, 2000)[keep] / n[keep]
    return np.polyfit(Tb - t_ref, vb, 3)[::-1], t_ref


def ardupilot(T, y, hz):
    """ArduPilot's tempcal_IMU.py, as its source describes it: a 2 s moving mean, a cubic in (T - 35)."""
    w = int(2 * hz)
    v = np.convolve(y, np.ones(w) / w, mode="valid")
    Tv = np.convolve(T, np.ones(w) / w, mode="valid")
    c = np.polyfit(Tv - 35.0, v, 3)[::-1]
    c[0] = 0.0
    return c, 35.0


def curve(c, t_ref, grid):
    return np.polynomial.polynomial.polyval(grid - t_ref, c)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--minutes", type=float, default=30.0, help="the warm-up's length (default 30)")
    ap.add_argument("--px4-tool", type=Path, help="a copy of PX4's Tools/process_sensor_caldata.py: run it too")
    ap.add_argument("--ardupilot-tool", type=Path, help="a copy of ArduPilot's Tools/scripts/tempcal_IMU.py: run it too")
    a = ap.parse_args()
    tools = ["simucal", "PX4", "ArduPilot"] + ["PX4's tool"] * bool(a.px4_tool) + ["ArduPilot's tool"] * bool(
        a.ardupilot_tool)
    errors = {f"{what}, {tool}": [] for what in ("gyro whole", "gyro change", "acc change") for tool in tools
              if not (what == "gyro whole" and "ArduPilot" in tool)}
    times = {"simucal (import ulog + calibrate --thermal)": [], "PX4's method": [], "ArduPilot's method": [],
             **({"PX4's tool (process_sensor_caldata.py)": []} if a.px4_tool else {}),
             **({"ArduPilot's tool (tempcal_IMU.py)": []} if a.ardupilot_tool else {})}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for seed in range(a.seeds):
            acc, gyro = log(tmp / f"w{seed}.ulg", seed, a.minutes)
            t0 = time.perf_counter()
            for cmd in (["import", "ulog", str(tmp / f"w{seed}.ulg"), "-o", str(tmp / f"s{seed}"), "--latitude-deg", "47"],
                        ["calibrate", str(tmp / f"s{seed}"), "--thermal", "-o", str(tmp / f"c{seed}.json")]):
                subprocess.run([sys.executable, "-m", "simucal", *cmd], check=True, capture_output=True)
            times["simucal (import ulog + calibrate --thermal)"].append(time.perf_counter() - t0)
            cal = calibration.load(tmp / f"c{seed}.json")
            own = {}
            if a.px4_tool:
                t0 = time.perf_counter()
                own["PX4's tool"] = (tool_params([sys.executable, str(a.px4_tool.resolve()), f"w{seed}.ulg"], tmp,
                                                 tmp / f"w{seed}.ulg.params"), px4_tool_curve)
                times["PX4's tool (process_sensor_caldata.py)"].append(time.perf_counter() - t0)
            if a.ardupilot_tool:
                t0 = time.perf_counter()
                own["ArduPilot's tool"] = (tool_params(
                    [sys.executable, str(a.ardupilot_tool.resolve()), "--no-graph", "--outfile", f"w{seed}.parm",
                     f"w{seed}.bin"], tmp, tmp / f"w{seed}.parm"), ardupilot_tool_curve)
                times["ArduPilot's tool (tempcal_IMU.py)"].append(time.perf_counter() - t0)
            for sensor, data, truth, per in (("gyro", gyro, GYRO, np.radians(1 / 3600)), ("acc", acc, ACC, G)):
                T = data["temperature"]
                grid = np.linspace(T.min(), T.max(), 200)
                th = getattr(cal, sensor).thermal
                for i, axis in enumerate("xyz"):
                    want = curve(truth[i], T_MID, grid)
                    ours = curve(np.array(th["parameters"][f"b_{axis}"]["coefficients"]) * per, th["t_ref_c"], grid)
                    t0 = time.perf_counter()
                    theirs = px4(T, data[axis], sensor == "acc")
                    times["PX4's method"].append(time.perf_counter() - t0)
                    t0 = time.perf_counter()
                    dropped = ardupilot(T, data[axis], 100.0)
                    times["ArduPilot's method"].append(time.perf_counter() - t0)
                    px = curve(*theirs, grid)
                    at35 = np.searchsorted(grid, 35.0)
                    change = lambda v: v - v[at35]  # noqa: E731
                    if sensor == "gyro":
                        errors["gyro whole, simucal"].append(ours - want)
                        errors["gyro whole, PX4"].append(px - want)
                    curves = {"simucal": ours, "PX4": px, "ArduPilot": curve(*dropped, grid),
                              **{tool: curve(*read(params, sensor, i), grid) for tool, (params, read) in own.items()}}
                    if sensor == "gyro" and "PX4's tool" in curves:
                        errors["gyro whole, PX4's tool"].append(curves["PX4's tool"] - want)
                    for tool, v in curves.items():
                        errors[f"{sensor} change, {tool}"].append(change(v) - change(want))
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errors.items()}
    print(f"{a.seeds} warm-ups of {a.minutes:g} min at 100 Hz, 15 -> 60 degC, a cubic bias on every axis, white noise "
          "and a random walk of the bias\n")
    print(header(["curve against the truth (rms over 15-60 degC, every axis and seed)", "simucal", "PX4's method",
                  "ArduPilot's method"] + tools[3:] + ["simucal / best other"]))
    for what, unit, scale in (("gyro, whole bias", "rad/s", "gyro whole"), ("gyro, change from 35 degC", "rad/s",
                                                                           "gyro change"),
                              ("acc, change from 35 degC", "m/s^2", "acc change")):
        cells = [rms.get(f"{scale}, {tool}") for tool in tools]
        others = [c for c in cells[1:] if c is not None]
        print(f"| {what} ({unit}) | " + " | ".join("-" if c is None else f"{c:.3g}" for c in cells)
              + f" | {cells[0] / min(others):.2f} |")
    print("\n| time per warm-up | seconds |\n|---|---|")
    for k, v in times.items():
        total = np.sum(v) / a.seeds
        print(f"| {k} | {total:.3g} |")


if __name__ == "__main__":
    main()
