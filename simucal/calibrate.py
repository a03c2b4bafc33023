"""`simucal calibrate`: one measurement set in, one calibration file out.

The method comes from the registry (methods.py): the one named, or by default the
first that takes the set's data (a turntable test: dong2018's exact method; a
stream: the hand-placed session; a field set: ruan2019). Every method returns the
calibration file's dict (io/calibration.py).
"""
from __future__ import annotations

from simucal import io, methods
from simucal.errors import CalibrationError
from simucal.io import calibration
from simucal.io.sensor_checks import stuck_channels


def calibrate(folder, method="auto", acc_model="acc_baseline", gyro_model="gyro_baseline", detect=None,
              add=(), acc_noise_g=None, gyro_noise_dph=None, heading_accuracy_deg=5.0) -> dict:
    """Calibrate a measurement set. method: a name of methods.METHODS, or "auto" (the default for
    the set's data). add: effect ids and model files (augmented.resolve_add), and "auto": the
    library effects a failing model needs, chosen one at a time (each sensor's block lists them
    under `auto`); acc_noise_g / gyro_noise_dph: the noise of one row where the data cannot give
    it; detect: a stream's static detection settings; heading_accuracy_deg: a field set's north
    reference. Options a method does not take are refused when set."""
    ms = io.read_set(folder)
    try:
        m = methods.choose(method, ms)
        stuck_channels(ms)
        ids = tuple(a for a in add if a != "auto")
        if "ids" in m.options:  # models and effects: imported only by the methods that fit them
            from simucal.fit.augmented import resolve_add
            acc_model, gyro_model, ids = resolve_add(ids, acc_model, gyro_model)
        given = dict(acc_model=acc_model, gyro_model=gyro_model, ids=ids, auto="auto" in add, detect=detect,
                     acc_noise_g=acc_noise_g, gyro_noise_dph=gyro_noise_dph, heading_accuracy_deg=heading_accuracy_deg)
        unused = [k for k in ("ids", "auto", "acc_noise_g", "gyro_noise_dph") if given[k] and k not in m.options]
        if unused:
            flag = {"ids": "--add", "auto": "--add auto"}.get(unused[0], "--" + unused[0].replace("_", "-"))
            raise CalibrationError(f"{flag} does not apply to method {m.name} ({m.summary}).")
        result = m.run(ms, **{k: v for k, v in given.items() if k in m.options})
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
        calibration.save(output, result)
        return result, None
    except (io.MeasurementSetError, CalibrationError, KeyError, FileNotFoundError, ValueError) as e:
        return None, str(e.args[0] if isinstance(e, KeyError) and e.args else e)
