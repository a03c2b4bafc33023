"""A thermal calibration's bias polynomials as an autopilot's thermal compensation: PX4's TC_A{n}_*/TC_G{n}_*
(a QGroundControl .params file) and ArduPilot's INS_TCAL{n+1}_* (a Mission Planner .param file), n the
log's instance of the IMU.

The narrow interface is `BiasPolynomial`: per sensor, per axis, the bias b(T) = sum_k c_k (T - T_ref)^k
in the autopilot's units (m/s^2, rad/s), with T_ref and the calibrated range, and the sensor's other
parameters that follow temperature (the autopilots correct an offset only). `bias_polynomials` builds
it from a calibration's `thermal` blocks; nothing else here reads the calibration.

The sign: simucal's model is output = M u + b(T) (io/calibration.py), so the offset an autopilot
subtracts from its raw reading is b(T) itself.

PX4 (src/modules/temperature_compensation/TemperatureCompensation.cpp,
`TemperatureCompensation::calc_thermal_offsets_3D`): dT = T - TREF with T clamped to [TMIN, TMAX],
offset_i = X0_i + X1_i dT + X2_i dT^2 + X3_i dT^3 (float32), m/s^2 and rad/s, subtracted from the raw
sensor_accel/sensor_gyro reading before the calibration's offset, scale and rotation to the body frame
(src/lib/sensor_calibration/Accelerometer.hpp, `Correct`: _rotation * ((data - _thermal_offset - _offset)
.emult(_scale))). So X_k = c_k with TREF = T_ref. PX4 applies a set only to the sensor whose device id is
TC_A{n}_ID / TC_G{n}_ID: the log's device ids where the data were imported from one, else the user sets them
(the file says so). The data must be the raw topics: a ULog's sensor_combined or vehicle_imu already has
PX4's calibration in it, and is refused.

ArduPilot (libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp, `TCal::correct_sensor` and
`TCal::polynomial_eval`): v -= P(T - 35) and v += P(T_cal - 35), T and T_cal (the temperature of the
ordinary calibration, INS_ACC1_CALTEMP / INS_GYR1_CALTEMP) clamped to [TMIN, TMAX], P(x) = (ACC1 x +
ACC2 x^2 + ACC3 x^3) * 1e-6 (SCALE_FACTOR), fixed reference TEMP_REFERENCE = 35 degC, applied after the
sensor's own orientation and before the offsets, scales and board orientation
(AP_InertialSensor_Backend.cpp, `_rotate_and_correct_accel`). So the polynomial is re-expanded about
35 degC and its constant dropped: ArduPilot corrects b(T) - b(T_cal), the ordinary calibration holds b(T_cal).

Frame: the export assumes the data's sensor axes are the autopilot's sensor axes (PX4's sensor_accel and
sensor_gyro, ArduPilot's IMU after its sensor orientation), i.e. the data were recorded from the
autopilot's own topics; the autopilot rotates to its body frame (FRD) after the correction.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple
from math import comb

import numpy as np

from simucal.errors import CalibrationError
from simucal.io import meta as meta_keys
from simucal.io import units

BIAS = ("b_x", "b_y", "b_z")
MAX_DEGREE = 3  # both autopilots: a cubic
SI_UNIT = {"acc": "m/s^2", "gyro": "rad/s"}
ARDUPILOT_T_REF_C = 35.0     # AP_InertialSensor_tempcal.cpp, TEMP_REFERENCE
ARDUPILOT_SCALE = 1.0e6      # AP_InertialSensor_tempcal.cpp, SCALE_FACTOR
PX4_REAL32, PX4_INT32 = 9, 6  # MAV_PARAM_TYPE of a QGroundControl .params line
PX4_SLOTS, ARDUPILOT_SLOTS = 4, 3  # TC_A0..TC_A3 (temperature_compensation's params); INS_TCAL1..3


@dataclass(frozen=True)
class BiasPolynomial:
    """One sensor's bias over temperature in the autopilot's units: coefficients[i, k] of (T - t_ref_c)^k on
    axis i (x, y, z), in m/s^2 (acc) or rad/s (gyro) per degC^k; the calibrated range; `others`: the
    sensor's other parameters that follow temperature, each 'name (change over the range)'."""
    sensor: str
    coefficients: np.ndarray
    t_ref_c: float
    t_min_c: float
    t_max_c: float
    others: tuple[str, ...] = ()


def gravity_mps2(meta: meta_keys.Meta) -> float:
    """The m/s^2 of simucal's g: meta.json's gravity for data in m/s^2 (they were divided by it), else the
    standard 9.80665 m/s^2 by which the autopilots' drivers turn a g into m/s^2."""
    return units.gravity(meta) if meta.get("acc_unit") == "m/s^2" else units.DEFAULT_GRAVITY


