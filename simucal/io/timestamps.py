"""A stream's time stamps: a logger's arrival times or the sensor's own clock.

Many loggers stamp each sample when it arrives, not when the sensor took it: the steps jitter
(a MEMS unit at 100 Hz read over USB: median step 10.24 ms, mean 10.00 ms, a 5 ms catch-up step
every ~20), while the sensor's clock ticks evenly. Integrating the gyro over the arrival steps
weighs each sample by a wrong dt. `--timestamps nominal` integrates on the sensor's clock: the
samples evenly spaced at the mean step, t_0 + i (t_last - t_0) / (n - 1).

The rule that proves a regular clock behind irregular stamps (auto): the arrival times stay
within CLOCK_BOUND_STEPS median steps of that even spacing over the whole stream. A sensor
clock read late by a bounded latency gives exactly this (each long step is paid back by a
catch-up); a dropped sample, a pause or a clock that changes its rate puts the stamps a whole
step or more off the line for good, and then the recorded stamps are kept.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

CHOICES = ("auto", "nominal", "recorded")
IRREGULAR = 0.05   # steps farther than this share of the median step from it: irregular, where ...
IRREGULAR_SHARE = 0.01  # ... at least this share of the steps are
CATCH_UP = 0.75    # a step shorter than this share of the median is a catch-up
CLOCK_BOUND_STEPS = 2.0  # arrival times within this many median steps of an even clock: a regular clock


def statistics(t) -> dict:
    """The stamps' steps: median, mean, std (ms), the catch-up steps (count, median ms), the longest
    step, the largest distance of any stamp from an even spacing at the mean step (in median steps),
    and whether the stamps are irregular and whether a regular clock is proved (module doc)."""
    t = np.asarray(t, float)
    dt = np.diff(t)
    med, mean = float(np.median(dt)), float((t[-1] - t[0]) / (len(t) - 1))
    catch = dt < CATCH_UP * med
    off = float(np.max(np.abs(t - (t[0] + mean * np.arange(len(t)))))) / med
    irregular = bool(np.mean(np.abs(dt - med) > IRREGULAR * med) >= IRREGULAR_SHARE)
    return {"median_step_ms": 1e3 * med, "mean_step_ms": 1e3 * mean, "std_step_ms": 1e3 * float(np.std(dt)),
            "catch_up_steps": int(catch.sum()),
            "catch_up_median_ms": 1e3 * float(np.median(dt[catch])) if catch.any() else None,
            "longest_step_ms": 1e3 * float(dt.max()), "off_even_clock_steps": off, "irregular": irregular,
            "regular_clock": bool(off <= CLOCK_BOUND_STEPS)}


def with_timestamps(ms, choice="auto"):
    """(the set with the time stamps to integrate on, the timestamps block of the calibration file).
    A stream only (a turntable's segments keep theirs); nominal: evenly spaced at the mean step;
    auto: nominal where the stamps are irregular and a regular clock is proved, else as recorded."""
    if choice not in CHOICES:
        raise ValueError(f"--timestamps {choice!r}: one of {', '.join(CHOICES)}")
    if ms.segments is not None or len(ms.samples["t_s"]) < 3:
        if choice == "nominal":
            from simucal.errors import CalibrationError
            raise CalibrationError(f"{ms.path / 'samples.csv'}: --timestamps nominal respaces a continuous stream's "
                                   "stamps; this set has segments.csv (leave the option out)")
        return ms, None
    st = statistics(ms.samples["t_s"])
    nominal = choice == "nominal" or (choice == "auto" and st["irregular"] and st["regular_clock"])
    st["used"] = "nominal" if nominal else "recorded"
    st["chosen_by"] = ("--timestamps " + choice) if choice != "auto" else (
        f"auto: the arrival times stay within {st['off_even_clock_steps']:.2g} median steps of an even clock (at most "
        f"{CLOCK_BOUND_STEPS:g}), so a regular clock took them" if nominal else
        "auto: the stamps are regular" if not st["irregular"] else
        f"auto: the stamps stray {st['off_even_clock_steps']:.3g} median steps from an even clock (more than "
        f"{CLOCK_BOUND_STEPS:g}: dropped samples, pauses or a changing rate), so they are kept")
    st["text"] = describe(st)
    if not nominal:
        return ms, st
    t = ms.samples["t_s"]
    even = t[0] + (t[-1] - t[0]) / (len(t) - 1) * np.arange(len(t))
    return replace(ms, samples={**ms.samples, "t_s": even}), st


def describe(st) -> str:
    """One line: the stamps' statistics and which were used, and why."""
    how = (f"irregular: median step {st['median_step_ms']:.4g} ms, mean {st['mean_step_ms']:.4g} ms, std "
           f"{st['std_step_ms']:.2g} ms, {st['catch_up_steps']} catch-up steps"
           + (f" (median {st['catch_up_median_ms']:.3g} ms)" if st["catch_up_steps"] else "")
           + f", longest {st['longest_step_ms']:.4g} ms" if st["irregular"] else
           f"regular: step {st['median_step_ms']:.4g} ms")
    used = ("integrated on the sensor's clock (evenly spaced at the mean step; --timestamps nominal)"
            if st["used"] == "nominal" else "used as recorded" + (
                " (--timestamps nominal would space them evenly at the mean step)" if st["irregular"] else ""))
    return f"time stamps: {how}; {used}; {st['chosen_by']}"
