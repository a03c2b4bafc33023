"""PX4's ULog (pyulog) as one IMU stream: which topic holds the IMU, how each is read, and the site's
latitude from the log's GPS.

PX4 logs the IMU in one or more of these topics, by its logging profile (SDLOG_PROFILE):
- `sensor_combined` (every profile; the default profile's only full-rate IMU topic): the primary IMU that
  PX4's voter chose (sensor_selection names its device ids), one message per gyro sample. `timestamp`
  (us) is the gyro's sample time and `gyro_rad` its mean rate (rad/s) over `gyro_integral_dt` (us; seconds,
  as a float, in logs before 2019); `accelerometer_m_s2` is the mean specific force over
  `accelerometer_integral_dt`, sampled at timestamp + `accelerometer_timestamp_relative` (2147483647,
  RELATIVE_TIMESTAMP_INVALID: the accelerometer did not update, and the row is left out). Each message is
  one row, read as logged.
- `sensor_accel` / `sensor_gyro` (per instance, the topic's multi_id): each sensor at its own stamps
  (timestamp_sample), put on one clock by log_stream.on_one_clock; 1 Hz in the default profile, full rate in the
  high-rate and thermal-calibration ones.
- `vehicle_imu` (per instance): `delta_angle` over `delta_angle_dt` and `delta_velocity` over
  `delta_velocity_dt` (us), read as their means, rad/s and m/s^2, at timestamp_sample.
- `sensor_accel_fifo` / `sensor_gyro_fifo` (PX4 v1.12+, per instance; the high-rate profiles): each message
  one read of the sensor's FIFO, `samples` (at most the length of its arrays, 32) readings `x[]`, `y[]`, `z[]`
  in integer counts, times `scale` (m/s^2 or rad/s a count), `dt` (us) apart; `timestamp_sample` is the
  newest reading's (the drivers stamp the FIFO's read), so reading k of N is at timestamp_sample - (N-1-k) dt.
  Every reading is a row (sensor_accel and sensor_gyro are each message's mean). The FIFO has no
  temperature: it is sensor_accel's of the same device id, interpolated. `sensor_imu_fifo` (one topic of
  both, `accel_x[]` ... with accel_scale and gyro_scale, and a temperature; a few PX4 versions) likewise.
  A FIFO topic whose samples exceed its arrays, or whose dt or scale is not positive, is no source: the
  warning (or, where nothing else holds the IMU, the refusal) names it.
Where a log holds several, the source whose slower sensor has the highest rate is read, and the log block
lists every source found with its rate and says why this one. With an instance asked for, only that
instance's topics qualify (sensor_combined follows the voter, not an instance). A source under 10 Hz is
read but named as such (LOW_RATE_HZ).

The latitude: the median of the GPS fixes (vehicle_gps_position or sensor_gps, fix_type 3 or more) where the
log holds some.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np

from simucal.io.importers import ImportError_
from simucal.io.log_stream import LogStream, need, on_one_clock, other_format

LOW_RATE_HZ = 10.0  # under this a source is named as such: the IMU's noise is averaged away, its bandwidth lost
RELATIVE_TIMESTAMP_INVALID = 2147483647
TOPICS = ["sensor_combined", "sensor_accel", "sensor_gyro", "vehicle_imu", "sensor_accel_fifo", "sensor_gyro_fifo",
          "sensor_imu_fifo", "sensor_selection", "vehicle_gps_position", "sensor_gps"]
FRAME = "FRD (PX4's body frame, after the board's rotation)"
# sensor_combined and vehicle_imu are VehicleIMU's output: PX4's calibration already applied
CORRECTED = ("PX4's own calibration already applied (offsets, scale factors and, where TC_*_ENABLE, its thermal "
             "compensation): what is left of the unit's errors, not the raw sensor")


@dataclass
class Source:
    """One topic (or pair of topics) of the log that holds both sensors."""
    name: str          # e.g. "sensor_combined" or "sensor_accel+sensor_gyro instance 1"
    instance: int | None
    rate_hz: float     # its slower sensor's
    samples: int
    read: Callable[[], LogStream]
    fault: str | None = None  # a FIFO topic that breaks its definition: listed, never read


def read_ulog(path, instance: int | None = None) -> LogStream:
    """The IMU of a ULog from its best source (module doc); `instance` None: any source, sensor_combined
    included; else that instance's sensor_accel/sensor_gyro or vehicle_imu."""
    path = Path(path)
    return _best(path, *_parsed(path), instance)