def _change(coefficients, t_ref_c, lo, hi) -> float:
    """Peak-to-peak change of a polynomial over [lo, hi]."""
    return float(np.ptp(np.polynomial.polynomial.polyval(np.linspace(lo, hi, 201) - t_ref_c, coefficients)))


def _unit(unit: str) -> str:
    return "" if unit == "1" else f" {unit}"


def bias_polynomials(cal, g_mps2: float) -> list[BiasPolynomial]:
    """The narrow interface from a thermal calibration (its blocks' `thermal`: t_ref_c and per parameter
    `coefficients` in (T - T_ref), the parameter's unit per degC^k; the block's own temperature_range_c, its
    rows', else the file's: TMIN/TMAX per sensor).
    Refused in one line: no thermal block, a bias not named b_x, b_y, b_z or not in g / deg/h."""
    out = []
    for sensor, block in cal.blocks():
        if not block.thermal:
            raise CalibrationError(f"{sensor}: no temperature polynomials (a calibration of one temperature): "
                                   "an autopilot's thermal compensation needs calibrate --thermal")
        fits, t_ref = block.thermal["parameters"], float(block.thermal["t_ref_c"])
        missing = [b for b in BIAS if b not in fits]
        if missing:
            raise CalibrationError(f"{sensor}: the model has no bias parameter {missing[0]} (has {list(fits)}): the "
                                   "export reads the bias as b_x, b_y, b_z")
        unit = block.param_units.get("b_x", block.bias_unit)
        if unit not in ("g", "deg/h"):
            raise CalibrationError(f"{sensor}: bias in {unit!r}; the export converts g or deg/h only")
        per = g_mps2 if unit == "g" else units.RAD_S_PER_DPH
        width = max(len(fits[b]["coefficients"]) for b in BIAS)
        coefficients = np.zeros((3, width))
        for i, b in enumerate(BIAS):
            c = np.asarray(fits[b]["coefficients"], float)
            coefficients[i, :len(c)] = c * per
        lo, hi = (float(t) for t in block.thermal.get("temperature_range_c") or cal.temperature_range_c)  # the sensor's
        others = tuple(f"{sensor} {n} (changes by {_change(f['coefficients'], t_ref, lo, hi):.3g}"
                       f"{_unit(block.param_units.get(n, '1'))} from {lo:g} to {hi:g} degC)"
                       for n, f in fits.items() if n not in BIAS and any(f["coefficients"][1:]))
        out.append(BiasPolynomial(sensor, coefficients, t_ref, lo, hi, others))
    return out


def about(coefficients: np.ndarray, shift_c: float) -> np.ndarray:
    """The same polynomials in (T - T_new), shift_c = T_new - T_ref: c'_j = sum_k c_k C(k, j) shift^(k-j)."""
    c = np.asarray(coefficients, float)
    d = c.shape[-1]
    B = np.array([[comb(k, j) * shift_c ** (k - j) if k >= j else 0.0 for k in range(d)] for j in range(d)])
    return c @ B.T


def _checked(polys: list[BiasPolynomial], autopilot: str) -> list[str]:
    """Refuse a bias of degree above 3 (naming it); the warnings for what the autopilot cannot express."""
    for p in polys:
        for i, c in enumerate(p.coefficients):
            if np.any(c[MAX_DEGREE + 1:]):
                raise CalibrationError(f"{p.sensor} {BIAS[i]}: a polynomial of degree {np.flatnonzero(c)[-1]} in "
                                       f"temperature; {autopilot} takes degree {MAX_DEGREE} at most: calibrate "
                                       f"with --thermal-degree {MAX_DEGREE}")
    return [f"{autopilot} corrects the bias only, not {o}" for p in polys for o in p.others]


def _cubic(p: BiasPolynomial) -> np.ndarray:
    """(3, 4): the coefficients of degree 0..3 (a lower degree padded with zeros)."""
    c = np.zeros((3, 4))
    n = min(p.coefficients.shape[1], 4)
    c[:, :n] = p.coefficients[:, :n]
    return c


def px4_parameters(polys: list[BiasPolynomial], device_ids: dict | None = None, slot: int = 0
                   ) -> tuple[list[tuple[str, float, int]], list[str]]:
    """[(name, value, MAV_PARAM_TYPE)] of PX4's TC_A{slot}_* / TC_G{slot}_* (module doc; slot: the sensor's
    instance, as PX4's own script numbers them), and the warnings; device_ids: {sensor: the device id a log
    holds}, written as TC_A{slot}_ID / TC_G{slot}_ID."""
    warnings = _checked(polys, "PX4")
    rows: list[tuple[str, float, int]] = []
    for p in polys:
        letter = "A" if p.sensor == "acc" else "G"
        c = _cubic(p)
        rows.append((f"TC_{letter}_ENABLE", 1, PX4_INT32))
        if device_ids and device_ids.get(p.sensor) is not None:
            rows.append((f"TC_{letter}{slot}_ID", int(device_ids[p.sensor]), PX4_INT32))
        rows += [(f"TC_{letter}{slot}_{k}", v, PX4_REAL32) for k, v in
                 (("TREF", p.t_ref_c), ("TMIN", p.t_min_c), ("TMAX", p.t_max_c))]
        rows += [(f"TC_{letter}{slot}_X{k}_{i}", float(c[i, k]), PX4_REAL32) for i in range(3) for k in range(4)]
    return rows, warnings


