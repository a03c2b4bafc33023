"""The checks of a calibration file before any of it is used: that it can be physics
(`check_file`, on the JSON as read), that it fits the data (`check_layout`), and the
scale factors of a fresh calibration (`scale_notes`). Each refusal names the entry."""
from __future__ import annotations

from typing import Any, Final, Mapping, cast

import numpy as np

from simucal.errors import CalibrationError, SimucalError
from simucal.io import records, units

LAYOUT_KEYS = ("acc_unit", "gyro_unit", "acc_pulses_per_g", "gyro_pulses_per_arcsec", "acc_counts_per_g",
               "gyro_counts_per_dps")
SERIAL: Final = "unit_serial"  # meta.json's optional serial number of the unit (README: the spec's extension)


class CalibrationFileError(SimucalError):
    """A calibration file that cannot be read, or that does not fit the data."""


def layout(ms) -> records.Layout:
    """The data's units, nominal scale factors, serial and sensors: a calibration is for these only."""
    out = cast(records.Layout, {k: ms.meta[k] for k in LAYOUT_KEYS + (SERIAL,)
                                if k in ms.meta})  # meta.json's, read by the spec
    out["sensors"] = [s for s, has in (("acc", ms.has_acc), ("gyro", ms.has_gyro)) if has]
    return out

# Beyond these no sensor block is physics: a hand-edited or corrupted file, refused naming the entry.
SCALE_RANGE = (0.5, 2.0)      # M's diagonal after the nominal scale factors
SMALL_UNITS = ("1", "rad")    # scale-factor errors and misalignments: |p| <= 0.5
PARAM_LIMIT = 1e6             # any other parameter, in its unit
BIAS_LIMIT = {"acc": 16.0, "gyro": 7.2e6}  # 16 g; 2000 deg/s in deg/h


def bias_limit(layout, sensor) -> float:
    """BIAS_LIMIT, or for raw counts the span of an unsigned 16-bit register at the nominal scale
    (the bias then holds the register's zero offset too)."""
    per = layout.get(f"{sensor}_counts_per_{'g' if sensor == 'acc' else 'dps'}")
    if layout.get(f"{sensor}_unit") != "counts" or not per:
        return BIAS_LIMIT[sensor]
    span = 2.0 ** 16 / min(per) * (1.0 if sensor == "acc" else units.DPH_PER_DPS)
    return max(BIAS_LIMIT[sensor], span)


def _matrix(path, where, value, shape):
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise CalibrationFileError(f"{path}: {where} is not a {shape[0]}x{shape[1] if len(shape) > 1 else ''} "
                                   "array of numbers".replace("x ", " ")) from None
    if a.shape != shape:
        raise CalibrationFileError(f"{path}: {where} has shape {list(a.shape)}, expected {list(shape)}")
    if not np.all(np.isfinite(a)):
        raise CalibrationFileError(f"{path}: {where} holds NaN or infinite entries")
    return a


def check_file(path, cal: dict) -> None:
    """Refuse a calibration that cannot be physics before it is applied: missing keys, shapes,
    NaN, a C_b_model that is not a proper rotation, scale factors outside SCALE_RANGE, a
    reversed axis, implausible parameters, unknown effects. Each refusal names the entry."""
    from simucal.generated.effects import EFFECTS
    lay = cal.get("layout")
    if not isinstance(lay, dict) or not isinstance(lay.get("sensors"), list):
        raise CalibrationFileError(f"{path}: lacks 'layout' (the data's units and sensors, written by simucal "
                                   "calibrate): it was not written by this version, or was edited; calibrate again")
    digests = cal.get("samples_sha256")
    if digests is not None and not (isinstance(digests, list) and all(isinstance(d, str) for d in digests)):
        raise CalibrationFileError(f"{path}: samples_sha256 must be a list of digests (strings), written by simucal "
                                   "calibrate: the file was edited by hand; calibrate again")
    for s in lay["sensors"]:
        block = cal.get(s)
        if s not in ("acc", "gyro") or not isinstance(block, dict):
            raise CalibrationFileError(f"{path}: layout names sensor {s!r}, but the file has no {s} block")
        for k in ("model", "M", "bias", "effects"):
            if k not in block:
                raise CalibrationFileError(f"{path}: the {s} block lacks {k!r}")
        if not isinstance(block["model"], str):
            raise CalibrationFileError(f"{path}: {s}.model = {block['model']!r} is not a model's name")
        for k in ("thermal", "params", "std", "param_units"):
            if k in block and not isinstance(block[k], dict):
                raise CalibrationFileError(f"{path}: {s}.{k} must be an object {{name: ...}}, not {block[k]!r}: the "
                                           "file was edited by hand; calibrate again")
        M = _matrix(path, f"{s}.M", block["M"], (3, 3))
        bias = _matrix(path, f"{s}.bias", block["bias"], (3,))
        diag = np.diag(M)
        if np.any(diag <= 0):
            raise CalibrationFileError(f"{path}: {s}.M has diagonal {np.round(diag, 4).tolist()}: a reversed axis; "
                                       "no calibration of a unit at its nominal signs has one")
        if np.any(diag < SCALE_RANGE[0]) or np.any(diag > SCALE_RANGE[1]) or np.linalg.det(M) <= 0:
            raise CalibrationFileError(f"{path}: {s}.M has diagonal {np.round(diag, 4).tolist()} (det "
                                       f"{np.linalg.det(M):.3g}): scale factors outside {SCALE_RANGE} of nominal "
                                       "are not a calibration of this unit")
        limit = bias_limit(lay, s)
        if np.any(np.abs(bias) > limit):
            raise CalibrationFileError(f"{path}: {s}.bias {bias.tolist()} is beyond any sensor's range "
                                       f"(|bias| <= {limit:.3g} {'g' if s == 'acc' else 'deg/h'})")
        if "C_b_model" in block:
            C = _matrix(path, f"{s}.C_b_model", block["C_b_model"], (3, 3))
            if np.abs(C.T @ C - np.eye(3)).max() > 1e-6 or np.linalg.det(C) < 0:
                raise CalibrationFileError(f"{path}: {s}.C_b_model is not a proper rotation (C^T C - I up to "
                                           f"{np.abs(C.T @ C - np.eye(3)).max():.2g}, det {np.linalg.det(C):.4g})")
        params = block.get("params", {})
        param_units = block.get("param_units", {})
        if not isinstance(params, dict):
            raise CalibrationFileError(f"{path}: {s}.params must be an object {{name: value}}")
        for name, v in params.items():
            unit = param_units.get(name, "1")
            limit = 0.5 if unit in SMALL_UNITS else PARAM_LIMIT
            if not isinstance(v, (int, float)) or not np.isfinite(v) or abs(v) > limit:
                raise CalibrationFileError(f"{path}: {s}.params.{name} = {v!r} is not a plausible value (finite, "
                                           f"|value| <= {limit:g}{'' if unit == '1' else ' ' + unit})")
        _check_stds(path, s, block)
        if not isinstance(block["effects"], dict):
            raise CalibrationFileError(f"{path}: {s}.effects must be an object {{id: {{value, ...}}}}")
        for e, entry in block["effects"].items():
            if e not in EFFECTS and not (isinstance(entry, dict) and entry.get("term_of") == block["model"]):
                raise CalibrationFileError(f"{path}: {s}.effects names {e!r}, which is no library effect "
                                           "(simucal diagnose lists them)")
            v = entry.get("value") if isinstance(entry, dict) else None
            if not isinstance(v, (int, float)) or not np.isfinite(v) or abs(v) > PARAM_LIMIT:
                raise CalibrationFileError(f"{path}: {s}.effects.{e}.value = {v!r} is not a plausible value")


