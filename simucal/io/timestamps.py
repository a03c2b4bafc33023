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
from typing import TYPE_CHECKING, Sequence, cast

import numpy as np

from simucal.errors import InputError
from simucal.io.stream_records import Gap, SegmentGap, Timestamps

if TYPE_CHECKING:  # simucal.io imports this module's users
    from simucal.io import MeasurementSet

CHOICES = ("auto", "nominal", "recorded")
IRREGULAR = 0.05   # steps farther than this share of the median step from it: irregular, where ...
IRREGULAR_SHARE = 0.01  # ... at least this share of the steps are
CATCH_UP = 0.75    # a step shorter than this share of the median is a catch-up
CLOCK_BOUND_STEPS = 2.0  # arrival times within this many median steps of an even clock: a regular clock
GAP_STEPS = 5.0    # a step longer than this many median steps is a gap: samples missing, not jitter


def gaps(t, rows=None) -> list[Gap]:
    """Every gap in the stamps t (a step over GAP_STEPS median steps): where it starts (s, and the row after
    which it opens), how long it lasts and how many samples at the median step it lacks. rows: the rows'
    numbers in the set, where t is a part of it."""
    t = np.asarray(t, float)
    if len(t) < 3:
        return []
    dt = np.diff(t)
    med = float(np.median(dt))
    rows = np.arange(len(t)) if rows is None else np.asarray(rows)
    return [{"after_row": int(rows[k]), "start_s": float(t[k]), "length_s": float(dt[k]),
             "samples_missing": int(round(dt[k] / med)) - 1} for k in np.nonzero(dt > GAP_STEPS * med)[0]]


def gap_text(found: Sequence[Gap], most=3) -> str:
    """The gaps in words: how many, then the first `most` (where, how long, samples missing)."""
    return (f"{len(found)} gap{'s' * (len(found) != 1)} in t_s (" + "; ".join(
        f"{g['length_s']:.4g} s from t = {g['start_s']:.6g} s, {g['samples_missing']} samples missing"
        for g in found[:most]) + (" ..." if len(found) > most else "") + ")")


def statistics(t) -> Timestamps:
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
            "regular_clock": bool(off <= CLOCK_BOUND_STEPS), "gaps": gaps(t)}


def with_timestamps(ms: MeasurementSet, choice: str = "auto") -> tuple[MeasurementSet, Timestamps | None]:
    """(the set with the time stamps to integrate on, the timestamps block of the calibration file).
    A stream only (a turntable's segments keep theirs); nominal: evenly spaced at the mean step;
    auto: nominal where the stamps are irregular and a regular clock is proved, else as recorded."""
    if choice not in CHOICES:
        raise InputError(f"--timestamps {choice!r}: one of {', '.join(CHOICES)}")
    if ms.segments is not None or len(ms.samples["t_s"]) < 3:
        if choice == "nominal":
            from simucal.errors import CalibrationError
            raise CalibrationError(f"{ms.path / 'samples.csv'}: --timestamps nominal respaces a continuous stream's "
                                   "stamps; this set has segments.csv (leave the option out)")
        return ms, segment_gaps(ms)
    st = statistics(ms.samples["t_s"])
    if choice == "nominal" and st["gaps"]:
        from simucal.errors import CalibrationError
        raise CalibrationError(f"{ms.path / 'samples.csv'}: --timestamps nominal would spread the stream's "
                               f"{gap_text(st['gaps'])} over every step; leave the option out (the recorded stamps "
                               "keep the gap where it is, and no move is integrated across one), or record without it")
    nominal = choice == "nominal" or (choice == "auto" and st["irregular"] and st["regular_clock"] and not st["gaps"])
    st["used"], st["choice"] = ("nominal" if nominal else "recorded"), choice  # the option, for validate
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


def segment_gaps(ms) -> Timestamps | None:
    """The gaps inside the segments of a set with segments.csv (between segments the table moves and nothing
    need be recorded), as the calibration's timestamps block, or None where there are none: named, never
    spread (each segment's mean and a rate run's fit take its rows at their recorded stamps)."""
    if ms.segments is None:
        return None
    found = [cast(SegmentGap, dict(g, segment=s.segment)) for s in ms.segments
             for g in gaps(ms.samples["t_s"][ms.rows(s.segment)], ms.rows(s.segment))]
    if not found:
        return None
    return {"gaps": found, "used": "recorded", "irregular": False, "chosen_by": "the segments' stamps as recorded",
            "text": f"time stamps: {gap_text(found)} inside segment{'s' * (len(found) > 1)} "
                    f"{', '.join(str(g['segment']) for g in found[:6])}: each segment's rows are taken at their "
                    "recorded stamps (nothing spread); check the recording there"}


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
    gap = f"; {gap_text(st['gaps'])}: no move is integrated across one" if st.get("gaps") else ""
    return f"time stamps: {how}{gap}; {used}; {st['chosen_by']}"
