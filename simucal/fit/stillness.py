"""Whether a recording is still enough for the Allan deviation (`simucal noise`): the sample clock without
gaps, and the unit at rest (its 1-s means wander by noise only), on a set in memory or on a stream read a chunk
at a time (its integrated output, simucal.fit.allan_sums)."""
from __future__ import annotations

import numpy as np

from simucal import io
from simucal.errors import CalibrationError

def still_stretches(ms, sensor, kind) -> tuple[list[np.ndarray], float, str]:
    """(stretches (rows, 3), dt, where): the rows the set's kind (simucal.methods.Kind) holds still, the whole
    stream or each static segment of a raw turntable set (three rows or more), in deg/h or g."""
    data = ms.gyro_dph() if sensor == "gyro" else ms.acc_g()
    t = ms.samples["t_s"]
    pieces, where = kind.still_rows(ms)
    dt = sample_step(np.concatenate([np.diff(t[p]) for p in pieces]), ms.path / "samples.csv")
    return [data[p] for p in pieces], dt, where


def sample_step(dts, path) -> float:
    """The sample clock (s): the median step of t_s; refused where a step is a gap (lost samples)."""
    lo, hi = float(dts.min()), float(dts.max())
    dt = float(np.median(dts, overwrite_input=True))  # dts reordered in place: no copy of a long record's steps
    # a logger's timestamps jitter around the sample clock (taken as the median step); a gap is lost samples
    if dt <= 0 or max(hi - dt, dt - lo) > 0.5 * dt:
        raise CalibrationError(f"{path}: t_s has gaps within the still stretches (steps "
                               f"{lo:.4g} to {hi:.4g} s, median {dt:.4g}): the Allan deviation needs "
                               "every sample of a constant rate; cut the recording at the gaps")
    return dt


def second_rows(dt) -> int:
    """Rows in one second: the means check_still compares."""
    return max(int(round(1.0 / dt)), 1)


# A still unit's 1-s means wander by its noise and drift only, far below these; a hand-placed move passes them
# (0.05 g of specific force; 1 deg/s of rate, where a set has no accelerometers to tell)
MOVING = {"acc": (0.05, "g", "specific force"), "gyro": (3600.0, "deg/h", "rate")}


def check_still(ms, dt, kind):
    """Where the set's kind must be still throughout (simucal.methods.Kind.still_whole), refuse a stream that moves: its
    1-s mean specific force (or, without accelerometers, rate) may wander by noise, not move by MOVING's amount (the
    difference of two means: a raw register's zero cancels, where an angle would need it)."""
    if not kind.still_whole:
        return
    sensor = "acc" if ms.has_acc else "gyro"
    x = ms.acc_g() if sensor == "acc" else ms.gyro_dph()
    k = second_rows(dt)
    refuse_moving(x[: len(x) // k * k].reshape(-1, k, 3).mean(1), x.mean(0), ms.path, sensor)


def refuse_moving(x_1s, x_mean, where, sensor="acc"):
    """check_still on a sensor's 1-s means (rows, 3) and its mean over the record (g or deg/h)."""
    limit, unit, what = MOVING[sensor]
    off = np.linalg.norm(x_1s - x_mean, axis=1)
    if len(off) > 1 and np.max(off) > limit:
        raise CalibrationError(f"{where}: the unit moves during the recording (its 1-s mean {what} differs "
                               f"from the record's mean by up to {np.max(off):.2g} {unit}, where a still unit's "
                               "wanders by the noise only): the Allan deviation needs a still unit; record it at rest")


def check_still_stream(kept, dt, where, sensor) -> None:
    """check_still from a sensor's theta: the 1-s means are its differences."""
    triad = io.SENSOR_COLS[sensor]
    th = [kept.theta[c] for c in triad]
    n, k = th[0].n - 1, second_rows(dt)
    center = np.array([kept.center[c] for c in triad])
    sums = np.column_stack([t.at(np.arange(0, n // k * k + 1, k)) for t in th])
    whole = np.array([t.at(np.array([n]))[0] for t in th])
    refuse_moving(np.diff(sums, axis=0) / k + center, whole / n + center, where, sensor)


