"""`simucal bench`: the speed figures (docs/benchmarks.md), measured in one run on this machine.

- one exact accelerometer fit, N = 12 (Table 1 plan): the compiled whole fit called once
  (min of repeats), the same fit by fit_exact with the compiled call, and the numpy path;
- the cost of fit_exact against N (12 ... 10^5 rows), which must stay linear;
- Monte Carlo of the paper scenario (simulate + exact fits + unification), trials per second,
  compiled and numpy (SIMUCAL_NO_COMPILE=1 in a subprocess); `simucal montecarlo --trials
  200000` as a whole process, with the range of std/CRLB over its 18 parameters;
- whole processes: `simucal calibrate` on a raw turntable set (86 segments at 100 Hz), on the
  imu_tk Xsens stream, `simucal diagnose` of the Xsens stream (and with --html), `simucal validate` of the raw
  set, `simucal noise` on 2 h at 100 Hz (720,000 rows x 6), `simucal calibrate --thermal` on 3
  plateaus, `simucal montecarlo --effect acc.quadratic.z=1e-4` (trials per second in process and
  of whole processes of 20,000 and 200,000 trials, with std/CRLB; the cost of a process of 100;
  with a user's model file in process), `simucal field-drift` (3 x 300 s at 100 Hz), `simucal
  --help`. Whole processes run the console script beside this interpreter, with bytecode cached
  (bench.process), but for `--help` and the 300,100-row calibrate also measured without that cache
  (*_as_before_s: as runs before 3dc5994 measured them);
- compiling one model's C.
Run by `simucal bench [-o OUT.json] [--before OLD.json]` or `python3 benchmarks/bench_speed.py`;
--before prints a previous run's figures beside these (benchmarks/bench_*.json hold earlier
runs). The imu_tk Xsens figures need ../shared/data beside the repository. Benchmarks print;
tests never time.
"""
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from simucal import io, progress
from simucal.io import outputs
from simucal.io.cache import compile_c, own_folder
from simucal.fit.catalog import load
from simucal.fit.models import generated_dir
from simucal.fit.norm_fit import Observations, fit_exact
from simucal.turntable import montecarlo
from simucal.turntable.observations import segment_observations
from simucal.turntable.simulate import Scenario, write

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "imu_tk-xsens"  # beside a source checkout
# each figure by name (its unit in the name: _s, _per_s, rows), or fit_exact's seconds by rows (_scaling)
Figures = dict[str, float | dict[int, float]]


def best(f, repeats=7, inner=20):
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(inner):
            f()
        out.append((time.perf_counter() - t) / inner)
    return min(out)


# this interpreter's console script, whatever PATH holds first (a version manager's shim is not simucal's time);
# where there is none beside it (simucal not installed as a script), the package run by this interpreter
SIMUCAL = [str(Path(sys.executable).with_name("simucal"))] if Path(sys.executable).with_name("simucal").is_file() \
    else [sys.executable, "-m", "simucal"]

# the sizes of the figures; "quick" runs every step at a size of seconds (CI's run of the README's commands):
# its figures are no measure of speed
SIZES: dict[str, dict[str, Any]] = {
    "full": dict(repeats=3, mc_trials=100000, mc_numpy_trials=20000, cli_trials=200000, effect_trials=(20000, 200000),
                 rate_hz=(100.0, 452.0), still_s=7200.0, thermal_rate_hz=20.0, scaling=(12, 100, 1000, 10000, 100000),
                 diagnose=True),
    "quick": dict(repeats=0, mc_trials=2500, mc_numpy_trials=500, cli_trials=2500, effect_trials=(500, 2500),
                  rate_hz=(2.0, 4.0), still_s=120.0, thermal_rate_hz=1.0, scaling=(12, 100), diagnose=False)}


def _env(cached=True):
    env = dict(os.environ)
    if cached and env.pop("PYTHONDONTWRITEBYTECODE", None):
        env.setdefault("PYTHONPYCACHEPREFIX", str(own_folder("pycache")))  # the user's alone: bytecode is code
    return env


REPEATS = [3]  # whole processes timed per figure (run's size sets it)


def process(args, repeats=None, cached=True):
    """The best wall time of a whole process, its modules' bytecode cached as an installed package
    has it: where PYTHONDONTWRITEBYTECODE is set, in a prefix in the cache (else every process
    compiles every module it imports again: the *_as_before_s figures measure it). cached=False:
    the environment as it is."""
    env = _env(cached)
    out = []
    for _ in range((REPEATS[0] if repeats is None else min(repeats, REPEATS[0])) + 1):  # the first writes the bytecode
        t = time.perf_counter()
        subprocess.run(args, check=True, capture_output=True, env=env)
        out.append(time.perf_counter() - t)
    return min(out[1:] or out)