def ardupilot_parameters(polys: list[BiasPolynomial], slot: int = 0) -> tuple[list[tuple[str, float]], list[str]]:
    """[(name, value)] of ArduPilot's INS_TCAL{slot + 1}_* (module doc; slot: the IMU's instance, IMU.I), and
    the warnings."""
    warnings = _checked(polys, "ArduPilot")
    lo, hi = max(p.t_min_c for p in polys), min(p.t_max_c for p in polys)
    tcal = f"INS_TCAL{slot + 1}"
    rows = [(f"{tcal}_ENABLE", 1), (f"{tcal}_TMIN", lo), (f"{tcal}_TMAX", hi)]
    by_sensor = {p.sensor: p for p in polys}
    for sensor, name in (("acc", "ACC"), ("gyro", "GYR")):
        p = by_sensor.get(sensor)  # one enable for both: a sensor not calibrated gets zeros, not stale values
        c = np.zeros((3, 4)) if p is None else about(_cubic(p), ARDUPILOT_T_REF_C - p.t_ref_c) * ARDUPILOT_SCALE
        warnings += [] if p else [f"no {sensor} calibration: {tcal}_{name}* set to 0 (no correction)"]
        rows += [(f"{tcal}_{name}{k}_{'XYZ'[i]}", float(c[i, k])) for k in range(1, 4) for i in range(3)]
    return rows, warnings


def _number(v) -> str:
    """Nine significant digits: every float32 (what both autopilots store) read back exactly."""
    return str(v) if isinstance(v, int) else f"{v:.9g}"


def _header(imus: list["Imu"], warnings, notes) -> list[str]:
    lines = [f"# from simucal calibrate --thermal: {', '.join(u.source for u in imus)}",
             "# the data's sensor axes taken as the autopilot's sensor axes (before its rotation to the body frame)"]
    lines += [f"# instance {u.slot} {p.sensor}: bias polynomial in {SI_UNIT[p.sensor]}, calibrated {p.t_min_c:g} to "
              f"{p.t_max_c:g} degC, from {u.source}" for u in imus for p in u.polys]
    return lines + [f"# {n}" for n in notes] + [f"# WARNING: {w}" for w in warnings]