def read_ulog_instances(path, instances: list[int] | None = None) -> list[LogStream]:
    """Each instance's IMU from its best source, the log parsed once; `instances` None: every instance that
    holds both sensors (sensor_combined, which follows PX4's voter, is no instance)."""
    path = Path(path)
    data, warnings = _parsed(path)
    held = sorted({s.instance for s in _usable(_sources(data, path), path, []) if s.instance is not None})
    if not held and ("sensor_combined", 0) in data:
        raise ImportError_(f"{path}: no instance holds both sensors (sensor_accel with sensor_gyro, or vehicle_imu); "
                           "the log has sensor_combined, PX4's primary IMU: import it without --instance, or log "
                           "the IMU per instance (SDLOG_PROFILE)")
    if not held:
        raise ImportError_(f"{path}: {_missing(data, None)}")
    for i in instances or []:
        if i not in held:
            raise ImportError_(f"{path}: {_missing(data, i)}")
    return [_best(path, data, list(warnings), i) for i in (instances or held)]


def _parsed(path: Path) -> tuple[dict, list[str]]:
    """{(topic, multi_id): its columns} of the topics read, and the warnings of a cut end."""
    pyulog = need("pyulog", "ULog", path)
    warnings = whole_ulog(path)
    try:
        ulog = pyulog.ULog(str(path), TOPICS)
    except Exception as e:  # pyulog raises bare Exceptions on a foreign or broken file
        raise ImportError_(f"{path}: not a ULog pyulog can read ({e})") from None
    return {(d.name, d.multi_id): d.data for d in ulog.data_list}, warnings


def _best(path: Path, data: dict, warnings: list[str], instance: int | None) -> LogStream:
    listed = [s for s in _sources(data, path) if instance is None or s.instance == instance]
    sources = _usable(listed, path, warnings)
    if not sources:
        raise ImportError_(f"{path}: {_missing(data, instance)}")
    best = max(sources, key=lambda s: (s.rate_hz, s.samples))
    stream = best.read()
    if best.name.startswith(("sensor_combined", "vehicle_imu")):
        stream.log["corrected"] = CORRECTED
    stream.log.update({"format": "ulog", "file": path.name, "sensor_frame": FRAME, "source": best.name,
                       "sources": [{"name": s.name, "rate_hz": round(s.rate_hz, 3), "samples": s.samples}
                                   for s in sources],
                       "why": "the highest rate of the sources that hold both sensors" if len(sources) > 1
                       else "the only source that holds both sensors"})
    if best.rate_hz < LOW_RATE_HZ:
        warnings.append(f"{path}: the IMU is read from {best.name} at {best.rate_hz:.3g} Hz, under {LOW_RATE_HZ:g} Hz "
                        f"(the fastest of {len(sources)} source{'s' * (len(sources) > 1)}): "
                        "enough for a warm-up's slow curve, not for noise or motion, which need the full rate "
                        "(PX4's high-rate logging)")
    latitude = gps_latitude(data)
    if latitude is not None:
        stream.log["gps_latitude_deg"] = latitude
    stream.warnings += warnings
    return stream


def _usable(sources: list[Source], path, warnings: list[str]) -> list[Source]:
    """The sources that can be read; a faulty FIFO topic is named in a warning, or refused where it is the
    only source."""
    faulty = [s for s in sources if s.fault is not None]
    usable = [s for s in sources if s.fault is None]
    if faulty and not usable:
        raise ImportError_(f"{path}: {faulty[0].fault}: the log holds no other IMU source; log it again, or "
                           "import a log whose FIFO topics keep PX4's definition")
    warnings += [f"{path}: {s.fault}: it is left out, and the IMU read from the next source" for s in faulty]
    return usable