def process_times(args, repeats):
    """Each run's wall time and its CPU time (user + system, the process and its children), after a
    first run that writes the bytecode: the spread of the walls shows threads spinning against
    each other (0.66-7.7 s), the CPU time what the process costs on a loaded machine."""
    import resource
    walls, cpus = [], []
    for k in range(repeats + 1):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        subprocess.run(args, check=True, capture_output=True, env=_env())
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if k:
            walls.append(time.perf_counter() - t)
            cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return walls, cpus


def _new_commands(tmp, fig, n):
    """The commands beside validate: noise on 2 h at 100 Hz, a thermal calibration of 3 plateaus,
    and the Monte Carlo with an effect as a whole process."""
    from simucal.handheld.simulate import write_still
    progress.status("bench: simucal noise (2 h at 100 Hz), calibrate --thermal (3 plateaus), montecarlo --effect")
    write_still(tmp / "still", seconds=n["still_s"], dt=0.01)
    fig["cli_noise_2h_100hz_s"] = process([*SIMUCAL, "noise", str(tmp / "still"), "-o", str(tmp / "n.json")])
    plateaus = write_plateaus(tmp, n["thermal_rate_hz"])
    fig["rows_thermal_plateau"] = len(io.read_set(plateaus[0]).samples["t_s"])
    walls, cpus = process_times([*SIMUCAL, "calibrate", *plateaus, "--thermal", "-o", str(tmp / "th.json")],
                                max(1, REPEATS[0] + 2))
    fig["cli_calibrate_thermal_3_plateaus_s"], fig["cli_calibrate_thermal_3_plateaus_worst_s"] = min(walls), max(walls)
    fig["cli_calibrate_thermal_3_plateaus_cpu_s"] = min(cpus)
    _montecarlo_effect(tmp, fig, n)


def write_plateaus(folder: Path, rate_hz: float) -> list[str]:
    """Three plateaus (-10, 25, 60 degC, each wandering +-0.3 degC; biases quadratic and
    scale factors linear in temperature) on the fibonacci48 plan at rate_hz: the sets' folders."""
    from simucal.turntable.simulate import plant
    plateaus = []
    for T, seed in ((-10.0, 1), (25.0, 2), (60.0, 3)):
        sc = Scenario(plan="fibonacci48", temp_c=(T, T), t_ref_c=25.0, rate_hz=rate_hz, temp_wander_c=0.3)
        plant(sc, ["acc.bias_temperature.x=2e-6", "acc.bias_temperature2.x=5e-8", "acc.scale_temperature.z=3e-6",
                   "gyro.bias_temperature.z=2e-3", "gyro.bias_temperature2.z=2e-5", "gyro.scale_temperature.x=2e-6"])
        write(folder / f"p{T:g}", sc, seed)
        plateaus.append(str(folder / f"p{T:g}"))
    return plateaus


def _montecarlo_effect(tmp, fig, n):
    """The Monte Carlo with acc.quadratic.z=1e-4: in process, and as whole processes of 100 trials
    (what the process costs before its trials: start-up, the reference fit, the check of the
    revolution's samples), 20,000 (the documented figure) and 200,000 (std/CRLB over them); with a
    user's model file (a cubic term) in process."""
    from simucal.turntable.simulate import plant
    sc = Scenario()
    plant(sc, ["acc.quadratic.z=1e-4"])
    montecarlo.run(sc, 2500, 0)  # the augmented model derived into the cache, its library loaded
    fig["montecarlo_effect_trials_per_s"] = montecarlo.run(sc, n["mc_trials"], 1)["trials_per_s"]
    cmd = [*SIMUCAL, "montecarlo", "--effect", "acc.quadratic.z=1e-4", "-o", str(tmp / "mce.json"), "--trials"]
    fig["cli_montecarlo_effect_100_trials_s"] = process(cmd + ["100"])
    few, many = n["effect_trials"]
    fig["cli_montecarlo_effect_trials_per_s"] = few / process(cmd + [str(few)])
    fig["cli_montecarlo_effect_200k_trials_per_s"] = many / process(cmd + [str(many)], repeats=1)
    ratios = [v["std_over_crlb"] for v in json.loads((tmp / "mce.json").read_text())["parameters"].values()]
    fig["montecarlo_effect_200k_std_over_crlb_min"], fig["montecarlo_effect_200k_std_over_crlb_max"] = \
        min(ratios), max(ratios)
    (tmp / "cubic.py").write_text(CUBIC_MODEL_FILE)
    sc = Scenario()
    plant(sc, effect_file=str(tmp / "cubic.py"), sets=["K3_x=1e-3"])
    montecarlo.run(sc, 2500, 0)
    fig["montecarlo_model_file_trials_per_s"] = montecarlo.run(sc, n["mc_trials"], 1)["trials_per_s"]


