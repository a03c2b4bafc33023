"""Benchmark: `calibrate --thermal` on plateaus that wander, over seeds.

Per seed: three plateaus (-10, 25, 60 degC, fibonacci48 at 20 Hz, each segment's temperature within
+-0.3 degC of its plateau) of one unit whose biases are quadratic and scale factors linear in
temperature (T_ref 25 degC), calibrated with --thermal, and validated at 40 degC (wandering too) on
the Table 1 plan. Prints per seed: the joint test's p and the lowest plateau's p under it per sensor,
the largest |c| / std of a coefficient the truth lacks, the largest |c - truth| / std of a planted
one, and validate's first check (the norm) over its floor per sensor.

    python3 benchmarks/bench_thermal.py FIRST_SEED END_SEED

With --ramp, per seed instead: one ramp 5 to 45 degC of the same unit on fibonacci48 in its own order
and with its positions shuffled, each calibrated with --thermal and validated at 30 degC on the Table 1
plan: the joint tests' p, validate's norm check over its floor, the ramp's warnings, and the rows the
gyro was fitted with and their temperature range. --wander W: every segment's temperature (the ramp's
and the check's) moved by a uniform draw within +-W degC (default 0).

    python3 benchmarks/bench_thermal.py FIRST_SEED END_SEED --ramp [--wander 0.3]
"""
import json
import subprocess
import sys
import tempfile
from pathlib import Path

SIMUCAL = str(Path(sys.executable).with_name("simucal"))
PLANTED = {"acc.bias_temperature.x": 2e-6, "acc.bias_temperature2.x": 5e-8, "acc.bias_temperature2.y": -3e-8,
           "acc.bias_temperature2.z": 2e-8, "acc.scale_temperature.z": 3e-6, "acc.scale_temperature.x": -2e-6,
           "gyro.bias_temperature.z": 2e-3, "gyro.bias_temperature2.z": 2e-5, "gyro.bias_temperature2.x": -1e-5,
           "gyro.scale_temperature.x": 2e-6, "gyro.scale_temperature.z": -3e-6}
EFFECTS = [a for k, v in PLANTED.items() for a in ("--effect", f"{k}={v}")]


def _truth():
    """{(sensor, parameter, degree): coefficient} of the planted effects."""
    out = {}
    for k, v in PLANTED.items():
        sensor, family, axis = k.split(".")
        out[(sensor, ("b_" if "bias" in family else "dK_") + axis, 2 if family.endswith("2") else 1)] = v
    return out


def run(*args):
    r = subprocess.run([SIMUCAL, *map(str, args)], capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(r.stdout + r.stderr)


def one_seed(root: Path, seed: int, truth: dict) -> str:
    sim = ("--rate-hz", 20, "--temperature-wander-c", 0.3, "--t-ref-c", 25, *EFFECTS)
    sets = []
    for k, T in enumerate((-10, 25, 60)):
        run("simulate", "-o", root / f"p{T}", "--plan", "fibonacci48", "--seed", 1000 * seed + k, "--temperature-c", T,
            *sim)
        sets.append(root / f"p{T}")
    run("simulate", "-o", root / "o40", "--plan", "table1", "--seed", 1000 * seed + 9, "--temperature-c", 40, *sim)
    run("calibrate", *sets, "--thermal", "--t-ref-c", 25, "-o", root / "cal.json")
    run("validate", root / "cal.json", root / "o40", "-o", root / "v.json")
    cal, v = json.loads((root / "cal.json").read_text()), json.loads((root / "v.json").read_text())
    lacking, planted = [0.0], []
    for s in ("acc", "gyro"):
        for name, f in cal[s]["thermal"]["parameters"].items():
            for k in (1, 2):
                c, e = (f["coefficients"][k], f["std"][k]) if k <= f["degree"] else (0.0, None)
                t = truth.get((s, name, k))
                if t is None and e is not None:
                    lacking.append(abs(c) / e)
                elif t is not None:
                    planted.append(abs(c - t) / e if e else float("inf"))
    floor = [v["checks"][s][0]["after_rms"] / v["checks"][s][0]["floor_rms"] for s in ("acc", "gyro")]
    cells = [seed] + [f"{x:.2g}" for s in ("acc", "gyro") for x in (cal[s]["p_value"],
                                                                     min(g["p_value"] for g in cal[s]["groups"]))]
    return "| " + " | ".join(map(str, cells + [f"{max(lacking):.2f}", f"{max(planted):.2f}",
                                                f"{floor[0]:.2f}", f"{floor[1]:.2f}"])) + " |"


def ramp_seed(root: Path, seed: int, wander: float) -> str:
    """--ramp (module doc)."""
    import numpy as np

    from simucal.turntable.plans import fibonacci
    positions = list(fibonacci(48))
    (root / "shuffled.csv").write_text("outer_deg,middle_deg,inner_deg\n" + "".join(
        ",".join(map(str, positions[i])) + "\n" for i in np.random.default_rng(seed).permutation(len(positions))))
    sim = ("--rate-hz", 20, "--t-ref-c", 25, "--temperature-wander-c", wander, *EFFECTS)
    run("simulate", "-o", root / "c30", "--plan", "table1", "--seed", 1000 * seed + 6, "--temperature-c", 30, *sim)
    out = []
    for name, plan in (("in order", "fibonacci48"), ("shuffled", root / "shuffled.csv")):
        ramp, r, v = root / f"ramp {name}", root / f"r {name}.json", root / f"v {name}.json"
        run("simulate", "-o", ramp, "--plan", plan, "--seed", 1000 * seed + 5, "--temperature-c", "5:45", *sim)
        run("calibrate", ramp, "--thermal", "-o", r)
        run("validate", r, root / "c30", "-o", v)
        cal, v = json.loads(r.read_text()), json.loads(v.read_text())
        floor = {s: round(v["checks"][s][0]["after_rms"] / v["checks"][s][0]["floor_rms"], 2) for s in ("acc", "gyro")}
        p = {s: float(f"{cal[s]['p_value']:.2g}") for s in ("acc", "gyro")}
        warned = [w.split(" input")[0] for w in cal.get("warnings", []) if "follows the ramp's temperature" in w]
        g = cal["gyro"]["thermal"]
        out.append(f"{name}: p {p}, at 30 degC x floor {floor}, warned {warned}, gyro rows {g['rows']} at "
                   f"{g['temperature_range_c'][0]:.3g}..{g['temperature_range_c'][1]:.3g} degC")
    return f"| ramp seed {seed}: " + "; ".join(out) + " |"


def main():
    first, end = (int(a) for a in sys.argv[1:3])
    wander = float(sys.argv[sys.argv.index("--wander") + 1]) if "--wander" in sys.argv else 0.0
    truth = _truth()
    if "--ramp" not in sys.argv:
        print("| seed | acc p | acc lowest plateau p | gyro p | gyro lowest plateau p | max std of a coefficient the "
              "truth lacks | max std off of a planted one | acc at 40 degC x floor | gyro at 40 degC x floor |\n"
              + "|---" * 9 + "|")
    for seed in range(first, end):
        with tempfile.TemporaryDirectory() as tmp:
            print(ramp_seed(Path(tmp), seed, wander) if "--ramp" in sys.argv else one_seed(Path(tmp), seed, truth),
                  flush=True)


if __name__ == "__main__":
    main()
