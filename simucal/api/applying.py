"""`simucal.apply` and `simucal.apply_set`: a calibration applied to raw outputs (arrays, DataFrames) and to a
measurement set, as `simucal apply` does (fit/apply.py: each row's inputs from its outputs through the model)."""
from __future__ import annotations

import warnings
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from simucal import io
from simucal.api.sets import as_set
from simucal.arguments import checked
from simucal.errors import CalibrationError
from simucal.fit import apply as fit_apply
from simucal.generated.effects import EFFECTS
from simucal.io import SAMPLE_COLS, units
from simucal.io.calibration import Calibration
from simucal.io.calibration_checks import LAYOUT_KEYS
from simucal.io.meta import Meta

PHYSICAL = {"acc": ("g", "m/s^2"), "gyro": ("deg/h", "deg/s", "rad/s")}  # units a calibrated output is given in


@checked
def apply(cal: Calibration, x: Any, *, acc_unit: str | None = None, gyro_unit: str | None = None, temp_c: Any = None,
          t_s: Any = None, sensor: str | None = None, columns: dict[str, str] | None = None,
          gravity_mps2: float = units.DEFAULT_GRAVITY) -> Any:
    """The calibrated inputs (specific force, angular rate in frame b) of raw outputs `x`.

    Parameters
    ----------
    cal : Calibration
        The calibration to apply (`simucal.calibrate`, `simucal.load`).
    x : array_like of shape (n, 6) or (n, 3), or pandas.DataFrame
        Raw outputs: (n, 6) columns ax ay az gx gy gz; (n, 3) one sensor's (`sensor`); a
        DataFrame's columns by the spec's names (or `columns`, ``{spec name: column}``).
    acc_unit, gyro_unit : str, optional
        The units of `x` (default: the calibration's own, as it was made). The result is in
        the same units where they are physical (g, m/s^2; deg/h, deg/s, rad/s), else in g
        and deg/h (pulse/s and counts are the calibration's nominal scale factors).
    temp_c : array_like of shape (n,), optional
        Each row's temperature (degC), required where the model follows temperature (a
        thermal calibration, a temperature effect); a DataFrame's temp_c column otherwise.
    t_s : array_like of shape (n,), optional
        Each row's time (s), required where the model drifts in time.
    sensor : {"acc", "gyro"}, optional
        Whose outputs an (n, 3) array holds, where the calibration has both; for a DataFrame,
        the one sensor to apply (else every sensor of the calibration, whose columns must all
        be there).
    columns : dict, optional
        For a DataFrame, its columns not named as the spec names them.
    gravity_mps2 : float
        g in m/s^2 where a unit is m/s^2 (the calibration's data's meta.json's, 9.80665 by default).

    Returns
    -------
    numpy.ndarray or pandas.DataFrame
        The same type and shape as `x`: an array of the calibrated values, or a copy of the
        frame with those columns replaced, their units in ``attrs["units"]`` ({"acc": ..., "gyro": ...}).

    Examples
    --------
    >>> calibrated = simucal.apply(cal, raw, acc_unit="counts", gyro_unit="counts")  # doctest: +SKIP
    """
    frame = hasattr(x, "columns") and not isinstance(x, np.ndarray)
    acc, gyro, names = _split(cal, x, frame, sensor, columns)
    if frame and temp_c is None and "temp_c" in x.columns:
        temp_c = x["temp_c"].to_numpy(float)
    _needs(cal, temp_c, t_s)
    given = _given_units(cal, acc_unit, gyro_unit, gravity_mps2)
    scales = {k: v for k, v in cal.layout.items() if k in LAYOUT_KEYS}
    mine = {"acc_unit": "g", "gyro_unit": "deg/h", **scales, "gravity_mps2": gravity_mps2}
    # the caller's units to the calibration's own (its check refuses any other): exact for physical units
    raw = [None if a is None else conv(back(a, {**scales, **given}), mine)
           for a, back, conv in ((acc, units.acc_to_g, units.g_to_acc),
                                 (gyro, units.gyro_to_dph, units.dph_to_gyro))]
    ms = io.MeasurementSet.from_arrays(*raw, acc_unit=str(mine["acc_unit"]), gyro_unit=str(mine["gyro_unit"]),
                                       temp_c=temp_c, **({"t_s": t_s} if t_s is not None else {"rate_hz": 1.0}),
                                       meta={**scales, "latitude_deg": 0.0, "gravity_mps2": gravity_mps2}, name="x")
    meta, out, _ = fit_apply.apply(cal, ms, "this calibration")
    for w in meta.get("warnings", []):  # rows outside the calibrated temperatures (kelvin named): as the command
        warnings.warn(w.replace(" of samples.csv", " of x"), stacklevel=3)  # the caller's line, past the door
    back = {"acc": given["acc_unit"] if given["acc_unit"] in PHYSICAL["acc"] else "g",
            "gyro": given["gyro_unit"] if given["gyro_unit"] in PHYSICAL["gyro"] else "deg/h"}
    result: dict[str, NDArray[np.float64]] = {}
    for s, cols, to in (("acc", SAMPLE_COLS[:3], units.g_to_acc), ("gyro", SAMPLE_COLS[3:], units.dph_to_gyro)):
        if cols[0] in out:
            u = np.column_stack([out[c] for c in cols])
            result.update(zip(cols, to(u, {f"{s}_unit": back[s], "gravity_mps2": gravity_mps2}).T))
    _plausible(result, back["acc"], given)
    if frame:
        assert names is not None  # _split names a frame's columns
        return _frame_of(x, result, names, back)
    return np.column_stack([result[c] for c in SAMPLE_COLS if c in result]).reshape(np.shape(x))