CUBIC_MODEL_FILE = """from simucal.derive.frames import f_b
from simucal.derive.models import Term
from simucal.derive.models.baseline import ACC_BASELINE
MODELS = [ACC_BASELINE.with_terms("acc_cubic_bench", [Term("K3_x", "x", f_b[0] ** 3, "g/g^3", "x cubic")])]
"""  # a user's model file: the Monte Carlo's truth and fitted model


def _cell(k, v) -> str:
    if v is None:
        return "-"
    return f"{v * 1e3:.3g} ms" if k.endswith("_s") and not k.endswith("per_s") else f"{v:.4g}"


def _table(fig, before, echo):
    """The figures, a previous run's beside them where given."""
    old = {}
    if before:
        old = json.loads(Path(before).read_text())
        echo(f"| figure | before ({Path(before).name}) | now |\n|---|---|---|")
    else:
        echo("| figure | value |\n|---|---|")
    for k, v in fig.items():
        if isinstance(v, dict):
            for n, s in v.items():
                was = old.get(k, {}).get(str(n))
                now = f"{s * 1e3:.3g} ms ({s / n * 1e6:.3g} us per row)"
                echo(f"| {k}, N = {n} | {_cell(k, was)} | {now} |" if before else f"| {k}, N = {n} | {now} |")
        else:
            echo(f"| {k} | {_cell(k, old.get(k))} | {_cell(k, v)} |" if before else f"| {k} | {_cell(k, v)} |")


