"""ArduPilot's DataFlash .bin (pymavlink) as one IMU stream.

The IMU messages carry both sensors at one stamp: TimeUS, GyrX..Z (rad/s), AccX..Z (m/s^2) and T (degC).
ArduPilot 4.x logs every IMU as `IMU` with an instance field I; older logs write the second and third as
`IMU2` and `IMU3` (no I), read here as instances 1 and 2. The device ids are the parameters INS_ACC_ID /
INS_GYR_ID (INS_ACC2_ID ... for instance 1, ...).

A file is a run of messages, each 0xA3 0x95, its type and a body whose length the type's FMT message gives
(FMT's own: 89 bytes). A log cut inside its last message (power pulled, a copy stopped) keeps every whole
message before the cut and says where; a file broken in its middle, or that is not a DataFlash log at all,
is refused in one line (pymavlink, which resynchronises byte by byte, would print a line per byte).
"""
from __future__ import annotations

import contextlib
import io as _io
import math
from pathlib import Path

import numpy as np

from simucal.io.importers import ImportError_
from simucal.io.log_stream import LogStream, increasing, need, other_format

NUMBERED = {"IMU": 0, "IMU2": 1, "IMU3": 2}  # instance of a message without I (logs before ArduPilot 4.0)


def read_dataflash(path, instance: int | None = None) -> LogStream:
    """The IMU messages of one instance (module doc; None: the lowest instance the log holds)."""
    path = Path(path)
    parsed = _parsed(path)
    seen = sorted(parsed[0])
    return _stream(path, parsed, seen[0] if instance is None and seen else instance)


def read_dataflash_instances(path, instances: list[int] | None = None) -> list[LogStream]:
    """Each instance's IMU messages, the log parsed once; `instances` None: every instance it holds."""
    path = Path(path)
    parsed = _parsed(path)
    wanted: list[int | None] = list(instances or sorted(parsed[0])) or [None]  # None: refused, saying why
    return [_stream(path, parsed, i) for i in wanted]


def _parsed(path: Path) -> tuple[dict[int, list[tuple]], dict[int, str], dict, list[str]]:
    """_messages's rows, kinds and parameters of the whole messages, and the warnings of a cut end."""
    need("pymavlink", "DataFlash log", path)
    from pymavlink import DFReader
    whole, warnings = whole_dataflash(path)
    try:
        with contextlib.redirect_stdout(_io.StringIO()):  # pymavlink prints what it skips
            log = DFReader.DFReader_binary(str(path))
            return (*_messages(log, whole), warnings)
    except ImportError_:
        raise
    except Exception as e:  # pymavlink raises what its parser meets
        raise ImportError_(f"{path}: not a DataFlash log pymavlink can read ({e})") from None


def _stream(path: Path, parsed, instance: int | None) -> LogStream:
    rows, kinds, params, warnings = parsed
    seen = sorted(rows)
    if instance is None or instance not in rows:
        raise ImportError_(f"{path}: no IMU messages{'' if instance is None else f' of instance {instance}'} in the "
                           f"log (it has {'instances ' + ', '.join(map(str, seen)) if seen else 'no IMU messages'})"
                           + (f": give --instance {seen[0]}" if seen else ": set LOG_BITMASK to log the IMU"))
    r = np.array(rows[instance], float)
    suffix = "" if instance == 0 else str(instance + 1)
    temp = None if np.all(np.isnan(r[:, 7])) else r[:, 7]
    orientation = params.get("AHRS_ORIENTATION", 0)
    log_block = {"format": "dataflash", "file": path.name, "instance": instance,
                 "messages": kinds[instance], "instances": seen,
                 "sensor_frame": f"FRD (ArduPilot's body frame, after AHRS_ORIENTATION {int(orientation)})",
                 "clock": "one IMU message holds both sensors at one stamp",
                 "acc_device_id": _int(params.get(f"INS_ACC{suffix}_ID")),
                 "gyro_device_id": _int(params.get(f"INS_GYR{suffix}_ID")),
                 "ahrs_orientation": int(orientation), "temperature": "IMU.T" if temp is not None else None}
    t = r[:, 0] * 1e-6
    increasing(t, path)
    return LogStream(t, r[:, 1:4], r[:, 4:7], temp, log_block, list(warnings))


def _messages(log, whole: int) -> tuple[dict[int, list[tuple]], dict[int, str], dict]:
    """{instance: [(TimeUS, acc x y z, gyro x y z, T)]}, {instance: its message's name} and the parameters,
    of the messages that end by byte `whole`."""
    rows: dict[int, list[tuple]] = {}
    kinds: dict[int, str] = {}
    params = {}
    while True:
        m = log.recv_match(type=["IMU", "IMU2", "IMU3", "PARM"])
        if m is None or log.offset > whole:
            break
        if m.get_type() == "PARM":
            params[m.Name] = m.Value
            continue
        i = int(getattr(m, "I", NUMBERED[m.get_type()]))
        kinds[i] = m.get_type()
        rows.setdefault(i, []).append((m.TimeUS, m.AccX, m.AccY, m.AccZ, m.GyrX, m.GyrY, m.GyrZ,
                                       getattr(m, "T", math.nan)))
    return rows, kinds, params


def whole_dataflash(path: Path) -> tuple[int, list[str]]:
    """(the byte where the last whole message ends, the warnings) of a DataFlash log (module doc); a file that
    is not one, or is broken before its end, is refused."""
    data = path.read_bytes()
    if data[:3] != b"\xa3\x95\x80":
        raise ImportError_(f"{path}: not a DataFlash log (it does not start with a FMT message, bytes A3 95 80)"
                           f"{other_format(data)}")
    lengths, pos, n = {128: 89}, 0, len(data)
    while pos + 3 <= n and data[pos:pos + 2] == b"\xa3\x95" and data[pos + 2] in lengths:
        if pos + lengths[data[pos + 2]] > n:
            break  # a message the file ends inside
        if data[pos + 2] == 128:
            lengths[data[pos + 3]] = data[pos + 4]  # FMT: the type it describes and that type's whole length
        pos += lengths[data[pos + 2]]
    if pos == n:
        return n, []
    # cut inside a message, or ending in bytes no message follows (a card's padding): every whole message is kept
    at_end = pos + 3 > n or (data[pos:pos + 2] == b"\xa3\x95" and data[pos + 2] in lengths) \
        or data.find(b"\xa3\x95", pos) < 0
    if not at_end:
        raise ImportError_(f"{path}: the log is broken at byte {pos:,} of {n:,}: no whole message starts there "
                           f"({n - pos:,} bytes follow): copy it again from the vehicle")
    return pos, [f"{path}: the log is cut inside its last message, or ends in bytes that are no message: every "
                 f"message up to byte {pos:,} is read, the last {n - pos:,} bytes are left out"]


def _int(v):
    return None if v is None else int(v)
