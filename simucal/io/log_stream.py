"""What every log reader returns (`LogStream`) and the pieces they share: the optional readers' import,
the stamps' checks, and two sensors put on one clock.

One clock: PX4 can log sensor_accel and sensor_gyro as two topics, each at its own rate and time stamps
(timestamp_sample). The rows are the slower sensor's samples at its stamps; each row's other sensor is the
mean of its samples stamped in (the slower's previous stamp, this one]: a bin mean, so the Allan variance
at multiples of the step is the logged data's, with nothing interpolated. The slower sensor's first sample
has no interval before it, and a row whose interval holds no sample of the faster sensor is left out; the
log block counts both and names the longest such interval. ArduPilot's IMU message, PX4's sensor_combined
and ROS's Imu carry both sensors in one message and need none of this.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from simucal.io.importers import ImportError_


@dataclass
class LogStream:
    t_s: np.ndarray          # (n,) s, the log's own clock
    acc_mps2: np.ndarray     # (n, 3)
    gyro_rads: np.ndarray    # (n, 3)
    temp_c: np.ndarray | None  # (n,) or None
    log: dict = field(default_factory=dict)  # meta.json's `log` block
    warnings: list[str] = field(default_factory=list)  # what the reader kept but a user must know


def need(module: str, fmt: str, path):
    """The optional reader `module`, or a one-line refusal naming the extra that installs it."""
    try:
        return __import__(module, fromlist=["_"])
    except ImportError:
        raise ImportError_(f"{path}: reading a {fmt} needs {module.split('.')[0]}: "
                           "pip install 'simucal[logs]'") from None


def other_format(data: bytes) -> str:
    """`: it is a ...` where a file's first bytes name a log format (for a refusal of the wrong one)."""
    if data[:3] == b"\xa3\x95\x80":
        return ": it is a DataFlash log: simucal import dataflash"
    if data[:13] == b"#ROSBAG V2.0\n":
        return ": it is a ROS 1 bag: simucal import rosbag"
    if data[:7] == b"ULog\x01\x12\x35":
        return ": it is a ULog: simucal import ulog"
    return ""


def increasing(t, path):
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        raise ImportError_(f"{path}: time stamps do not increase at message {bad[0] + 1} ({t[bad[0]]:.6f} s then "
                           f"{t[bad[0] + 1]:.6f} s)")


def on_one_clock(t_a, acc, temp_a, t_g, gyro, path, names=("sensor_accel", "sensor_gyro")):
    """(t, acc, gyro, temp, how) of two sensors logged at their own stamps: the slower sensor's rows, the
    other's samples averaged over each row's interval (module doc). temp: the accelerometer's, on the rows;
    names: the two topics', for the log block and the refusals."""
    for t, what in ((t_a, names[0]), (t_g, names[1])):
        if len(t) < 2:
            raise ImportError_(f"{path}: {what} holds {len(t)} samples")
        increasing(t, f"{path} ({what})")
    if t_a[-1] <= t_g[0] or t_g[-1] <= t_a[0]:
        raise ImportError_(f"{path}: {names[0]} ({t_a[0]:.3f} to {t_a[-1]:.3f} s) and {names[1]} ({t_g[0]:.3f} to "
                           f"{t_g[-1]:.3f} s) never overlap in time: no row holds both sensors")
    acc_slower = np.median(np.diff(t_a)) >= np.median(np.diff(t_g))
    (t_s, slow), (t_f, fast) = ((t_a, acc), (t_g, gyro)) if acc_slower else ((t_g, gyro), (t_a, acc))
    temp_s, temp_f = (temp_a, None) if acc_slower else (None, temp_a)
    rows = np.searchsorted(t_s, t_f, side="left")  # fast sample i falls in (t_s[rows-1], t_s[rows]]
    inside = (rows >= 1) & (rows < len(t_s))
    count = np.bincount(rows[inside], minlength=len(t_s))
    sums = np.stack([np.bincount(rows[inside], fast[inside, j], len(t_s)) for j in range(3)], axis=1)
    keep = count > 0
    if not keep.any():
        raise ImportError_(f"{path}: no {names[0]} interval holds a {names[1]} sample (or the reverse)")
    mean = sums[keep] / count[keep, None]
    temp_rows: np.ndarray | None
    if temp_f is not None:
        temp_rows = np.bincount(rows[inside], temp_f[inside], len(t_s))[keep] / count[keep]
    else:
        temp_rows = None if temp_s is None else temp_s[keep]
    empty = np.nonzero(~keep[1:])[0] + 1
    # the first sample's, which has no interval, counted too
    gaps: dict[str, float] = {"rows_left_out": int((~keep).sum())}
    if empty.size:
        longest = int(empty[np.argmax(t_s[empty] - t_s[empty - 1])])
        gaps["longest_s"] = float(t_s[longest] - t_s[longest - 1])
        gaps["longest_at_s"] = float(t_s[longest - 1])
    slow_name, fast_name = names if acc_slower else names[::-1]
    how = {"rows": f"{slow_name}'s samples at their timestamp_sample ({1 / np.median(np.diff(t_s)):.4g} Hz)",
           "other": f"{fast_name}'s samples ({1 / np.median(np.diff(t_f)):.4g} Hz) averaged over each row's interval "
                    "(the previous row's stamp, this row's]", "intervals_without_a_sample": gaps}
    if temp_rows is not None and np.all(np.isnan(temp_rows)):
        temp_rows = None
    acc_rows, gyro_rows = (slow[keep], mean) if acc_slower else (mean, slow[keep])
    return t_s[keep], acc_rows, gyro_rows, temp_rows, how