def _scaling(c, sizes) -> dict[int, float]:
    """fit_exact's time against N = 12 ... 100,000 rows (it must stay linear)."""
    progress.status("bench: fit_exact against N = 12 ... 100,000 rows")
    scaling = {}
    rng = np.random.default_rng(0)
    for N in sizes:
        u = rng.normal(size=(N, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        p = np.array([2e-3, 8e-3, 6e-3, 1e-4, 1e-4, 1e-4, 8e-4, -1e-3, -3.2e-3])
        o = Observations(c.output(u, p) + rng.normal(0, 1e-5, (N, 3)), np.ones(N), np.full((N, 3), 1e-5))
        scaling[N] = best(lambda: fit_exact(c, o), repeats=3, inner=1)
    return scaling


def _fits_and_montecarlo(tmp, fig, n):
    """One exact fit (compiled, fit_exact, numpy), fit_exact against N, the Monte Carlo in process
    (compiled and numpy) and as a whole process."""
    progress.status("bench: one exact fit, N = 12 (compiled and numpy)")
    write(tmp / "t1", Scenario(unify_positions=False), 3)
    obs, _ = segment_observations(io.read_set(tmp / "t1"), "acc")
    c, py = load("acc_baseline"), load("acc_baseline", compiled=False)
    rows = len(obs.N)
    args = (obs.N[None], obs.rho[None], np.broadcast_to(obs.sigma, (rows, 3))[None],
            np.zeros((1, rows, len(c.aux))), np.zeros((1, 9)))
    if c.fit_compiled(*args) is not None:
        fig["fit_exact_acc_n12_compiled_call_s"] = best(lambda: c.fit_compiled(*args))
        fig["fit_exact_acc_n12_s"] = best(lambda: fit_exact(c, obs))
    fig["fit_exact_acc_n12_numpy_s"] = best(lambda: fit_exact(py, obs), inner=5)
    fig["fit_exact_scaling_s"] = _scaling(c, n["scaling"])
    progress.status(f"bench: the Monte Carlo, {n['mc_trials']} trials compiled, {n['mc_numpy_trials']} in numpy")
    montecarlo.run(Scenario(), 2000, 0)  # warm: compiled libraries loaded
    fig["montecarlo_trials_per_s"] = montecarlo.run(Scenario(), n["mc_trials"], 1)["trials_per_s"]
    code = (f"from {montecarlo.__name__} import run; from {Scenario.__module__} import Scenario; "
            f"run(Scenario(), 2000, 0); print(run(Scenario(), {n['mc_numpy_trials']}, 1)['trials_per_s'])")
    env = {**os.environ, "SIMUCAL_NO_COMPILE": "1"}  # warm, then measure
    fig["montecarlo_trials_per_s_numpy"] = float(subprocess.run([sys.executable, "-c", code], env=env, check=True,
                                                                capture_output=True, text=True).stdout.split()[-1])
    progress.status(f"bench: simucal montecarlo --trials {n['cli_trials']}, whole processes")
    fig["cli_montecarlo_200k_trials_s"] = process([*SIMUCAL, "montecarlo", "--trials", str(n["cli_trials"]), "-o",
                                                  str(tmp / "mc.json")])
    ratios = [v["std_over_crlb"] for v in json.loads((tmp / "mc.json").read_text())["parameters"].values()]
    fig["montecarlo_200k_std_over_crlb_min"], fig["montecarlo_200k_std_over_crlb_max"] = min(ratios), max(ratios)


def _whole_commands(tmp, fig, n):
    """calibrate, diagnose, validate, field-drift and --help as whole processes."""
    progress.status("bench: simucal calibrate and field-drift as whole processes")
    write(tmp / "raw", Scenario(rate_hz=n["rate_hz"][0]), 1)
    fig["rows_raw_turntable"] = len(io.read_set(tmp / "raw").samples["t_s"])
    fig["cli_calibrate_raw_turntable_s"] = process([*SIMUCAL, "calibrate", str(tmp / "raw"), "-o", str(tmp / "c.json")])
    write(tmp / "raw300k", Scenario(rate_hz=n["rate_hz"][1]), 1)  # 300,000 rows
    fig["rows_raw_turntable_300k"] = len(io.read_set(tmp / "raw300k").samples["t_s"])
    fig["cli_calibrate_raw_turntable_300k_s"] = process([*SIMUCAL, "calibrate", str(tmp / "raw300k"), "-o",
                                                         str(tmp / "c3.json")])
    if DATA.is_dir():
        subprocess.run([*SIMUCAL, "import", "imu_tk", str(DATA / "xsens_acc.mat"), str(DATA / "xsens_gyro.mat"),
                        "-o", str(tmp / "xsens"), "--acc-counts-per-g", "4096", "--gyro-counts-per-dps",
                        str(6258 * np.pi / 180), "--latitude-deg", "45.4"], check=True, capture_output=True)
        fig["cli_calibrate_xsens_s"] = process([*SIMUCAL, "calibrate", str(tmp / "xsens"), "-o", str(tmp / "x.json")])
    if DATA.is_dir() and n["diagnose"]:  # seconds each: the one step a quick run leaves out
        fig["cli_diagnose_xsens_s"] = process([*SIMUCAL, "diagnose", str(tmp / "xsens"), "-o", str(tmp / "xd.json")])
        fig["cli_diagnose_xsens_html_s"] = process([*SIMUCAL, "diagnose", str(tmp / "xsens"), "-o",
                                                    str(tmp / "xd.json"), "--html", str(tmp / "xd.html")])
    fig["cli_validate_raw_turntable_s"] = process([*SIMUCAL, "validate", str(tmp / "c.json"), str(tmp / "raw"), "-o",
                                                   str(tmp / "v.json")])
    _new_commands(tmp, fig, n)
    subprocess.run([*SIMUCAL, "simulate", "-o", str(tmp / "field"), "--scenario", "field"], check=True,
                   capture_output=True)
    fig["cli_field_drift_s"] = process([*SIMUCAL, "field-drift", str(tmp / "field"), "-o", str(tmp / "d.json")])
    fig["cli_help_s"] = process([*SIMUCAL, "--help"])
    # as runs before 3dc5994 measured a process: this environment's bytecode setting (none cached here)
    fig["cli_help_as_before_s"] = process([*SIMUCAL, "--help"], cached=False)
    fig["cli_calibrate_raw_turntable_300k_as_before_s"] = process(
        [*SIMUCAL, "calibrate", str(tmp / "raw300k"), "-o", str(tmp / "c3.json")], cached=False)


def run(json_path=None, echo=print, before=None, size="full") -> Figures:
    """Every figure, printed as a table (and written as JSON to json_path); before: a previous run's
    JSON, printed beside; size: a key of SIZES ("quick": every step at a size of seconds)."""
    n = SIZES[size]
    fig: Figures = {}
    REPEATS[0] = n["repeats"]
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        _fits_and_montecarlo(tmp, fig, n)
        _whole_commands(tmp, fig, n)
        progress.status("bench: one model compiled afresh")
        src = (generated_dir() / "acc_baseline.c").read_text() + f"\n/* {time.time()} */\n"  # a fresh build
        t = time.perf_counter()
        compile_c("bench_acc_baseline", src)
        fig["derive_compile_one_model_s"] = time.perf_counter() - t
    if size != "full":
        echo(f"size {size}: every step run at a size of seconds; these figures measure nothing")
    _table(fig, before, echo)
    if json_path:
        outputs.write_text(json_path, json.dumps({k: ({str(n): s for n, s in v.items()} if isinstance(v, dict) else v)
                                               for k, v in fig.items()}, indent=1) + "\n")
    return fig
