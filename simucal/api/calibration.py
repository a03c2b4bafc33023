"""`simucal.Calibration`: the calibration file's object (simucal.io.calibration) with `apply` to
arrays and DataFrames and `parameters` as a table."""
from __future__ import annotations

from dataclasses import fields
from typing import Any, NamedTuple

import numpy as np

from simucal.api.tables import table
from simucal.errors import CalibrationError
from simucal.fit import apply as fit_apply
from simucal.fit.augmented import AugmentedModel
from simucal.generated.effects import EFFECTS
from simucal.io import SAMPLE_COLS, arrays, calibration, units
from simucal.io.calibration_checks import LAYOUT_KEYS

PHYSICAL = {"acc": ("g", "m/s^2"), "gyro": ("deg/h", "deg/s", "rad/s")}  # units a calibrated output is given in


class Parameter(NamedTuple):
    """One row of `Calibration.parameters()`."""
    name: str
    sensor: str
    value: float
    std: float
    unit: str
    meaning: str


def _model_rows(sensor, block) -> list[Parameter]:
    model = AugmentedModel(block.model, block.library_effects())
    return [Parameter(n, sensor, float(block.params[n]), float(block.std.get(n, np.nan)),
                      block.param_units.get(n, u), m)
            for n, u, m in zip(model.params, model.param_units, model.meanings)]


def _affine_rows(sensor, block) -> list[Parameter]:
    """An affine block (multiposition, a stream's gyro): M's (or the fitted T's) entries and the bias,
    their stds where the method gave them (as M- and bias-shaped arrays)."""
    name, A = "M", block.M
    if "T" in block.std and "T" in block.details:  # a stream's gyro fits T = M^-1 (input = T (output - bias))
        name, A = "T", np.asarray(block.details["T"], float)
    sd = np.asarray(block.std.get(name, np.full((3, 3), np.nan)), float)
    b_sd = np.asarray(block.std.get("bias", np.full(3, np.nan)), float)
    per = "output {} per input {}" if name == "M" else "input {} per output {} (T = M^-1)"
    rows = [Parameter(f"{name}_{'xyz'[i]}{'xyz'[j]}", sensor, float(A[i, j]), float(sd[i, j]), "1",
                      f"row {'xyz'[i]}, column {'xyz'[j]} of {name}: " + per.format('xyz'[i], 'xyz'[j]))
            for i in range(3) for j in range(3)]
    return rows + [Parameter(f"bias_{c}", sensor, float(block.bias[i]), float(b_sd[i]), block.bias_unit,
                             f"{c} output at zero input") for i, c in enumerate("xyz")]