def _sources(data, path) -> list[Source]:
    out = []
    combined = data.get(("sensor_combined", 0))
    if combined is not None and "gyro_rad[0]" in combined and len(combined["timestamp"]) > 1:
        out.append(Source("sensor_combined", None, _rate(combined["timestamp"]), len(combined["timestamp"]),
                          partial(_combined, combined, data.get(("sensor_selection", 0)), data, path)))
    for (name, i), d in sorted(data.items()):
        if name == "sensor_accel" and ("sensor_gyro", i) in data:
            g = data[("sensor_gyro", i)]
            if len(d["timestamp"]) > 1 and len(g["timestamp"]) > 1:
                out.append(Source(f"sensor_accel+sensor_gyro instance {i}", i,
                                  min(_rate(_stamps(d)), _rate(_stamps(g))),
                                  min(len(d["timestamp"]), len(g["timestamp"])), partial(_pair, d, g, i, path)))
        if name == "vehicle_imu" and len(d["timestamp"]) > 1:
            out.append(Source(f"vehicle_imu instance {i}", i, _rate(_stamps(d)), len(d["timestamp"]),
                              partial(_vehicle_imu, d, i, data, path)))
        if name == "sensor_accel_fifo" and ("sensor_gyro_fifo", i) in data:
            g = data[("sensor_gyro_fifo", i)]
            out.append(_fifo_source("sensor_accel_fifo+sensor_gyro_fifo", ((name, d, ""), ("sensor_gyro_fifo", g, "")),
                                    i, data, path))
        if name == "sensor_imu_fifo":
            out.append(_fifo_source(name, ((name, d, "accel_"), (name, d, "gyro_")), i, data, path))
    return out


def _missing(data, instance) -> str:
    """What the log lacks, and the fix, where no source holds both sensors."""
    has = lambda topic: sorted(i for n, i in data if n == topic)  # noqa: E731
    acc, gyro, vimu = has("sensor_accel"), has("sensor_gyro"), has("vehicle_imu")
    both = sorted(set(acc) & set(gyro) | set(vimu))
    if instance is not None and both:
        return f"no IMU source of instance {instance} (the log's instances with both sensors: " \
               f"{', '.join(map(str, both))}): give --instance {both[0]}, or leave --instance out"
    found = "; ".join(f"{t}: instances {', '.join(map(str, i))}" for t, i in
                      (("sensor_accel", acc), ("sensor_gyro", gyro), ("sensor_accel_fifo", has("sensor_accel_fifo")),
                       ("sensor_gyro_fifo", has("sensor_gyro_fifo"))) if i) or "no IMU topic"
    return (f"no topic holds both sensors (sensor_combined, sensor_accel with sensor_gyro of one instance, or "
            f"vehicle_imu, sensor_accel_fifo with sensor_gyro_fifo; it has {found}): log the IMU (SDLOG_PROFILE)")


def _rate(t_us) -> float:
    return 1e6 / float(np.median(np.diff(np.asarray(t_us, float))))


def _stamps(d) -> np.ndarray:
    return np.asarray(d.get("timestamp_sample", d["timestamp"]), float)


def _xyz(d, name=None) -> np.ndarray:
    """(n, 3) of a vector field (`name[0]` ...), or of the fields x, y, z where name is None."""
    return np.column_stack([d[f"{name}[{j}]" if name else "xyz"[j]] for j in range(3)]).astype(float)


def _device_id(d, key="device_id") -> int | None:
    return int(np.median(d[key])) if d is not None and key in d and len(d[key]) else None


