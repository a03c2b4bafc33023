"""`simucal calibrate`: one measurement set in, one calibration file out.

A set with segments.csv is a turntable test (turntable/calibrate.py: dong2018's
exact, linear and multi-position methods); one without is a continuous stream, a
hand-placed session (handheld/calibrate.py). Both return the calibration file's
dict (io/calibration.py).
"""
from __future__ import annotations

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit.augmented import AugmentedModel, resolve_add
from simucal.handheld.calibrate import calibrate_handheld
from simucal.io import calibration
from simucal.io.sensor_checks import stuck_channels
from simucal.turntable.calibrate import METHODS, calibrate_table


def calibrate(folder, method="exact", acc_model="acc_baseline", gyro_model="gyro_baseline", detect=None,
              add=(), acc_noise_g=None, gyro_noise_dph=None) -> dict:
    """Calibrate a measurement set. add: effect ids and model files (augmented.resolve_add), and
    "auto": the library effects a failing model needs, chosen one at a time (each sensor's
    block lists them under `auto`); acc_noise_g / gyro_noise_dph: the noise of one row where
    the data cannot give it."""
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; one of {METHODS}")
    ms = io.read(folder)
    try:
        stuck_channels(ms)
        auto = "auto" in add
        acc_model, gyro_model, ids = resolve_add([a for a in add if a != "auto"], acc_model, gyro_model)
        if ms.segments is None:  # one continuous stream: a hand-placed session
            result = calibrate_handheld(ms, AugmentedModel(acc_model, tuple(e for e in ids if e.startswith("acc."))),
                                        detect, gyro_effects=tuple(e for e in ids if e.startswith("gyro.")),
                                        auto=auto)
        else:
            result = calibrate_table(ms, method, acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph, auto)
        notes = calibration.scale_notes(result, ms.meta)
    except CalibrationError as e:
        raise e.naming(ms.path) from None
    if notes:
        result["warnings"] = result.get("warnings", []) + notes
    return result


def calibrate_to_file(folder, output, kwargs: dict):
    """calibrate() one set and write its file; (result, None), or (None, the refusal's message).
    One task of a batch (`simucal calibrate DIR1 DIR2 ... --scheduler`): a refusal loses no other set."""
    try:
        result = calibrate(folder, **kwargs)
        calibration.write(output, result)
        return result, None
    except (io.MeasurementSetError, CalibrationError, KeyError, FileNotFoundError, ValueError) as e:
        return None, str(e.args[0] if isinstance(e, KeyError) and e.args else e)