class Calibration(calibration.Calibration):
    """A calibration of one unit: per sensor the model output = h(input, p), its parameters with
    their stds, the test of the model and what the method reports (README, "the calibration file").

    Returned by `simucal.calibrate` and `simucal.load`; written by `simucal.save`.

    Examples
    --------
    >>> import simucal
    >>> cal = simucal.load("calibration.json")  # doctest: +SKIP
    >>> cal.acc.p_value, cal.sensors  # doctest: +SKIP
    (0.41, ['acc', 'gyro'])
    """

    @classmethod
    def of(cls, cal: calibration.Calibration) -> Calibration:
        """The same calibration as this class (its fields shared, not copied)."""
        return cal if isinstance(cal, cls) else cls(**{f.name: getattr(cal, f.name) for f in fields(cal)})

    def parameters(self) -> Any:
        """Every parameter of every sensor's model as a table: a list of `Parameter` rows.

        Returns
        -------
        pandas.DataFrame or list of Parameter
            ``(name, sensor, value, std, unit, meaning)`` per parameter: a DataFrame where pandas
            is installed, else a list of `Parameter` rows. An affine model (the multi-position
            method, a stream's gyro) gives M's entries and the bias. std is the file's (inflated by
            the misfit where the model fails its test).

        Examples
        --------
        >>> p = cal.parameters()  # doctest: +SKIP
        >>> p.set_index(["sensor", "name"]).loc[("acc", "dK_z"), ["value", "std", "unit"]]  # doctest: +SKIP
        """
        return table([r for s, b in self.blocks() for r in (_model_rows(s, b) if b.params else _affine_rows(s, b))],
                      Parameter._fields)

    def apply(self, x: Any, *, acc_unit: str | None = None, gyro_unit: str | None = None, temp_c: Any = None,
              t_s: Any = None, sensor: str | None = None, columns: dict[str, str] | None = None,
              gravity_mps2: float = units.DEFAULT_GRAVITY) -> Any:
        """The calibrated inputs (specific force, angular rate in frame b) of raw outputs `x`.

        Parameters
        ----------
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
            Whose outputs an (n, 3) array holds, where the calibration has both.
        columns : dict, optional
            For a DataFrame, its columns not named as the spec names them.
        gravity_mps2 : float
            g in m/s^2 where a unit is m/s^2 (the calibration's data's meta.json's, 9.80665 by default).

        Returns
        -------
        numpy.ndarray or pandas.DataFrame
            The same type and shape as `x`: an array of the calibrated values, or a copy of the
            frame with those columns replaced.

        Examples
        --------
        >>> calibrated = cal.apply(raw, acc_unit="counts", gyro_unit="counts")  # doctest: +SKIP
        """
        frame = hasattr(x, "columns") and not isinstance(x, np.ndarray)
        acc, gyro, names = _split(self, x, frame, sensor, columns)
        if frame and temp_c is None and "temp_c" in x.columns:
            temp_c = x["temp_c"].to_numpy(float)
        _needs(self, temp_c, t_s)
        given = {"acc_unit": acc_unit or self.layout.get("acc_unit", "g"),
                 "gyro_unit": gyro_unit or self.layout.get("gyro_unit", "deg/h"), "gravity_mps2": gravity_mps2}
        scales = {k: v for k, v in self.layout.items() if k in LAYOUT_KEYS}
        mine = {"acc_unit": "g", "gyro_unit": "deg/h", **scales, "gravity_mps2": gravity_mps2}
        # the caller's units to the calibration's own (its check refuses any other): exact for physical units
        raw = [None if a is None else conv(back(a, {**scales, **given}), mine)
               for a, back, conv in ((acc, units.acc_to_g, units.g_to_acc), (gyro, units.gyro_to_dph, units.dph_to_gyro))]
        ms = arrays.from_arrays(*raw, acc_unit=mine["acc_unit"], gyro_unit=mine["gyro_unit"], temp_c=temp_c,
                                **({"t_s": t_s} if t_s is not None else {"rate_hz": 1.0}),
                                meta={**scales, "latitude_deg": 0.0, "gravity_mps2": gravity_mps2}, name="x")
        _, out, _ = fit_apply.apply(self, ms, "this calibration")
        back = {"acc": given["acc_unit"] if given["acc_unit"] in PHYSICAL["acc"] else "g",
                "gyro": given["gyro_unit"] if given["gyro_unit"] in PHYSICAL["gyro"] else "deg/h"}
        result: dict[str, np.ndarray] = {}
        for s, cols, to in (("acc", SAMPLE_COLS[:3], units.g_to_acc), ("gyro", SAMPLE_COLS[3:], units.dph_to_gyro)):
            if cols[0] in out:
                u = np.column_stack([out[c] for c in cols])
                result.update(zip(cols, to(u, {f"{s}_unit": back[s], "gravity_mps2": gravity_mps2}).T))
        if frame:
            df = x.copy()
            for c, v in result.items():
                df[names[c]] = v
            return df
        return np.column_stack([result[c] for c in SAMPLE_COLS if c in result]).reshape(np.shape(x))


def _split(cal, x, frame, sensor, columns):
    """(acc, gyro, {spec name: the frame's column}) of x."""
    if frame:
        names = {c: c for c in SAMPLE_COLS} | dict(columns or {})
        got = {s: x[[names[c] for c in cols]].to_numpy(float) if all(names[c] in x.columns for c in cols) else None
               for s, cols in (("acc", SAMPLE_COLS[:3]), ("gyro", SAMPLE_COLS[3:]))}
        if got["acc"] is None and got["gyro"] is None:
            raise CalibrationError(f"the frame has neither ax ay az nor gx gy gz (columns: {list(x.columns)}): name "
                                   "them with columns={'ax': ..., ...}")
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


def _needs(cal, temp_c, t_s) -> None:
    """Refuse leaving out an input the model reads (it would be taken as 0, silently)."""
    reads = {r for _, b in cal.blocks() for e in b.library_effects() for r in EFFECTS[e].reads}
    if any(b.thermal is not None for _, b in cal.blocks()):
        reads.add("temp_c")
    if temp_c is None and reads & {"temp_c", "dtemp_c"}:
        raise CalibrationError("the calibration follows temperature: give each row's temp_c= (degC)")
    if t_s is None and "t_s" in reads:
        raise CalibrationError("the calibration has a bias drifting in time: give each row's t_s= (s)")
