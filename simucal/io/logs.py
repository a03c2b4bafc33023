"""The logs most MEMS users have, read into one stream (a measurement set without segments.csv): PX4's
ULog (io/ulog.py, pyulog), ArduPilot's DataFlash .bin (io/dataflash.py, pymavlink), ROS 1 and ROS 2 bags of
sensor_msgs/Imu (io/rosbag.py, rosbags). Each reader is its format's own library, an optional dependency:
`pip install 'simucal[logs]'`.

The outputs stay as logged: m/s^2 and rad/s, in the log's sensor frame (PX4 and ArduPilot: FRD, the body
frame after the board's rotation; ROS: the message's frame_id, FLU by REP 103), with temp_c where the log
has it. meta.json's `log` block says the file, the source (topic, instance), the frame, each sensor's device
id and how the two sensors were put on one clock (io/log_stream.py).

What a set may not hold is refused at import, in one line naming the file: NaN samples (the spec has none),
two sensors that never overlap, a log that is not of its format. What a user must know is kept and said
(meta.json's `warnings`, and the command's WARNING lines): a log cut inside its last message, gaps in
the rows (io/timestamps.gaps: where and how long), a source under 10 Hz, a "still" magnitude far from g (a wrong unit?).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, cast

import numpy as np

from simucal import io
from simucal.io import timestamps
from simucal.io.dataflash import read_dataflash, read_dataflash_instances
from simucal.io.importers import ImportError_, import_meta
from simucal.io.log_stream import LogStream
from simucal.io.meta import Meta
from simucal.io.rosbag import read_rosbag
from simucal.io.ulog import read_ulog, read_ulog_instances

G_MPS2 = 9.80665
MAGNITUDE_OFF = 0.2  # a median |f| more than this fraction away from g is named (m/s^2 assumed)

READERS: dict[str, Callable[..., LogStream]] = {"ulog": read_ulog, "dataflash": read_dataflash}
# every instance of one log, parsed once (a ROS bag's Imu topics are no instances)
INSTANCE_READERS: dict[str, Callable[..., list[LogStream]]] = {"ulog": read_ulog_instances,
                                                               "dataflash": read_dataflash_instances}


def read_log(fmt: str, path, instance: int | None = None, topic: str | None = None) -> LogStream:
    """The log at path in format fmt (ulog, dataflash or rosbag), checked (module doc)."""
    stream = read_rosbag(path, topic) if fmt == "rosbag" else READERS[fmt](path, instance)
    return checked(stream, Path(path))


def checked(s: LogStream, path: Path) -> LogStream:
    """The stream refused where a sensor holds NaN; a temperature with NaN dropped, and it, the gaps and an
    implausible magnitude added to its warnings."""
    if s.temp_c is not None and not np.all(np.isfinite(s.temp_c)):
        # a driver without a temperature logs NaN, and one logs it until its first reading: no column rather
        # than a broken one, said where some rows had one
        if np.any(np.isfinite(s.temp_c)):
            s.warnings.append(f"{path}: {int((~np.isfinite(s.temp_c)).sum()):,} of {len(s.temp_c):,} temperature "
                              "samples are NaN: the set has no temp_c column (a thermal calibration needs one on "
                              "every row)")
        s.temp_c = None
        s.log["temperature"] = None
    for name, x in (("accelerometer", s.acc_mps2), ("gyro", s.gyro_rads)):
        bad = ~np.isfinite(x).all(axis=1)
        if bad.any():
            first = int(np.argmax(bad))
            raise ImportError_(f"{path}: {int(bad.sum()):,} {name} samples are NaN or infinite (the first at "
                               f"{s.t_s[first]:.3f} s of the log, row {first + 1:,}); a measurement set holds none: "
                               "cut the log where its sensor failed, or log again")
    found = timestamps.gaps(s.t_s - s.t_s[0])
    if found:
        s.log["gaps"] = found
        s.warnings.append(f"{path}: {timestamps.gap_text(found)}: a calibration sees no motion there; meta.json's "
                          "log.gaps lists each")
    magnitude = float(np.median(np.linalg.norm(s.acc_mps2, axis=1))) if len(s.acc_mps2) else G_MPS2
    if abs(magnitude / G_MPS2 - 1) > MAGNITUDE_OFF:
        s.warnings.append(f"{path}: the accelerometer's median magnitude is {magnitude:.4g} m/s^2 "
                          f"({magnitude / G_MPS2:.3g} g), not near g (9.81 m/s^2): are the samples in m/s^2?")
    return s


def import_log(fmt: str, path, out, latitude_deg, instance: int | None = None, topic: str | None = None) -> Meta:
    """`simucal import ulog|dataflash|rosbag FILE -o SET`: the log as a stream (module doc); its meta, whose
    `warnings` the command prints."""
    return cast(Meta, dict(_write(read_log(fmt, path, instance, topic), fmt, Path(path), out, latitude_deg).meta))


def instance_folder(out, instance: int) -> Path:
    """The set of one instance in `import --instance all -o OUT`."""
    return Path(out) / f"instance{instance}"


def import_instances(fmt: str, path, out, latitude_deg, instances: list[int] | None = None,
                     force: bool = False) -> list[io.MeasurementSet]:
    """`simucal import ulog|dataflash FILE --instance all|0,1 -o OUT`: one set per instance (None: every
    instance that holds both sensors), OUT/instance<n>, the log parsed once; the sets as written (in memory:
    their files are renamed into place when the command ends)."""
    from simucal.io import outputs
    if fmt not in INSTANCE_READERS:
        raise ImportError_(f"{path}: --instance reads an autopilot's log (ulog, dataflash); a {fmt} has topics "
                           "(--topic)")
    streams = [checked(s, Path(path)) for s in INSTANCE_READERS[fmt](path, instances)]
    folders = [instance_folder(out, s.log["instance"]) for s in streams]
    outputs.check([path], sets=folders, force=force)
    return [_write(s, fmt, Path(path), f, latitude_deg) for s, f in zip(streams, folders)]


def _write(s: LogStream, fmt: str, path: Path, out, latitude_deg) -> io.MeasurementSet:
    """The stream written as a set at `out`; the set."""
    if latitude_deg is None and s.log.get("gps_latitude_deg") is not None:
        latitude_deg = s.log["gps_latitude_deg"]
        s.log["latitude"] = "the log's GPS fixes (their median)"
    source = s.log.get("topic") or s.log.get("source") or f"instance {s.log.get('instance')}"
    extra: dict = {"log": s.log, "description": f"imported from {path.name} ({fmt}): {source}"}
    if s.warnings:
        extra["warnings"] = list(s.warnings)
    meta = import_meta("m/s^2", "rad/s", latitude_deg, extra)
    samples = {"t_s": s.t_s - s.t_s[0], "ax": s.acc_mps2[:, 0], "ay": s.acc_mps2[:, 1], "az": s.acc_mps2[:, 2],
               "gx": s.gyro_rads[:, 0], "gy": s.gyro_rads[:, 1], "gz": s.gyro_rads[:, 2]}
    s.log["t0_s"] = float(s.t_s[0])  # the log's own time of the first row (t_s counts from it)
    if s.temp_c is not None:
        samples["temp_c"] = s.temp_c
    io.write_set(out, meta, samples)
    return io.MeasurementSet(Path(out), {"format": io.FORMAT, **meta}, samples, None)


def bag_as_set(path, topic: str | None = None):
    """A ROS bag's Imu topic as a measurement set in memory (`simucal noise BAG`): the samples as
    `import rosbag` writes them. The latitude a bag does not hold is set to 0 and said: the Allan
    variance takes out each stretch's mean, and with it the Earth rate."""
    s = read_log("rosbag", path, topic=topic)
    meta = {"latitude_deg": 0.0, "log": {**s.log, "t0_s": float(s.t_s[0])},
            **({"warnings": list(s.warnings)} if s.warnings else {}),
            "description": f"{Path(path).name}, topic {s.log['topic']} (latitude unknown, 0 here: the "
                           "Allan deviation does not use it)"}
    return io.MeasurementSet.from_arrays(s.acc_mps2, s.gyro_rads, acc_unit="m/s^2", gyro_unit="rad/s",
                                         t_s=s.t_s - s.t_s[0], meta=meta, name=str(path))
