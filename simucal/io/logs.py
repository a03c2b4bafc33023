"""The logs most MEMS users have, read into one stream (a measurement set without segments.csv): PX4's
ULog (pyulog), ArduPilot's DataFlash .bin (pymavlink), ROS 1 and ROS 2 bags of sensor_msgs/Imu (rosbags).
Each reader is its format's own library, an optional dependency: `pip install 'simucal[logs]'`.

The outputs stay as logged: m/s^2 and rad/s, in the log's sensor frame (PX4 and ArduPilot: FRD, the body
frame after the board's rotation; ROS: the message's frame_id, FLU by REP 103), with temp_c where the log
has it. meta.json's `log` block says the file, the topic or instance, the frame, each sensor's device id
and how the two sensors were put on one clock.

One clock: PX4 logs sensor_accel and sensor_gyro as two topics, each at its own rate and time stamps
(timestamp_sample). The rows are the slower sensor's samples at its stamps; each row's other sensor is the
mean of its samples stamped in (the slower's previous stamp, this one]: a bin mean, so the Allan variance
at multiples of the step is the logged data's, with nothing interpolated. A row whose interval holds no
sample of the faster sensor is left out, and the log block counts such gaps and names the longest.
ArduPilot's IMU message and ROS's Imu carry both sensors at one stamp and need none of this.

A file that cannot be used is refused in one line naming it and what is missing (ImportError_).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from simucal import io
from simucal.io.importers import ImportError_, import_meta


@dataclass
class LogStream:
    t_s: np.ndarray          # (n,) s
    acc_mps2: np.ndarray     # (n, 3)
    gyro_rads: np.ndarray    # (n, 3)
    temp_c: np.ndarray | None  # (n,) or None
    log: dict = field(default_factory=dict)  # meta.json's `log` block


def _need(module: str, fmt: str, path):
    try:
        return __import__(module, fromlist=["_"])
    except ImportError:
        raise ImportError_(f"{path}: reading a {fmt} needs {module.split('.')[0]}: pip install 'simucal[logs]'") from None


def read_ulog(path, instance: int = 0) -> LogStream:
    """PX4's sensor_accel and sensor_gyro of one multi instance (x y z m/s^2 and rad/s, temperature, device_id),
    on one clock (module doc)."""
    path = Path(path)
    pyulog = _need("pyulog", "ULog", path)
    _whole_ulog(path)
    try:
        ulog = pyulog.ULog(str(path), ["sensor_accel", "sensor_gyro"])
    except Exception as e:  # pyulog raises bare Exceptions on a foreign or broken file
        raise ImportError_(f"{path}: not a ULog pyulog can read ({e})") from None
    topics = {}
    for name in ("sensor_accel", "sensor_gyro"):
        found = sorted(d.multi_id for d in ulog.data_list if d.name == name)
        if instance not in found:
            raise ImportError_(f"{path}: no {name} instance {instance} in the log (it has "
                               f"{'instances ' + ', '.join(map(str, found)) if found else 'no ' + name}): "
                               f"{'give --instance ' + str(found[0]) if found else 'log the IMU (SDLOG_PROFILE)'}")
        topics[name] = ulog.get_dataset(name, instance).data
    a, g = topics["sensor_accel"], topics["sensor_gyro"]
    t_a, t_g = (np.asarray(d.get("timestamp_sample", d["timestamp"]), float) * 1e-6 for d in (a, g))
    acc = np.column_stack([a["x"], a["y"], a["z"]]).astype(float)
    gyro = np.column_stack([g["x"], g["y"], g["z"]]).astype(float)
    temp_a = np.asarray(a["temperature"], float) if "temperature" in a else None
    t, acc, gyro, temp, clock = on_one_clock(t_a, acc, temp_a, t_g, gyro, path)
    log = {"format": "ulog", "file": path.name, "instance": instance, "topics": ["sensor_accel", "sensor_gyro"],
           "sensor_frame": "FRD (PX4's body frame, after the board's rotation)", "clock": clock,
           "acc_device_id": _device_id(a), "gyro_device_id": _device_id(g),
           "temperature": "sensor_accel's" if temp is not None else None}
    return LogStream(t, acc, gyro, temp, log)


def _whole_ulog(path: Path) -> None:
    """Refuse a ULog cut short: after its 16-byte header every message is a uint16 size and a uint8 type,
    and the last must end where the file does (pyulog drops a cut message without a word)."""
    data = path.read_bytes()
    if data[:7] != b"ULog\x01\x12\x35":
        raise ImportError_(f"{path}: not a ULog (its first bytes are not ULog's magic)")
    pos, n = 16, len(data)
    while pos + 3 <= n:
        pos += 3 + data[pos] + 256 * data[pos + 1]
    if pos != n:
        raise ImportError_(f"{path}: the log is cut short: its last message ends {pos - n} bytes past the file's end "
                           f"(at byte {n:,}); a log copied before the vehicle closed it, or truncated: copy it again")


def _device_id(d) -> int | None:
    return int(np.median(d["device_id"])) if "device_id" in d and len(d["device_id"]) else None


def read_dataflash(path, instance: int = 0) -> LogStream:
    """ArduPilot's IMU messages of one instance (TimeUS, GyrX..Z rad/s, AccX..Z m/s^2, T degC) and the
    device ids INS_ACC_ID / INS_GYR_ID (INS_ACC2_ID ... for instance 1 ...) from its parameters."""
    path = Path(path)
    _need("pymavlink", "DataFlash log", path)
    from pymavlink import DFReader
    try:
        log = DFReader.DFReader_binary(str(path))
    except Exception as e:  # pymavlink raises what its parser meets
        raise ImportError_(f"{path}: not a DataFlash log pymavlink can read ({e})") from None
    rows, params, seen = [], {}, set()
    while True:
        m = log.recv_match(type=["IMU", "PARM"])
        if m is None:
            break
        if m.get_type() == "PARM":
            params[m.Name] = m.Value
            continue
        seen.add(getattr(m, "I", 0))
        if getattr(m, "I", 0) == instance:
            rows.append((m.TimeUS, m.AccX, m.AccY, m.AccZ, m.GyrX, m.GyrY, m.GyrZ, getattr(m, "T", math.nan)))
    _whole_dataflash(path)
    if not rows:
        raise ImportError_(f"{path}: no IMU messages of instance {instance} in the log (it has "
                           f"{'instances ' + ', '.join(map(str, sorted(seen))) if seen else 'no IMU messages'})"
                           + (f": give --instance {min(seen)}" if seen else ": set LOG_BITMASK to log the IMU"))
    r = np.array(rows, float)
    suffix = "" if instance == 0 else str(instance + 1)
    temp = None if np.all(np.isnan(r[:, 7])) else r[:, 7]
    orientation = params.get("AHRS_ORIENTATION", 0)
    log_block = {"format": "dataflash", "file": path.name, "instance": instance, "messages": "IMU",
                 "sensor_frame": "FRD (ArduPilot's body frame, after AHRS_ORIENTATION "
                                 f"{int(orientation)})", "clock": "one IMU message holds both sensors at one stamp",
                 "acc_device_id": _int(params.get(f"INS_ACC{suffix}_ID")),
                 "gyro_device_id": _int(params.get(f"INS_GYR{suffix}_ID")),
                 "ahrs_orientation": int(orientation), "temperature": "IMU.T" if temp is not None else None}
    t = r[:, 0] * 1e-6
    _increasing(t, path)
    return LogStream(t, r[:, 1:4], r[:, 4:7], temp, log_block)


def _whole_dataflash(path: Path) -> None:
    """Refuse a DataFlash log cut short: each message is 0xA3 0x95, its type and a body whose length the
    type's FMT message gives (FMT's own: 89 bytes), and the last must end where the file does."""
    data = path.read_bytes()
    lengths, pos, n = {128: 89}, 0, len(data)
    while pos + 3 <= n and data[pos:pos + 2] == b"\xa3\x95" and data[pos + 2] in lengths:
        if data[pos + 2] == 128 and pos + 5 <= n:
            lengths[data[pos + 3]] = data[pos + 4]  # FMT: the type it describes and that type's whole length
        pos += lengths[data[pos + 2]]
    if pos != n:
        raise ImportError_(f"{path}: the log is cut short or broken at byte {min(pos, n):,} of {n:,} (no whole message "
                           "there): copy it again from the vehicle")


def _int(v):
    return None if v is None else int(v)


def read_rosbag(path, topic: str | None = None) -> LogStream:
    """sensor_msgs/Imu on `topic` (the bag's only Imu topic where not given) of a ROS 1 bag or a ROS 2 bag
    folder, stamped by each message's header (the bag's receive time where the header's stamp is 0)."""
    path = Path(path)
    _need("rosbags", "ROS bag", path)
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as e:  # rosbags' ReaderError and what its storage backends raise
        raise ImportError_(f"{path}: not a ROS bag rosbags can read ({e})") from None
    try:
        imus = sorted({c.topic for c in reader.connections if c.msgtype == "sensor_msgs/msg/Imu"})
        if topic is None:
            if len(imus) != 1:
                raise ImportError_(f"{path}: {'no sensor_msgs/Imu topic' if not imus else 'several Imu topics: ' + ', '.join(imus)}"
                                   f" in the bag{': give --topic' if imus else ''} (its topics: "
                                   f"{', '.join(sorted({c.topic + ' ' + c.msgtype for c in reader.connections}))})")
            topic = imus[0]
        cons = [c for c in reader.connections if c.topic == topic]
        if not cons:
            raise ImportError_(f"{path}: no topic {topic} in the bag (its Imu topics: {', '.join(imus) or 'none'})")
        if any(c.msgtype != "sensor_msgs/msg/Imu" for c in cons):
            raise ImportError_(f"{path}: topic {topic} is {cons[0].msgtype}, not sensor_msgs/Imu"
                               + (f"; the bag's Imu topics: {', '.join(imus)}" if imus else ""))
        r, raws, frame, k = np.empty((sum(c.msgcount for c in cons), 7)), [], None, 0  # 56 bytes a message
        for con, t_bag, raw in reader.messages(connections=cons):
            raws.append((t_bag, raw))
            if len(raws) == CHUNK_MESSAGES:
                (rows, frame), raws = _imu_rows(reader, raws, con.msgtype), []
                r, k = _filled(r, k, rows)
        if raws:
            rows, frame = _imu_rows(reader, raws, cons[0].msgtype)
            r, k = _filled(r, k, rows)
    except ImportError_:
        raise
    except Exception as e:  # a bag cut short fails in rosbags' reader or its storage
        raise ImportError_(f"{path}: the bag could not be read to its end ({e}): copy it again, or reindex it") from None
    finally:
        reader.close()
    if not k:
        raise ImportError_(f"{path}: topic {topic} holds no messages")
    r = r[:k]
    _increasing(r[:, 0], path)
    log = {"format": "rosbag", "file": path.name, "topic": topic, "sensor_frame": f"{frame or '(no frame_id)'} "
           "(the message's frame_id; FLU by REP 103)", "clock": "one Imu message holds both sensors at one stamp",
           "temperature": None}
    return LogStream(r[:, 0], r[:, 1:4], r[:, 4:7], None, log)


def _imu_row(m, t_bag) -> tuple:
    """(t s, a x y z, w x y z) of one deserialised Imu message: the header's stamp, the bag's receive
    time where the stamp is 0."""
    stamp = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
    a, w = m.linear_acceleration, m.angular_velocity
    return (stamp if stamp > 0 else t_bag * 1e-9, a.x, a.y, a.z, w.x, w.y, w.z)


CHUNK_MESSAGES = 65536  # raw messages held at once (about 20 MB)


def _filled(r, k, rows):
    """rows written into r from row k (r grown where the bag held more messages than its index said)."""
    if k + len(rows) > len(r):
        r = np.concatenate([r[:k], np.empty((k + len(rows) - len(r[:k]), 7))])
    r[k:k + len(rows)] = rows
    return r, k + len(rows)


def _imu_rows(reader, raws, msgtype) -> tuple[np.ndarray, str | None]:
    """The rows (n, 7) of a chunk of a topic's raw Imu messages and the frame_id. Where every message has one
    length (one frame_id), they are read as one numpy record array at the fields' offsets in the
    serialisation (ROS 1: packed; ROS 2: CDR, each double aligned to 8 after the 4-byte header),
    checked against rosbags' deserialisation of the first and last message; else, or where the check
    fails, message by message (rosbags deserialises 60,000 messages a second; a 3 h bag at 200 Hz
    took 62 s)."""
    first = reader.deserialize(raws[0][1], msgtype) if raws else None
    frame = first.header.frame_id if first is not None else None
    if raws and len({len(raw) for _, raw in raws}) == 1:
        assert frame is not None  # the first message's (raws holds one)
        L = len(frame.encode())
        if reader.is2:  # CDR: 4-byte header; sec, nanosec, string (length with its NUL), doubles aligned to 8
            stamp, doubles = 4, 4 + (-(-(12 + L + 1) // 8) * 8)
        else:  # ROS 1: seq, secs, nsecs, string (length, chars), doubles packed
            stamp, doubles = 4, 16 + L
        buf = np.frombuffer(b"".join(raw for _, raw in raws), np.uint8).reshape(len(raws), -1)
        f8 = lambda off: buf[:, off:off + 24].copy().view("<f8")  # noqa: E731 (3 doubles a row)
        sec = buf[:, stamp:stamp + 4].copy().view("<u4" if not reader.is2 else "<i4")[:, 0].astype(float)
        nsec = buf[:, stamp + 4:stamp + 8].copy().view("<u4")[:, 0] * 1e-9
        t_bag = np.array([t for t, _ in raws], float) * 1e-9
        t = np.where(sec + nsec > 0, sec + nsec, t_bag)
        # orientation (4 doubles), its covariance (9), angular_velocity (3), its covariance (9), linear_acceleration
        rows = np.column_stack([t, f8(doubles + 8 * 25), f8(doubles + 8 * 13)])
        last = reader.deserialize(raws[-1][1], msgtype)
        if all(np.allclose(rows[i], _imu_row(m, raws[i][0]), rtol=0, atol=0) for i, m in ((0, first), (-1, last))):
            return rows, frame
    return np.array([_imu_row(reader.deserialize(raw, msgtype), t) for t, raw in raws]).reshape(-1, 7), frame


def _increasing(t, path):
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        raise ImportError_(f"{path}: time stamps do not increase at message {bad[0] + 1} ({t[bad[0]]:.6f} s then "
                           f"{t[bad[0] + 1]:.6f} s)")


def on_one_clock(t_a, acc, temp_a, t_g, gyro, path):
    """(t, acc, gyro, temp, how) of two sensors logged at their own stamps: the slower sensor's rows, the
    other's samples averaged over each row's interval (module doc). temp: the accelerometer's, on the rows."""
    for t, what in ((t_a, "sensor_accel"), (t_g, "sensor_gyro")):
        if len(t) < 2:
            raise ImportError_(f"{path}: {what} holds {len(t)} samples")
        _increasing(t, f"{path} ({what})")
    acc_slower = np.median(np.diff(t_a)) >= np.median(np.diff(t_g))
    (t_s, slow), (t_f, fast) = ((t_a, acc), (t_g, gyro)) if acc_slower else ((t_g, gyro), (t_a, acc))
    temp_s, temp_f = (temp_a, None) if acc_slower else (None, temp_a)
    rows = np.searchsorted(t_s, t_f, side="left")  # fast sample i falls in (t_s[rows-1], t_s[rows]]
    inside = (rows >= 1) & (rows < len(t_s))
    count = np.bincount(rows[inside], minlength=len(t_s))
    sums = np.stack([np.bincount(rows[inside], fast[inside, j], len(t_s)) for j in range(3)], axis=1)
    keep = count > 0
    mean = sums[keep] / count[keep, None]
    if temp_f is not None:
        temp_rows = np.bincount(rows[inside], temp_f[inside], len(t_s))[keep] / count[keep]
    else:
        temp_rows = None if temp_s is None else temp_s[keep]
    empty = np.nonzero(~keep[1:])[0] + 1
    gaps = {"rows_left_out": int(empty.size)}
    if empty.size:
        longest = int(empty[np.argmax(t_s[empty] - t_s[empty - 1])])
        gaps["longest_s"] = float(t_s[longest] - t_s[longest - 1])
        gaps["longest_at_s"] = float(t_s[longest - 1])
    slow_name, fast_name = ("sensor_accel", "sensor_gyro") if acc_slower else ("sensor_gyro", "sensor_accel")
    how = {"rows": f"{slow_name}'s samples at their timestamp_sample ({1 / np.median(np.diff(t_s)):.4g} Hz)",
           "other": f"{fast_name}'s samples ({1 / np.median(np.diff(t_f)):.4g} Hz) averaged over each row's interval "
                    "(the previous row's stamp, this row's]", "intervals_without_a_sample": gaps}
    t_keep = t_s[keep]
    slow_keep = slow[keep]
    if temp_rows is not None and np.all(np.isnan(temp_rows)):
        temp_rows = None
    acc_rows, gyro_rows = (slow_keep, mean) if acc_slower else (mean, slow_keep)
    return t_keep, acc_rows, gyro_rows, temp_rows, how


def is_rosbag(path) -> bool:
    """A ROS 1 bag (a file that starts as one) or a ROS 2 bag (a folder with metadata.yaml)."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file() and not (path / "meta.json").is_file()
    with path.open("rb") as fh:
        return fh.read(13) == b"#ROSBAG V2.0\n"


def bag_as_set(path, topic: str | None = None):
    """A ROS bag's Imu topic as a measurement set in memory (`simucal noise BAG`): the samples as
    `import rosbag` writes them. The latitude a bag does not hold is set to 0 and said: the Allan
    variance takes out each stretch's mean, and with it the Earth rate."""
    from simucal.io.arrays import from_arrays
    s = read_rosbag(path, topic)
    return from_arrays(s.acc_mps2, s.gyro_rads, acc_unit="m/s^2", gyro_unit="rad/s", t_s=s.t_s - s.t_s[0],
                       meta={"latitude_deg": 0.0, "log": {**s.log, "t0_s": float(s.t_s[0])},
                             "description": f"{Path(path).name}, topic {s.log['topic']} (latitude unknown, 0 here: the "
                                            "Allan deviation does not use it)"}, name=str(path))


READERS: dict[str, Callable[..., LogStream]] = {"ulog": read_ulog, "dataflash": read_dataflash, "rosbag": read_rosbag}


def read_log(fmt: str, path, instance: int = 0, topic: str | None = None) -> LogStream:
    """The log at path in format fmt (ulog, dataflash or rosbag)."""
    if fmt == "rosbag":
        return read_rosbag(path, topic)
    return READERS[fmt](path, instance)


def import_log(fmt: str, path, out, latitude_deg, instance: int = 0, topic: str | None = None) -> dict:
    """`simucal import ulog|dataflash|rosbag FILE -o SET`: the log as a stream (module doc); its meta."""
    s = read_log(fmt, path, instance, topic)
    if s.temp_c is not None and not np.all(np.isfinite(s.temp_c)):
        s.temp_c = None  # a driver without a temperature logs NaN: no column rather than a broken one
        s.log["temperature"] = None
    meta = import_meta("m/s^2", "rad/s", latitude_deg, {"log": s.log, "description": f"imported from {Path(path).name} "
                                                  f"({fmt}): {s.log.get('topic') or 'instance ' + str(instance)}"})
    samples = {"t_s": s.t_s - s.t_s[0], "ax": s.acc_mps2[:, 0], "ay": s.acc_mps2[:, 1], "az": s.acc_mps2[:, 2],
               "gx": s.gyro_rads[:, 0], "gy": s.gyro_rads[:, 1], "gz": s.gyro_rads[:, 2]}
    s.log["t0_s"] = float(s.t_s[0])  # the log's own time of the first row (t_s counts from it)
    if s.temp_c is not None:
        samples["temp_c"] = s.temp_c
    io.write_set(out, meta, samples)
    return meta
