"""Test logs in the autopilots' and ROS's formats, written from simulated units with a planted truth:
a ULog by its specification (docs.px4.io, "ULog File Format": a 16-byte header, then messages of a
uint16 size and a uint8 type), a DataFlash .bin by ArduPilot's (FMT messages describing the others, each
message 0xA3 0x95 and its type id) and ROS 1 and ROS 2 bags by rosbags' writers. pyulog, pymavlink and
rosbags read them as they read a vehicle's logs (tests/test_logs.py)."""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

ULOG_MAGIC = b"ULog\x01\x12\x35"
PX4_ACCEL = ("uint64_t timestamp", "uint64_t timestamp_sample", "uint32_t device_id", "float x", "float y", "float z",
             "float temperature", "uint32_t error_count")
PX4_BARO = ("uint64_t timestamp", "uint64_t timestamp_sample", "uint32_t device_id", "float pressure",
            "float temperature", "uint32_t error_count")
PX4_GYRO = PX4_ACCEL
PX4_FIFO = ("uint64_t timestamp", "uint64_t timestamp_sample", "uint32_t device_id", "float dt", "float scale",
            "uint8_t samples", "int16_t[32] x", "int16_t[32] y", "int16_t[32] z")  # sensor_accel_fifo, sensor_gyro_fifo
PX4_IMU_FIFO = ("uint64_t timestamp", "uint64_t timestamp_sample", "uint32_t device_id", "float dt", "uint8_t samples",
                "float accel_scale", "float gyro_scale",
                *(f"int16_t[24] {s}_{a}" for s in ("accel", "gyro") for a in "xyz"), "float temperature",
                "uint32_t error_count")  # sensor_imu_fifo, both sensors in one (a few PX4 versions)


