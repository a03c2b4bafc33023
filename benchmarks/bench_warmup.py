"""Benchmark: a still warm-up (15 -> 60 degC, a cubic bias on every axis, white noise and a wandering bias) as
a PX4 ULog, calibrated by simucal (`import ulog`, `calibrate --thermal --px4 --ardupilot`) and by the two
autopilots' methods on the same samples, each curve's error against the planted truth over seeds.

With --imus 2 the board has two IMUs (instance 1 a degree warmer, each its own curves and device ids), as
PX4 and ArduPilot log them: simucal imports both (`--instance all`) and calibrates them in one command
(`calibrate imus/instance0 imus/instance1 --thermal --px4 F --ardupilot F`), and every IMU's curves are
held against its own truth: simucal's calibration file, the slot of its PX4 file (TC_A<k>/TC_G<k>, with
the device ids) and of its ArduPilot file (INS_TCAL<k+1>), and the tools' slots on the same log.

The autopilots' tools are not vendored here (their code is theirs); their methods are run as their
documentation and source describe them (docs/temperature.md), and where a copy of a tool is given
(--px4-tool FILE: PX4's Tools/process_sensor_caldata.py; --ardupilot-tool FILE: ArduPilot's
Tools/scripts/tempcal_IMU.py) the tool itself runs too, on the same samples (the ULog, with a still
barometer, which PX4's script needs; for ArduPilot the same samples as a DataFlash log of IMU
messages), and its parameter file is read back: PX4's Tools/process_sensor_caldata.py takes
a 31-sample median filter, means over 2,000 equal temperature bins and a cubic in (T - T_ref), T_ref the
middle of the range, the accelerometer less its median reading; ArduPilot's Tools/scripts/tempcal_IMU.py a
2 s moving mean and a cubic in (T - 35), its constant dropped. Errors: the rms over the temperature range
of each axis's curve less the truth, the gyro's whole bias (where a curve has a constant: simucal, PX4)
and every sensor's change from 35 degC (all: ArduPilot keeps no constant, the accelerometer's is gravity's).

    python3 benchmarks/bench_warmup.py [--seeds 5] [--minutes 30] [--imus 1] [--px4-tool FILE] [--ardupilot-tool FILE]
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
# per IMU: a cubic bias in (T - T_MID) per axis, m/s^2 and rad/s (tests/test_instances.py's two boards)
ACC = [np.array([[0.02, 4e-4, -2e-5, 1e-6], [-0.01, -3e-4, 1e-5, 2e-6], [0.015, 2e-4, 3e-5, -1.5e-6]]),
       np.array([[-0.03, -2e-4, 1e-5, -1e-6], [0.02, 5e-4, -2e-5, 0.0], [-0.01, -4e-4, 0.0, 1e-6]])]
GYRO = [np.array([[2e-3, 3e-5, -6e-7, 2e-8], [-1e-3, -2e-5, 4e-7, 1.5e-8], [5e-4, 1.5e-5, 3e-7, -2e-8]]),
        np.array([[-4e-3, -1e-5, 5e-7, -1e-8], [3e-3, 4e-5, -2e-7, 0.0], [-2e-3, -3e-5, 0.0, 2e-8]])]
DEVICE_IDS = [(1442826, 2490378), (1442834, 2490386)]  # (accelerometer, gyro) of each IMU
T_MID = 37.5
HZ = 100.0


def log(path: Path, seed: int, minutes: float, imus: int = 1) -> list[tuple[dict, dict]]:
    """The ULog of one warm-up, each sensor of each IMU at HZ with its own jittered stamps (tests/test_logs.py's
    board), and the same samples as a DataFlash log; [(accelerometer, gyro) topics] per IMU."""
    rng = np.random.default_rng(seed)

    def topic(truth, white, walk, device_id, warmer):
        t = np.arange(0, minutes * 60, 1 / HZ) + rng.uniform(0, 0.1 / HZ, int(round(minutes * 60 * HZ)))
        T = 15 + warmer + 45 * (1 - np.exp(-t / (minutes * 60 / 3.0)))
        xyz = ((T - T_MID)[:, None] ** np.arange(4)) @ truth.T + rng.normal(0, white, (len(t), 3)) \
            + np.cumsum(rng.normal(0, walk, (len(t), 3)), axis=0)
        return {"t_us": np.round(t * 1e6), "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "temperature": T,
                "device_id": device_id}
    gravity = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [-G, 0, 0, 0]])
    boards = [(topic(ACC[k] + gravity, 0.02, 2e-5, DEVICE_IDS[k][0], k),
               topic(GYRO[k], 2e-3, 2e-7, DEVICE_IDS[k][1], k))
              for k in range(imus)]
    gyro = boards[0][1]
    baro = {"t_us": gyro["t_us"][::4], "pressure": np.full(len(gyro["t_us"][::4]), 1013.25),
            "temperature": gyro["temperature"][::4], "device_id": 4653065}
    write_ulog(path, [a for a, _ in boards], [g for _, g in boards], baro=baro)
    # the same samples as ArduPilot logs them: one IMU message holds both sensors (at the gyro's stamps)
    write_dataflash(path.with_suffix(".bin"), [{"t_us": g["t_us"], "temperature": g["temperature"],
                                                "acc": np.c_[a["x"], a["y"], a["z"]],
                                                "gyro": np.c_[g["x"], g["y"], g["z"]]} for a, g in boards])
    return boards


def read_params(path: Path) -> dict:
    """{name: value} of a parameter file: QGC's .params (tab-separated, the name third), or NAME VALUE /
    NAME,VALUE (ArduPilot's)."""
    params = {}
    for line in path.read_text().splitlines():
        f = line.replace(",", " ").split()
        if len(f) >= 2 and not line.startswith("#"):
            name, value = (f[2], f[3]) if len(f) >= 5 else (f[0], f[1])
            params[name] = float(value)
    return params


def tool_params(cmd, cwd: Path, out: Path) -> dict:
    """Run an autopilot's own script and read the parameter file it writes."""
    subprocess.run(cmd, cwd=cwd, check=True, capture_output=True, env={**os.environ, "MPLBACKEND": "Agg"})
    return read_params(out)


def px4_file_curve(params, sensor, i, slot=0):
    """A TC_* curve of a PX4 .params (PX4's tool's or simucal's): (coefficients in T - T_ref, T_ref), in the
    log's units."""
    p = f"TC_{'G' if sensor == 'gyro' else 'A'}{slot}"
    return np.array([params[f"{p}_X{k}_{i}"] for k in range(4)]), params[f"{p}_TREF"]


def ardupilot_file_curve(params, sensor, i, slot=0):
    """An INS_TCAL<slot+1>_* curve of an ArduPilot .parm: (coefficients in T - 35, 35), its constant 0."""
    p = f"INS_TCAL{slot + 1}_{'GYR' if sensor == 'gyro' else 'ACC'}"
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


def simucal_run(tmp: Path, seed: int, imus: int):
    """simucal's import and one calibrate of every IMU: ([calibration per IMU], its PX4 file, its ArduPilot file)."""
    sets = tmp / f"s{seed}"
    dirs = [sets / f"instance{k}" for k in range(imus)] if imus > 1 else [sets]
    out = tmp / f"c{seed}.json"
    for cmd in (["import", "ulog", tmp / f"w{seed}.ulg", "-o", sets, "--latitude-deg", "47"]
                + ["--instance", "all"] * (imus > 1),
                ["calibrate", *dirs, "--thermal", "-o", out, "--px4", tmp / f"s{seed}.params",
                 "--ardupilot", tmp / f"s{seed}.parm"]):
        subprocess.run([sys.executable, "-m", "simucal", *map(str, cmd)], check=True, capture_output=True)
    cals = [calibration.load(out.with_name(f"c{seed}_instance{k}.json") if imus > 1 else out) for k in range(imus)]
    return cals, read_params(tmp / f"s{seed}.params"), read_params(tmp / f"s{seed}.parm")


def tools_run(a, tmp: Path, seed: int, times: dict) -> dict:
    """Each autopilot's own script given a copy: {column: its parameters}."""
    own = {}
    if a.px4_tool:
        t0 = time.perf_counter()
        own["PX4's tool"] = tool_params([sys.executable, str(a.px4_tool.resolve()), f"w{seed}.ulg"], tmp,
                                        tmp / f"w{seed}.ulg.params")
        times["PX4's tool (process_sensor_caldata.py)"].append(time.perf_counter() - t0)
    if a.ardupilot_tool:
        t0 = time.perf_counter()
        own["ArduPilot's tool"] = tool_params(
            [sys.executable, str(a.ardupilot_tool.resolve()), "--no-graph", "--outfile", f"w{seed}.parm",
             f"w{seed}.bin"], tmp, tmp / f"w{seed}.parm")
        times["ArduPilot's tool (tempcal_IMU.py)"].append(time.perf_counter() - t0)
    return own


def imu_errors(k, board, cal, files: dict, errors: dict, times: dict):
    """IMU k's curves less its truth, into errors[(k, what, column)]; files {column: (params, reader)}."""
    for sensor, data, truth, per in (("gyro", board[1], GYRO[k], np.radians(1 / 3600)), ("acc", board[0], ACC[k], G)):
        T = data["temperature"]
        grid = np.linspace(T.min(), T.max(), 200)
        at35 = np.searchsorted(grid, 35.0)
        th = getattr(cal, sensor).thermal
        for i, axis in enumerate("xyz"):
            want = curve(truth[i], T_MID, grid)
            t0 = time.perf_counter()
            c_px4, ref_px4 = px4(T, data[axis], sensor == "acc")
            times["PX4's method"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            c_ap, ref_ap = ardupilot(T, data[axis], HZ)
            times["ArduPilot's method"].append(time.perf_counter() - t0)
            curves = {"simucal": curve(np.array(th["parameters"][f"b_{axis}"]["coefficients"]) * per,
                                       th["t_ref_c"], grid),
                      "PX4's method": curve(c_px4, ref_px4, grid), "ArduPilot's method": curve(c_ap, ref_ap, grid),
                      **{column: file_curve(read, params, sensor, i, k, grid)
                         for column, (params, read) in files.items()}}
            for column, v in curves.items():
                if sensor == "gyro" and "ArduPilot" not in column and "INS_TCAL" not in column:
                    errors.setdefault((k, "gyro whole", column), []).append(v - want)
                errors.setdefault((k, f"{sensor} change", column), []).append(v - want - (v[at35] - want[at35]))


def file_curve(read, params, sensor, i, k, grid):
    """IMU k's curve of axis i in a parameter file, on the grid."""
    c, t_ref = read(params, sensor, i, k)
    return curve(c, t_ref, grid)


def device_ids(k, files: dict) -> str:
    """The TC_A<k>_ID / TC_G<k>_ID of every PX4 file against the log's: 'column: acc/gyro (ok|WRONG)'."""
    cells = []
    for column, (params, read) in files.items():
        if read is px4_file_curve:
            got = (int(params[f"TC_A{k}_ID"]), int(params[f"TC_G{k}_ID"]))
            cells.append(f"{column} {got[0]}/{got[1]} ({'ok' if got == DEVICE_IDS[k] else 'WRONG'})")
    return "; ".join(cells)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--minutes", type=float, default=30.0, help="the warm-up's length (default 30)")
    ap.add_argument("--imus", type=int, default=1, choices=(1, 2), help="IMUs on the board (default 1)")
    ap.add_argument("--px4-tool", type=Path, help="a copy of PX4's Tools/process_sensor_caldata.py: run it too")
    ap.add_argument("--ardupilot-tool", type=Path,
                    help="a copy of ArduPilot's Tools/scripts/tempcal_IMU.py: run it too")
    a = ap.parse_args()
    errors: dict = {}
    times = {"simucal (import ulog + calibrate --thermal, both files)": [], "PX4's method": [],
             "ArduPilot's method": [], **({"PX4's tool (process_sensor_caldata.py)": []} if a.px4_tool else {}),
             **({"ArduPilot's tool (tempcal_IMU.py)": []} if a.ardupilot_tool else {})}
    ids = set()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for seed in range(a.seeds):
            boards = log(tmp / f"w{seed}.ulg", seed, a.minutes, a.imus)
            t0 = time.perf_counter()
            cals, px4_file, ardupilot_file = simucal_run(tmp, seed, a.imus)
            times["simucal (import ulog + calibrate --thermal, both files)"].append(time.perf_counter() - t0)
            files = {"simucal's TC_ file": (px4_file, px4_file_curve),
                     "simucal's INS_TCAL file": (ardupilot_file, ardupilot_file_curve)}
            for column, params in tools_run(a, tmp, seed, times).items():
                files[column] = (params, px4_file_curve if "PX4" in column else ardupilot_file_curve)
            for k in range(a.imus):
                imu_errors(k, boards[k], cals[k], files, errors, times)
                ids.add(f"IMU {k}: {device_ids(k, files)}")
    print(f"{a.seeds} warm-ups of {a.minutes:g} min at {HZ:g} Hz, {a.imus} IMU{'s' * (a.imus > 1)}, 15 -> 60 degC, a "
          "cubic bias on every axis, white noise and a random walk of the bias\n")
    table(errors, a.imus)
    print("\ndevice ids of the PX4 files (accelerometer/gyro) against the log's:\n" + "\n".join(sorted(ids)))
    print(f"\n| time per warm-up ({a.imus} IMU{'s' * (a.imus > 1)}) | seconds |\n|---|---|")
    for k, v in times.items():
        print(f"| {k} | {np.sum(v) / a.seeds:.3g} |")


def table(errors: dict, imus: int):
    """The rms of each curve's error, a row per IMU and curve, a column per source."""
    columns = list(dict.fromkeys(c for _, _, c in errors))
    rms = {key: float(np.sqrt(np.mean(np.square(v)))) for key, v in errors.items()}
    print(header(["IMU", "curve against the truth (rms over its range, every axis and seed)", *columns,
                  "simucal / best other"]))
    for k in range(imus):
        for what, name, unit in (("gyro whole", "gyro, whole bias", "rad/s"),
                                 ("gyro change", "gyro, change from 35 degC", "rad/s"),
                                 ("acc change", "acc, change from 35 degC", "m/s^2")):
            cells = [rms.get((k, what, c)) for c in columns]
            others = [c for c, col in zip(cells, columns) if c is not None and not col.startswith("simucal")]
            print(f"| {k} | {name} ({unit}) | " + " | ".join("-" if c is None else f"{c:.3g}" for c in cells)
                  + f" | {rms[(k, what, 'simucal')] / min(others):.2f} |")


if __name__ == "__main__":
    main()