def _and(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def px4_note(imus: list["Imu"]) -> str:
    """What to do with the PX4 file: the device ids it holds, or that the user must set."""
    known = [u.slot for u in imus if u.device_ids and all(v is not None for v in u.device_ids.values())]
    unknown = [u.slot for u in imus if u.slot not in known]
    said = [f"{_and([f'TC_A{n}_ID and TC_G{n}_ID' for n in known])} are the log's device ids (PX4 applies each set "
            "only to those sensors)"] if known else []
    said += [f"set {_and([f'TC_A{n}_ID and TC_G{n}_ID' for n in unknown])} to the sensor's device id "
             f"({_and([f'CAL_ACC{n}_ID, CAL_GYRO{n}_ID' for n in unknown])}): PX4 applies each set only to that "
             "sensor"] if unknown else []
    return "; ".join(said) + "; then reboot and redo the ordinary accelerometer and gyro calibration"


def ardupilot_note(imus: list["Imu"]) -> str:
    offsets = _and([f"INS_ACC{u.slot + 1}_CALTEMP and INS_GYR{u.slot + 1}_CALTEMP" for u in imus])
    return (f"the constant bias is the ordinary calibration's (offsets at {offsets}): redo it after loading; "
            "these polynomials correct the change from that temperature")


@dataclass(frozen=True)
class Imu:
    """One IMU's export: its bias polynomials, its log's device ids, its slot (the log's instance) and the
    sets it was calibrated from."""
    polys: list[BiasPolynomial]
    device_ids: dict | None
    slot: int
    source: str
    effects: tuple[str, ...] = ()  # the effects fitted beside the polynomials (a warm-up's temperature rates)


def unexpressed(u: Imu, autopilot: str) -> list[str]:
    """The warnings of the effects an IMU's calibration fitted that the autopilot has no parameter for."""
    return [f"{e} was fitted beside the bias polynomial, but {autopilot} has no parameter for it: the file holds the "
            "polynomial alone (the bias at a steady temperature), so the correction is off by that term while the "
            "temperature changes" for e in u.effects]


def px4_text(imus: list[Imu]) -> tuple[str, list[str]]:
    """A QGroundControl .params file (tab-separated: vehicle id, component id, name, value, type) of every
    IMU's TC_A{n}_*/TC_G{n}_* (one TC_*_ENABLE each, as PX4's own script writes them) and the warnings."""
    rows: list[tuple[str, float, int]] = []
    warnings: list[str] = []
    for u in imus:
        got, said = px4_parameters(u.polys, u.device_ids, u.slot)
        said += unexpressed(u, "PX4")
        rows += [r for r in got if r not in rows]
        warnings += [f"instance {u.slot}: {w}" if len(imus) > 1 else w for w in said]
    lines = ["# Onboard parameters for Vehicle 1", "#"] + _header(imus, warnings, [px4_note(imus)])
    lines += ["#", "# Vehicle-Id Component-Id Name Value Type"]
    lines += [f"1\t1\t{n}\t{_number(v)}\t{t}" for n, v, t in rows]
    return "\n".join(lines) + "\n", warnings


def ardupilot_text(imus: list[Imu]) -> tuple[str, list[str]]:
    """A Mission Planner .param file (NAME,VALUE lines, # comments) of every IMU's INS_TCAL{n+1}_* and the
    warnings."""
    rows: list[tuple[str, float]] = []
    warnings: list[str] = []
    for u in imus:
        got, said = ardupilot_parameters(u.polys, u.slot)
        said += unexpressed(u, "ArduPilot")
        rows += got
        warnings += [f"instance {u.slot}: {w}" if len(imus) > 1 else w for w in said]
    lines = _header(imus, warnings, [ardupilot_note(imus)]) + [f"{n},{_number(v)}" for n, v in rows]
    return "\n".join(lines) + "\n", warnings


def imu(cal, meta: meta_keys.Meta, px4: bool = False) -> Imu:
    """The export of one calibration; meta: its data's meta.json (gravity_mps2, the log's instance and device
    ids). Refused: --px4 of data PX4 has already corrected, an instance beyond the autopilots' slots."""
    polys = bias_polynomials(cal, gravity_mps2(meta))
    source = ", ".join(cal.input) if isinstance(cal.input, list) else str(cal.input)
    got = meta.get("log")
    log = got if isinstance(got, dict) else {}
    ids = {p.sensor: log.get(f"{p.sensor}_device_id") for p in polys} if log else None
    # the slot is the log's instance (PX4's primary IMU, sensor_combined, has none: slot 0, matched by its id)
    instance = log.get("instance")
    slot = instance if isinstance(instance, int) else 0
    if px4 and log.get("corrected"):
        raise CalibrationError(f"--px4: {source} was imported from {log.get('source')}, with {log['corrected']}; PX4's "
                               "TC_* correct the raw sensor_accel/sensor_gyro: log those (SDLOG_PROFILE's thermal "
                               "calibration bit) and import them with --instance N")
    return Imu(polys, ids, slot, source, tuple(e for _, b in cal.blocks() for e in b.effects))


class AutopilotFile(NamedTuple):
    """One file of `Calibration.autopilot_files`: where it goes, its text, what it warns of and what to do with it."""
    path: str
    text: str
    warnings: list[str]
    note: str


def files(units: list[tuple], px4: str | None = None, ardupilot: str | None = None) -> list[AutopilotFile]:
    """texts' files as records, none where no file is asked for."""
    return [AutopilotFile(*f) for f in texts(units, px4, ardupilot)] if px4 or ardupilot else []


def texts(units: list[tuple], px4: str | None = None, ardupilot: str | None = None) -> list[tuple]:
    """[(path, text, warnings, note)] of the files asked for, each holding every unit's slot; units: [(a thermal
    calibration, its data's meta.json)], one per IMU of the log."""
    imus = [imu(cal, meta, bool(px4)) for cal, meta in units]
    slots = [u.slot for u in imus]
    if len(set(slots)) < len(slots):
        twice = next(s for s in slots if slots.count(s) > 1)
        raise CalibrationError(f"instance {twice}: two calibrations for one slot ("
                               f"{' and '.join(u.source for u in imus if u.slot == twice)}): export one per instance")
    for given, name, room in ((px4, "--px4", PX4_SLOTS), (ardupilot, "--ardupilot", ARDUPILOT_SLOTS)):
        beyond = [u for u in imus if u.slot >= room]
        if given and beyond:
            raise CalibrationError(f"{name}: {beyond[0].source} is the log's IMU instance {beyond[0].slot}; "
                                   f"the autopilot has thermal compensation slots for instances 0 to {room - 1} only")
    made = [(px4, *px4_text(imus), px4_note(imus))] if px4 else []
    return made + ([(ardupilot, *ardupilot_text(imus), ardupilot_note(imus))] if ardupilot else [])