def _combined(d, selection, data, path) -> LogStream:
    """sensor_combined: one row a message, where the accelerometer updated (module doc)."""
    t_us = np.asarray(d["timestamp"], float)
    relative = np.asarray(d["accelerometer_timestamp_relative"], np.int64)
    valid = relative != RELATIVE_TIMESTAMP_INVALID
    dt = np.asarray(d["gyro_integral_dt"])
    dt_unit = "s" if dt.dtype.kind == "f" else "us"  # PX4 logged it as float seconds before 2019
    acc_id, gyro_id = _device_id(selection, "accel_device_id"), _device_id(selection, "gyro_device_id")
    log = {"instance": None, "topics": ["sensor_combined"] + (["sensor_selection"] if selection is not None else []),
           "clock": {"rows": "sensor_combined's messages at their timestamp, the gyro's sample time "
                             f"({_rate(t_us):.4g} Hz)",
                     "gyro": f"gyro_rad, its mean rate over gyro_integral_dt ({dt_unit})",
                     "acc": "accelerometer_m_s2, its mean over accelerometer_integral_dt, at timestamp + "
                            "accelerometer_timestamp_relative (largest |relative| "
                            f"{int(np.max(np.abs(relative[valid]), initial=0))} us)",
                     "intervals_without_a_sample": {"rows_left_out": int((~valid).sum())}},
           "acc_device_id": acc_id, "gyro_device_id": gyro_id,
           "primary": "the IMU PX4's voter chose (sensor_selection's device ids)"}
    warnings = []
    if selection is not None and any(len(np.unique(selection[k])) > 1 for k in ("accel_device_id", "gyro_device_id")):
        warnings.append(f"{path}: PX4's voter changed the primary IMU during the log (sensor_selection), so "
                        "sensor_combined's rows come from more than one sensor: log the IMU per instance "
                        "(sensor_accel, sensor_gyro) and give --instance")
    t_s = t_us[valid] * 1e-6
    temp, how = _temperature_of(acc_id, t_s, data)
    log["temperature"] = how
    return LogStream(t_s, _xyz(d, "accelerometer_m_s2")[valid], _xyz(d, "gyro_rad")[valid], temp, log, warnings)


def _temperature_of(acc_device_id, t_s, data) -> tuple[np.ndarray | None, str | None]:
    """The temperature of sensor_combined's accelerometer: the sensor_accel instance of its device id,
    interpolated onto the rows where its samples span them (to within two of its periods)."""
    for (name, i), a in sorted(data.items()):
        if name != "sensor_accel" or acc_device_id is None or _device_id(a) != acc_device_id or "temperature" not in a:
            continue
        t_a, temp = _stamps(a) * 1e-6, np.asarray(a["temperature"], float)
        ok = np.isfinite(temp)
        if ok.sum() < 2:
            return None, None
        margin = 2 / (_rate(t_a * 1e6))
        if t_a[ok][0] - margin <= t_s[0] and t_s[-1] <= t_a[ok][-1] + margin:
            return (np.interp(t_s, t_a[ok], temp[ok]),
                    f"sensor_accel instance {i}'s (the same device id), {_rate(t_a * 1e6):.3g} Hz, interpolated")
    return None, None


def _pair(a, g, instance, path) -> LogStream:
    """sensor_accel and sensor_gyro of one instance on one clock (log_stream.on_one_clock)."""
    temp_a = np.asarray(a["temperature"], float) if "temperature" in a else None
    t, acc, gyro, temp, clock = on_one_clock(_stamps(a) * 1e-6, _xyz(a), temp_a, _stamps(g) * 1e-6,
                                             _xyz(g), path)
    return LogStream(t, acc, gyro, temp, {"instance": instance, "topics": ["sensor_accel", "sensor_gyro"],
                                          "clock": clock, "acc_device_id": _device_id(a),
                                          "gyro_device_id": _device_id(g),
                                          "temperature": "sensor_accel's" if temp is not None else None})


