"""meta.json's keys as a type: MeasurementSet.meta (docs/spec/measurement-set.md)."""
from __future__ import annotations

from typing import TypedDict

from simucal.io.records import JSONObject, SensorUnits


class FullScale(TypedDict, total=False):
    acc: list[float]                  # [lo, hi] in acc_unit
    gyro: list[float]


class Meta(SensorUnits, total=False):
    """meta.json of a measurement set (docs/spec/measurement-set.md: the keys and their units), with the
    extensions the spec allows (a serial number, the table's stated errors, an importer's record of its log)."""
    format: str
    latitude_deg: float
    gravity_mps2: float
    earth_rate_dph: float
    full_scale: FullScale
    acc_noise_g: float
    gyro_noise_dph: float
    average_s: float                  # the averaging of averaged rows, s
    description: str
    table_tilt_arcsec: float          # the table's stated outer-axis tilt and angle accuracy
    table_accuracy_arcsec: float
    acc_offset_counts: list[float] | float  # a digital sensor's register value at zero input
    gyro_offset_counts: list[float] | float
    log: JSONObject                   # an importer's record of the log it read (file, topics, clock, ...)
    warnings: list[str]


def log_imu(meta: Meta) -> tuple | None:
    """(instance, acc device id, gyro device id) of a set imported from an autopilot's log (meta.json's
    `log`), which tells one IMU of a log from another; None for a set from elsewhere."""
    log = meta.get("log")
    if not isinstance(log, dict):
        return None
    return log.get("instance"), log.get("acc_device_id"), log.get("gyro_device_id")