@checked
def apply_set(cal: Calibration, data: Any, *, where: str = "this calibration",
              units: str = "spec") -> io.MeasurementSet:
    """The calibrated measurement set of a set's raw outputs (`simucal apply`): the samples in g and
    deg/h (``units="si"``: m/s^2 with the set's gravity_mps2, and rad/s, both units of the spec), frame b,
    its other columns and segments kept; rows outside the calibrated temperatures are said in
    ``meta["warnings"]``.

    Parameters
    ----------
    cal : Calibration
        The calibration to apply.
    data : str, os.PathLike or MeasurementSet
        The raw set (a folder, or a set in memory).
    where : str
        How a refusal names this calibration (the command line: its file).
    units : str
        "spec" (g, deg/h) or "si" (m/s^2, rad/s; meta.json's acc_unit and gyro_unit say so).

    Returns
    -------
    MeasurementSet
        In memory; ``.write(folder)`` writes it as `simucal apply -o` does.

    Examples
    --------
    >>> calibrated = simucal.apply_set(cal, "other")  # doctest: +SKIP
    >>> calibrated.write("calibrated")  # doctest: +SKIP
    """
    from simucal.io import units as spec  # the module: `units` is the argument here
    spec.check_unit_system(units)
    ms = as_set(data)
    meta, samples, segments = fit_apply.apply(cal, ms, where)
    if units == "si":  # the spec's own SI units: m/s^2 (the set's gravity) and rad/s
        si = {"acc_unit": "m/s^2", "gyro_unit": "rad/s", "gravity_mps2": spec.gravity(ms.meta)}
        for s, cols, to in (("acc", SAMPLE_COLS[:3], spec.g_to_acc), ("gyro", SAMPLE_COLS[3:], spec.dph_to_gyro)):
            if s in ms.sensors:
                samples.update(zip(cols, to(np.column_stack([samples[c] for c in cols]), si).T))
        meta.update(acc_unit=si["acc_unit"], gyro_unit=si["gyro_unit"])
    calibrated = cast(Meta, {"format": io.FORMAT, **meta})  # the set's meta.json, its units the calibrated ones
    return io.MeasurementSet(ms.path, calibrated, samples, segments)


def _frame_of(x: Any, result: dict[str, NDArray[np.float64]], names: dict[str, str], units_of: dict[str, str]) -> Any:
    """A copy of frame x with the calibrated columns replaced, their units in attrs["units"]."""
    df = x.copy()
    for c, v in result.items():
        df[names[c]] = v
    df.attrs["units"] = {s: units_of[s] for s, cols in (("acc", SAMPLE_COLS[:3]), ("gyro", SAMPLE_COLS[3:]))
                         if cols[0] in result}
    df.attrs["frame"] = "b (the calibration's)"
    return df