def _vehicle_imu(d, instance, data, path) -> LogStream:
    """vehicle_imu: each delta over its own integration time (module doc)."""
    t_s = _stamps(d) * 1e-6
    dt_a, dt_v = (np.asarray(d[k], float) * 1e-6 for k in ("delta_angle_dt", "delta_velocity_dt"))
    valid = (dt_a > 0) & (dt_v > 0)
    acc_id = _device_id(d, "accel_device_id")
    temp, how = _temperature_of(acc_id, t_s[valid], data)
    log = {"instance": instance, "topics": ["vehicle_imu"], "acc_device_id": acc_id,
           "gyro_device_id": _device_id(d, "gyro_device_id"), "temperature": how,
           "clock": {"rows": f"vehicle_imu's messages at timestamp_sample ({_rate(t_s * 1e6):.4g} Hz)",
                     "gyro": "delta_angle / delta_angle_dt", "acc": "delta_velocity / delta_velocity_dt",
                     "intervals_without_a_sample": {"rows_left_out": int((~valid).sum())}}}
    return LogStream(t_s[valid], _xyz(d, "delta_velocity")[valid] / dt_v[valid, None],
                     _xyz(d, "delta_angle")[valid] / dt_a[valid, None], temp, log)


def _fifo_source(name: str, sensors, multi_id: int, data, path) -> Source:
    """A FIFO source: sensors ((topic, columns, field prefix) of the accelerometer, then the gyro's); its
    instance the sensor_accel instance of the accelerometer's device id (the FIFO topics' multi_ids follow
    their first publication), else the topic's own."""
    faults = [_fifo_fault(d, topic, multi_id, prefix) for topic, d, prefix in sensors]
    acc_id = _device_id(sensors[0][1])
    same = [i for (n, i), a in sorted(data.items()) if n == "sensor_accel" and _device_id(a) == acc_id]
    instance = same[0] if same and acc_id is not None else multi_id
    held = [np.asarray(d["samples"], np.int64) > 0 for _, d, _ in sensors] if not any(faults) else []
    rate = min(1e6 / float(np.median(np.asarray(d["dt"], float)[h])) for (_, d, _), h in zip(sensors, held)) \
        if held and all(h.sum() > 1 for h in held) else 0.0
    count = min(int(np.sum(d["samples"])) for _, d, _ in sensors) if rate else 0
    return Source(f"{name} instance {instance}", instance, rate, count,
                  partial(_fifo_pair, sensors, instance, data, path),
                  next((f for f in faults if f), None) or (None if rate else f"{name} instance {multi_id}: "
                                                           "fewer than two messages hold samples"))


def _fifo_fault(d, topic: str, multi_id: int, prefix: str) -> str | None:
    """What breaks PX4's definition of a FIFO topic's messages (samples within its arrays, dt and scale
    positive), or None."""
    scale = f"{prefix}scale" if prefix else "scale"
    lacks = [k for k in ("timestamp_sample", "dt", "samples", scale, f"{prefix}x[0]") if k not in d]
    if lacks:
        return f"{topic} instance {multi_id} lacks the field {lacks[0]} of PX4's definition"
    width, n = _fifo_width(d, prefix), np.asarray(d["samples"], np.int64)
    held = n > 0
    for bad, what in ((n > width, lambda k: f"samples {n[k]}, more than the {width} its {prefix}x[] holds"),
                      (held & ~(np.asarray(d["dt"], float) > 0), lambda k: f"dt {d['dt'][k]:g} us, not a positive "
                                                                         "interval between samples"),
                      (held & ~(np.asarray(d[scale], float) > 0), lambda k: f"{scale} {d[scale][k]:g}, not a "
                                                                           "positive unit a count")):
        if bad.any():
            k = int(np.argmax(bad))
            return f"{topic} instance {multi_id}, message {k} (of {len(n)}): {what(k)}"
    return None


def _fifo_width(d, prefix: str) -> int:
    """The length of a FIFO topic's arrays (32 in sensor_accel_fifo, 24 in sensor_imu_fifo)."""
    return sum(1 for k in d if k.startswith(f"{prefix}x["))