def _ulog_message(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def _ulog_key(kind: bytes, ctype: str, name: str, value: bytes) -> bytes:
    key = f"{ctype} {name}".encode()
    return _ulog_message(kind, struct.pack("<B", len(key)) + key + value)


def write_ulog(path, accel: dict | list | None, gyro: dict | list | None, instance=0, params=None, truncate_bytes=0,
               baro=None, accel_fifo: dict | list | None = None, gyro_fifo: dict | list | None = None,
               imu_fifo: dict | None = None):
    """A ULog with sensor_accel and sensor_gyro (PX4's fields; either None: left out) of multi instance
    `instance`, or lists of them, one an instance from `instance` on. Each a dict of numpy columns: t_us
    (timestamp and timestamp_sample), x, y, z (m/s^2 or rad/s), temperature (degC, NaN where the driver has
    none), device_id. baro: a sensor_baro topic (t_us, pressure hPa, temperature, device_id), which PX4's
    thermal calibration script reads too. accel_fifo, gyro_fifo: sensor_accel_fifo and sensor_gyro_fifo
    (PX4's fields), one message a row: t_us (timestamp_sample, the newest sample's), dt (us), scale,
    samples, x, y, z ((n, 32) integer counts), device_id; a list: one an instance from `instance` on.
    imu_fifo: sensor_imu_fifo of instance `instance`: t_us, dt, samples, accel_scale, gyro_scale, accel_x ...
    gyro_z ((n, 24) counts), temperature, device_id.
    truncate_bytes: cut the file's end."""
    out = bytearray(ULOG_MAGIC + b"\x01" + struct.pack("<Q", 0))
    out += _ulog_message(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    listed = lambda c: [] if c is None else c if isinstance(c, list) else [c]  # noqa: E731
    topics = [(name, fields, pack, cols, i) for name, fields, pack, group in (
        ("sensor_accel", PX4_ACCEL, _sensor_row, listed(accel)), ("sensor_gyro", PX4_GYRO, _sensor_row, listed(gyro)),
        ("sensor_baro", PX4_BARO, _baro_row, listed(baro)),
        ("sensor_accel_fifo", PX4_FIFO, _fifo_row, listed(accel_fifo)),
        ("sensor_gyro_fifo", PX4_FIFO, _fifo_row, listed(gyro_fifo)),
        ("sensor_imu_fifo", PX4_IMU_FIFO, _imu_fifo_row, listed(imu_fifo)))
        for i, cols in enumerate(group, start=instance if name != "sensor_baro" else 0)]
    for name, fields in dict.fromkeys((t[0], t[1]) for t in topics):
        out += _ulog_message(b"F", (f"{name}:" + "".join(f"{f};" for f in fields)).encode())
    out += _ulog_key(b"I", "char[8]", "sys_name", b"PX4_SITL")
    for name, value in (params or {}).items():
        out += _ulog_key(b"P", "float" if isinstance(value, float) else "int32_t", name,
                         struct.pack("<f" if isinstance(value, float) else "<i", value))
    for msg_id, (name, *_, i) in enumerate(topics):
        out += _ulog_message(b"A", struct.pack("<BH", i, msg_id) + name.encode())
    rows = []
    for msg_id, (_, _, pack, c, _) in enumerate(topics):
        for k in range(len(c["t_us"])):
            rows.append((int(c["t_us"][k]), msg_id, _ulog_message(b"D", struct.pack("<H", msg_id) + pack(c, k))))
    rows.sort(key=lambda r: (r[0], r[1]))
    out += b"".join(r[2] for r in rows)
    Path(path).write_bytes(bytes(out[:len(out) - truncate_bytes]))


def _sensor_row(c, k) -> bytes:
    return struct.pack("<QQIffffI", int(c["t_us"][k]), int(c["t_us"][k]), int(c["device_id"]),
                       *(c[v][k] for v in ("x", "y", "z", "temperature")), 0)


def _baro_row(c, k) -> bytes:
    return struct.pack("<QQIffI", int(c["t_us"][k]), int(c["t_us"][k]), int(c["device_id"]), c["pressure"][k],
                       c["temperature"][k], 0)


def _fifo_row(c, k) -> bytes:
    each = lambda v: np.broadcast_to(c[v], (len(c["t_us"]),))[k]  # noqa: E731 (a scalar or one a message)
    return struct.pack("<QQIffB32h32h32h", int(c["t_us"][k]), int(c["t_us"][k]), int(c["device_id"]),
                       each("dt"), each("scale"), int(c["samples"][k]),
                       *(int(v) for axis in "xyz" for v in c[axis][k]))


def _imu_fifo_row(c, k) -> bytes:
    return struct.pack("<QQIfBff144hfI", int(c["t_us"][k]), int(c["t_us"][k]), int(c["device_id"]), c["dt"],
                       int(c["samples"][k]), c["accel_scale"], c["gyro_scale"],
                       *(int(v) for s in ("accel", "gyro") for a in "xyz" for v in c[f"{s}_{a}"][k]),
                       c["temperature"][k], 0)


DF_HEAD = b"\xa3\x95"
DF_FMT = 128
DF_TYPES = {"Q": 8, "B": 1, "f": 4, "N": 16, "I": 4, "Z": 64, "n": 4}


def _df_fmt(type_id: int, name: str, fmt: str, columns: str) -> bytes:
    length = 3 + sum(DF_TYPES[c] for c in fmt)
    return DF_HEAD + struct.pack("<BBB4s16s64s", DF_FMT, type_id, length, name.encode(), fmt.encode(), columns.encode())


def write_dataflash(path, imu: dict | list | None, instance=0, params=None, temperature=True, truncate_bytes=0,
                    numbered=False):
    """An ArduPilot DataFlash log: FMT, PARM messages (TimeUS, Name, Value) and IMU messages (TimeUS, I,
    GyrX..Z rad/s, AccX..Z m/s^2 and, where temperature, T degC) of instance `instance`; imu a dict of numpy
    columns t_us, acc (n, 3), gyro (n, 3), temperature (or None: no IMU messages), or a list of them, one an
    instance from `instance` on. numbered: as logs before ArduPilot 4.0, the second and third IMU as IMU2
    and IMU3 messages without an I field."""
    cols = "GyrX,GyrY,GyrZ,AccX,AccY,AccZ" + (",T" if temperature else "")
    fmt = "f" * (7 if temperature else 6)
    out = bytearray(_df_fmt(DF_FMT, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns"))
    out += _df_fmt(64, "PARM", "QNf", "TimeUS,Name,Value")
    if numbered:
        for k, name in enumerate(("IMU", "IMU2", "IMU3")):
            out += _df_fmt(65 + k, name, "Q" + fmt, "TimeUS," + cols)
    else:
        out += _df_fmt(65, "IMU", "QB" + fmt, "TimeUS,I," + cols)
    for name, value in (params or {}).items():
        out += DF_HEAD + struct.pack("<BQ16sf", 64, 0, name.encode(), float(value))
    imus = [] if imu is None else imu if isinstance(imu, list) else [imu]
    rows = []
    for i, one in enumerate(imus, start=instance):
        for k in range(len(one["t_us"])):
            values = [*one["gyro"][k], *one["acc"][k]] + ([one["temperature"][k]] if temperature else [])
            head = struct.pack("<BQ", 65 + i, int(one["t_us"][k])) if numbered \
                else struct.pack("<BQB", 65, int(one["t_us"][k]), i)
            rows.append((int(one["t_us"][k]), i, DF_HEAD + head + struct.pack("<" + "f" * len(values), *values)))
    rows.sort(key=lambda r: (r[0], r[1]))
    out += b"".join(r[2] for r in rows)
    Path(path).write_bytes(bytes(out[:len(out) - truncate_bytes]))


def write_bag(path, t_s, acc_mps2, gyro_rads, topic="/imu", ros=1, msgtype="sensor_msgs/msg/Imu", frame_id=None):
    """A ROS 1 bag (ros=1) or a ROS 2 bag folder (ros=2, sqlite3) of sensor_msgs/Imu on `topic`, stamped
    t_s (the header's stamp, and the bag's time); msgtype another type to plant a wrong one; frame_id(k)
    message k's frame_id (default imu_link)."""
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    T = store.types
    has_seq = "seq" in T["std_msgs/msg/Header"].__dataclass_fields__
    if ros == 1:
        from rosbags.rosbag1 import Writer
        writer, serialize = Writer(Path(path)), store.serialize_ros1
    else:
        from rosbags.rosbag2 import Writer
        writer, serialize = Writer(Path(path), version=9), store.serialize_cdr
    with writer as w:
        con = w.add_connection(topic, msgtype, typestore=store)
        for k, t in enumerate(t_s):
            sec, nanosec = int(t // 1), int(round((t % 1) * 1e9))
            header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                              frame_id=frame_id(k) if frame_id else "imu_link",
                                              **({"seq": k} if has_seq else {}))
            if msgtype == "sensor_msgs/msg/Imu":
                v3 = T["geometry_msgs/msg/Vector3"]
                msg = T[msgtype](header=header,
                                 orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                                 orientation_covariance=np.zeros(9), angular_velocity=v3(*gyro_rads[k]),
                                 angular_velocity_covariance=np.zeros(9), linear_acceleration=v3(*acc_mps2[k]),
                                 linear_acceleration_covariance=np.zeros(9))
            else:  # a Temperature message where an Imu is expected
                msg = T[msgtype](header=header, temperature=25.0, variance=0.0)
            w.write(con, int(round(t * 1e9)), serialize(msg, msgtype))