def _check_stds(path, sensor, block) -> None:
    """A std (or each entry of a matrix's) is null (not estimated) or a finite number >= 0: a negative or NaN one is no
    uncertainty, and apply, validate and the reports would carry it on."""
    entries = [(f"{k}.{n}", v) for k in ("std", "std_raw") if isinstance(block.get(k), dict)
               for n, v in block[k].items()]
    entries += [(f"effects.{e}.std", d.get("std")) for e, d in block["effects"].items() if isinstance(d, dict)] \
        if isinstance(block.get("effects"), dict) else []
    for where, v in entries:
        if not all(x is None or (isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) and x >= 0)
                   for x in _flat(v)):
            raise CalibrationFileError(f"{path}: {sensor}.{where} = {v!r} is no standard deviation (null or a finite "
                                       "number >= 0): the file was edited or damaged; calibrate again")


def _flat(v) -> list:
    """The entries of a nested list (a matrix's stds), a scalar as one."""
    return [x for e in v for x in _flat(e)] if isinstance(v, list) else [v]


SCALE_NOTE = 0.1  # a scale factor this far from 1 after the nominal ones: the nominal is likely wrong


def scale_notes(cal, meta: Mapping[str, Any]) -> list[str]:
    """Lines naming implausible scale factors of a fresh calibration (M's diagonal, after dividing by
    the nominal scale factors of meta.json); a reversed axis (diagonal <= 0) is refused instead."""
    lines = []
    for s, block in cal.blocks():
        diag = np.diag(block.M)
        nominal = ", ".join(f"{k} = {meta[k]}" for k in LAYOUT_KEYS if k.startswith(s) and k in meta)
        if np.any(diag <= 0):
            axes = ", ".join("xyz"[i] for i in np.nonzero(diag <= 0)[0])
            raise CalibrationError(
                f"{s}: scale factors {np.round(diag, 3).tolist()}, negative on {axes}, which no unit at its nominal "
                "signs has: one axis of the accelerometer or gyro triad has its sign flipped (a column written as "
                "65536 - value, an axis wired reversed, or a left-handed frame); the norm cannot tell which triad: "
                "check the sign of every column in samples.csv against the unit's axes and calibrate again")
        far = np.abs(diag - 1) > SCALE_NOTE
        if np.any(far):
            lines.append(f"{s}: scale factors {np.round(diag, 4).tolist()} after dividing by the nominal ones "
                         f"({nominal or 'the unit in meta.json'}): "
                         f"{', '.join('xyz'[i] for i in np.nonzero(far)[0])} more than {SCALE_NOTE:.0%} from 1; "
                         "the nominal scale factor or the unit is likely wrong (the calibration corrects it, but "
                         "check meta.json)")
    return lines


def check_layout(cal, ms, where) -> None:
    """Refuse data of another unit, nominal scale or sensor set than the calibration's."""
    mine, theirs = cal.layout, layout(ms)
    if SERIAL in mine and SERIAL in theirs and str(mine[SERIAL]) != str(theirs[SERIAL]):
        raise CalibrationFileError(f"{ms.path}: unit_serial is {theirs[SERIAL]!r}, but {where} was made for unit "
                                   f"{mine[SERIAL]!r}: calibrate this unit's own data")
    for s in theirs["sensors"]:
        if s not in mine["sensors"] or getattr(cal, s) is None:
            raise CalibrationFileError(f"{ms.path}: has {s} data, but {where} calibrates no {s}")
    for k in LAYOUT_KEYS:
        sensor = k.split("_")[0]
        if sensor in theirs["sensors"] and mine.get(k) != theirs.get(k):
            raise CalibrationFileError(f"{ms.path}: {k} is {theirs.get(k)!r}, but {where} was made for "
                                       f"{mine.get(k)!r}: another sensor or unit; calibrate this sensor's own data")