def _plausible(result: dict[str, NDArray[np.float64]], acc_unit: str, given: dict[str, Any]) -> None:
    """A unit mix-up (pulse/s given as g) would come back silently absurd: refused as a set's is."""
    if "ax" in result:
        f = np.linalg.norm(np.column_stack([result[c] for c in SAMPLE_COLS[:3]]), axis=1)
        units.check_magnitude("acc", f, 1.0 if acc_unit == "g" else given["gravity_mps2"],
                              f"simucal.apply(acc_unit={given['acc_unit']!r}): calibrated")


def _given_units(cal: Calibration, acc_unit: str | None, gyro_unit: str | None,
                 gravity_mps2: float) -> dict[str, Any]:
    """The caller's units (default the calibration's own), refused where simucal does not know one."""
    given = {"acc_unit": acc_unit or cal.layout.get("acc_unit", "g"),
             "gyro_unit": gyro_unit or cal.layout.get("gyro_unit", "deg/h"), "gravity_mps2": gravity_mps2}
    for s, known in (("acc", units.ACC_UNITS), ("gyro", units.GYRO_UNITS)):
        if given[f"{s}_unit"] not in known:
            raise CalibrationError(f"{s}_unit={given[f'{s}_unit']!r}: not a unit simucal knows; one of {known}")
    return given


Split = tuple[NDArray[np.float64] | None, NDArray[np.float64] | None,
              dict[str, str] | None]  # acc, gyro, the frame's columns


def _split(cal: Calibration, x: Any, frame: bool, sensor: str | None,
           columns: dict[str, str] | None) -> Split:
    """(acc, gyro, {spec name: the frame's column}) of x."""
    if frame:
        names = {c: c for c in SAMPLE_COLS} | dict(columns or {})
        wanted = [sensor] if sensor else cal.sensors
        got = {}
        for s, cols in (("acc", SAMPLE_COLS[:3]), ("gyro", SAMPLE_COLS[3:])):
            missing = [names[c] for c in cols if names[c] not in x.columns]
            if s in wanted and missing:  # a sensor left raw beside calibrated ones would pass unnoticed
                raise CalibrationError(f"the frame lacks {', '.join(missing)} (the calibration's {s} reads "
                                       f"{' '.join(names[c] for c in cols)}; its columns: {list(x.columns)}): "
                                       "name them with columns={'" + cols[0] + "': ..., ...}" + ("" if sensor else
                                       f", or apply one sensor with sensor='{'gyro' if s == 'acc' else 'acc'}'"))
            got[s] = x[[names[c] for c in cols]].to_numpy(float) if s in wanted else None
        return got["acc"], got["gyro"], names
    a = np.asarray(x, float)
    if a.ndim != 2 or a.shape[1] not in (3, 6):
        raise CalibrationError(f"x has shape {a.shape}: give (n, 6) (ax ay az gx gy gz) or (n, 3) with sensor=")
    if a.shape[1] == 6:
        return a[:, :3], a[:, 3:], None
    sensor = sensor or (cal.sensors[0] if len(cal.sensors) == 1 else None)
    if sensor not in ("acc", "gyro"):
        raise CalibrationError(f"x has 3 columns and the calibration has {' and '.join(cal.sensors)}: say whose with "
                               "sensor='acc' or sensor='gyro'")
    return (a, None, None) if sensor == "acc" else (None, a, None)


def _needs(cal: Calibration, temp_c: Any, t_s: Any) -> None:
    """Refuse leaving out an input the model reads (it would be taken as 0, silently)."""
    reads = {r for _, b in cal.blocks() for e in b.library_effects() for r in EFFECTS[e].reads}
    if any(b.thermal is not None for _, b in cal.blocks()):
        reads.add("temp_c")
    if temp_c is None and reads & {"temp_c", "dtemp_c"}:
        raise CalibrationError("the calibration follows temperature: give each row's temp_c= (degC)")
    if t_s is None and "t_s" in reads:
        raise CalibrationError("the calibration has a bias drifting in time: give each row's t_s= (s)")