def fifo_samples(d, prefix: str = "") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_us, (n, 3) readings in m/s^2 or rad/s, each reading's message) of a FIFO topic, every message
    unpacked (module doc): reading k of N at timestamp_sample - (N-1-k) dt, its counts times the scale."""
    n = np.asarray(d["samples"], np.int64)
    k = np.arange(_fifo_width(d, prefix))
    held = k[None, :] < n[:, None]
    t_us = (np.asarray(d["timestamp_sample"], float)[:, None]
            - (n[:, None] - 1 - k) * np.asarray(d["dt"], float)[:, None])
    counts = np.stack([np.column_stack([d[f"{prefix}{axis}[{j}]"] for j in k]) for axis in "xyz"], axis=-1)
    scale = np.asarray(d[f"{prefix}scale" if prefix else "scale"], float)[:, None, None]
    message = np.broadcast_to(np.arange(len(n))[:, None], held.shape)
    return t_us[held], (counts * scale)[held], message[held]


def _fifo_pair(sensors, instance, data, path) -> LogStream:
    """A FIFO source's readings, the two sensors on one clock (log_stream.on_one_clock: where both read one
    FIFO, at the same stamps, each row is one reading of each)."""
    (topic_a, a, pa), (topic_g, g, pg) = sensors
    (t_a, acc, msg_a), (t_g, gyro, _) = fifo_samples(a, pa), fifo_samples(g, pg)
    names = (topic_a, topic_g) if topic_a != topic_g else (f"{topic_a} (accel_)", f"{topic_g} (gyro_)")
    temp_a = np.asarray(a["temperature"], float)[msg_a] if "temperature" in a else None
    t, acc_rows, gyro_rows, temp, clock = on_one_clock(t_a * 1e-6, acc, temp_a, t_g * 1e-6, gyro, path, names)
    acc_id = _device_id(a)
    how = f"{topic_a}'s" if temp is not None else None
    if temp is None:
        temp, how = _temperature_of(acc_id, t, data)
    clock["fifo"] = "every reading of each message, reading k of N at timestamp_sample - (N-1-k) dt"
    warnings = [f"{path}: {topic} holds PX4's rotation field (PX4 before v1.12): its readings are in the sensor's "
                "own frame, before the board's rotation" for topic, d, _ in sensors[:1 + (topic_a != topic_g)]
                if "rotation" in d and np.any(np.asarray(d["rotation"]) != 0)]
    return LogStream(t, acc_rows, gyro_rows, temp, {
        "instance": instance, "topics": list(dict.fromkeys([topic_a, topic_g])), "clock": clock,
        "acc_device_id": acc_id, "gyro_device_id": _device_id(g), "temperature": how}, warnings)


def gps_latitude(data) -> float | None:
    """The median latitude (deg) of the log's 3D GPS fixes, or None."""
    for topic in ("vehicle_gps_position", "sensor_gps"):
        d = data.get((topic, 0))
        if d is None:
            continue
        lat = (np.asarray(d["latitude_deg"], float) if "latitude_deg" in d
               else np.asarray(d["lat"], float) * 1e-7 if "lat" in d else None)
        if lat is None:
            continue
        fix = np.asarray(d["fix_type"]) >= 3 if "fix_type" in d else np.ones(len(lat), bool)
        good = fix & np.isfinite(lat) & (np.abs(lat) <= 90) & (lat != 0)
        if good.any():
            return round(float(np.median(lat[good])), 6)
    return None


def whole_ulog(path: Path) -> list[str]:
    """A ULog's whole messages: after its 16-byte header every message is a uint16 size and a uint8 type.
    A file cut inside its last message (power pulled, a copy stopped) keeps every whole message before the
    cut, and the warning says where and how much was cut (pyulog drops the cut message without a word)."""
    data = path.read_bytes()
    if data[:7] != b"ULog\x01\x12\x35":
        raise ImportError_(f"{path}: not a ULog (its first bytes are not ULog's magic){other_format(data)}")
    pos, last, n = 16, 16, len(data)
    while pos + 3 <= n:
        last, pos = pos, pos + 3 + data[pos] + 256 * data[pos + 1]
    if pos == n:
        return []
    pos = last if pos > n else pos  # the start of the message the file ends inside
    return [f"{path}: the log is cut inside its last message: every message up to byte {pos:,} is read, the "
            f"last {n - pos:,} bytes (a message the file ends inside) are left out"]

