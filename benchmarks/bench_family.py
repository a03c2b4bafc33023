"""Benchmark: the model test as one family (fit/family.py): false alarms on clean sets and the
power against one library effect at 5, 10 and 20 of its own stds, for every kind of data that ranks
candidates (a turntable set, a hand-placed stream's poses and moves, a rotation sequence, a turntable unit at
three temperature plateaus calibrated --thermal), before
(the omnibus alone at ALPHA, the rule before the family) and after (the family at ALPHA), and how often
`--add auto` adds the planted effect at 10 std.

Each effect's std is the calibration's own std of it on a pilot set (the effect added by hand), so
"k std" is k times what the data can resolve. Each kind's effect is one its data tell from every other
candidate (a hand-placed session's poses cannot tell acc.quadratic.z from acc.scale_asymmetry.z, and
diagnose says so: twins are a matter of the plan, not of this power). Found: the sensor's model fails and its advice
names the planted effect. Sampling error of a rate p over n seeds: sqrt(p (1 - p) / n); at ALPHA = 1e-3 over
200 seeds a right model fails in 0.2 sets on average (none in 82 % of such runs).

    python3 benchmarks/bench_family.py [--seeds 200] [--kinds turntable,poses,moves,sequence,thermal] [--auto-seeds 40]
"""
import argparse
import time
import warnings

import numpy as np

import simucal
from simucal.fit.results import ALPHA
from simucal.report.markdown import header

# kind: (simulate's keywords, calibrate's keywords, the effect planted, its sensor); a clean set's false alarm
# counts the sensors of the kind's test (a turntable's two; a sequence's one filter fails both at once)
KINDS = {
    "turntable": ({"plan": "fibonacci48"}, {}, "acc.cross_coupling.xy", "acc"),
    "poses": ({"scenario": "handheld"}, {}, "acc.cross_coupling.yz", "acc"),  # a hand-placed stream's poses
    "moves": ({"scenario": "handheld"}, {}, "gyro.g_sensitivity.xz", "gyro"),  # and its moves
    "sequence": ({"sequence": "psins19"}, {"method": "systematic"}, "acc.cross_coupling.xy", "acc"),
    # three wandering plateaus (0, 25, 50 degC) with a temperature term planted, calibrated --thermal
    # (not acc.quadratic.z: its twin acc.scale_asymmetry.z correlates ~0.98 with it over these plateaus, so at 10 std
    # the twin scored higher in 1 seed of 6, and the targeted record names the twin: a plan limit, not power)
    "thermal": ({"plan": "fibonacci24", "t_ref_c": 25.0, "temperature_wander_c": 0.3}, {},
                "acc.cross_coupling.xy", "acc"),
}
PILOT = {"acc.cross_coupling.xy": 1e-4, "acc.cross_coupling.yz": 1e-4, "gyro.g_sensitivity.xz": 1e-3,
         "acc.quadratic.z": 5e-5}
STRENGTHS = (5, 10, 20)
PLATEAUS_C = (0.0, 25.0, 50.0)


def data(kind, seed, effects=None):
    """The set of one seed (a thermal kind's: its three plateaus, seeds 3 seed + 0..2)."""
    sim = KINDS[kind][0]
    if kind != "thermal":
        return simucal.simulate(seed=seed, effects=effects, **sim)
    effects = {**(effects or {}), "acc.bias_temperature.x": 2e-6}
    return [simucal.simulate(seed=3 * seed + i, temperature_c=T, effects=effects, **sim)
            for i, T in enumerate(PLATEAUS_C)]


def effect_std(kind) -> float:
    """The calibration's std of the kind's effect on a pilot set with it planted and added by hand."""
    _, cal_kw, eid, sensor = KINDS[kind]
    cal = simucal.calibrate(data(kind, 10_000, {eid: PILOT[eid]}), add=[eid], **cal_kw)
    return float(getattr(cal, sensor).effects[eid].std)


def outcome(cal, sensor, eid=None) -> tuple[bool, bool, bool]:
    """(the family fails, the omnibus alone fails at ALPHA, the advice names eid) for one sensor."""
    b = getattr(cal, sensor)
    omnibus = b.details.get("omnibus_p_value", b.p_value)
    return (b.verdict == "fails", omnibus is not None and omnibus < ALPHA,
            eid is not None and b.verdict == "fails" and b.details.get("advice") == eid)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--auto-seeds", type=int, default=40, help="seeds of --add auto at 10 std (default 40)")
    a = ap.parse_args()
    warnings.simplefilter("ignore")  # the sets' own notes (nominal scale factors, ...) are not the point here
    rows = []
    for kind in a.kinds.split(","):
        _, cal_kw, eid, sensor = KINDS[kind]
        t0 = time.perf_counter()
        std = effect_std(kind)
        tested = {"poses": ("acc",), "moves": ("gyro",)}.get(kind, ("acc", "gyro"))
        clean = np.array([[outcome(simucal.calibrate(data(kind, s), **cal_kw), x)[:2]
                           for x in tested] for s in range(a.seeds)])  # (seeds, sensor, [family, omnibus])
        rows.append((kind, f"clean ({' or '.join(tested)} fails)", "-", clean[:, :, 1].any(1).mean(),
                     clean[:, :, 0].any(1).mean()))
        for k in STRENGTHS:
            hit = np.array([outcome(simucal.calibrate(data(kind, s, {eid: k * std}), **cal_kw), sensor, eid)
                            for s in range(a.seeds)])
            rows.append((kind, f"{eid} at {k} std (found)", f"{k * std:.3g}", hit[:, 1].mean(), hit[:, 2].mean()))
        added = [eid in getattr(simucal.calibrate(data(kind, s, {eid: 10 * std}), add="auto", **cal_kw),
                                sensor).effects for s in range(a.auto_seeds)]
        rows.append((kind, f"`--add auto` adds {eid} at 10 std", f"{10 * std:.3g}", None, float(np.mean(added))))
        print(f"{kind}: {time.perf_counter() - t0:.0f} s; " + "; ".join(
            f"{what}: {before} -> {after}" for k, what, _, before, after in rows if k == kind), flush=True)
    print(f"\n{a.seeds} seeds per row ({a.auto_seeds} for --add auto); ALPHA = {ALPHA:g}; before: the omnibus alone "
          "at ALPHA fails the model (its advice was asked only then); after: the family fails it and its advice "
          "names the effect\n")
    print(header(["data", "sets", "effect size", "before", "after"]))
    for kind, what, size, before, after in rows:
        print(f"| {kind} | {what} | {size} | {'-' if before is None else f'{before:.3f}'} | {after:.3f} |")


if __name__ == "__main__":
    main()
