"""`simucal.Calibration`: the calibration file's object (simucal.io.calibration) with `apply` to
arrays and DataFrames and `parameters` as a table."""
from __future__ import annotations

import warnings
from pathlib import Path
from dataclasses import fields
from typing import Any, NamedTuple, cast

import numpy as np
from numpy.typing import NDArray

from simucal.api.arguments import checked
from simucal.api.tables import table
from simucal.api.vocabulary import common_table
from simucal.errors import CalibrationError, InputError
from simucal.fit import apply as fit_apply
from simucal.fit.augmented import AugmentedModel
from simucal.fit.thermal import terms as thermal_terms
from simucal.generated.effects import EFFECTS
from simucal.io import SAMPLE_COLS, arrays, calibration, units
from simucal.io.calibration_checks import LAYOUT_KEYS
from simucal.io.meta import Meta

PHYSICAL = {"acc": ("g", "m/s^2"), "gyro": ("deg/h", "deg/s", "rad/s")}  # units a calibrated output is given in


class Parameter(NamedTuple):
    """One row of `Calibration.parameters()`."""
    name: str
    sensor: str
    value: float
    std: float
    unit: str
    meaning: str


def _model_rows(sensor: str, block: calibration.SensorBlock) -> list[Parameter]:
    """Each parameter at T_ref; for a thermal calibration also each coefficient of its polynomial
    in (T - T_ref) (name.T1, name.T2, ...), in unit per degC^k."""
    model = AugmentedModel(block.model, block.library_effects())
    rows = []
    for n, u, m in zip(model.params, model.param_units, model.meanings):
        unit = block.param_units.get(n, u)
        rows.append(Parameter(n, sensor, float(block.params[n]), float(cast(float, block.std.get(n, np.nan))), unit,
                              m + (f" (at T_ref = {block.thermal['t_ref_c']:.4g} degC)" if block.thermal else "")))
        rows += [Parameter(term, sensor, c, e, term_unit, f"{m}: coefficient of (T - T_ref)^{k}")
                 for term, k, c, e, term_unit in thermal_terms(block.thermal, n, unit)]
    return rows


def _affine_rows(sensor: str, block: calibration.SensorBlock) -> list[Parameter]:
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


class AutopilotFile(NamedTuple):
    """One file of `Calibration.autopilot_files`: where it goes, its text, what it warns of and what to do with it."""
    path: str
    text: str
    warnings: list[str]
    note: str


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
    @checked
    def of(cls, cal: calibration.Calibration) -> Calibration:
        """The same calibration as this class (its fields shared, not copied)."""
        return cal if isinstance(cal, cls) else cls(**{f.name: getattr(cal, f.name) for f in fields(cal)})

    def __repr__(self) -> str:  # a notebook cell shows this: the file's every array is for parameters()
        tested = ", ".join(f"{s} (p = {b.p_value:.2g})" if b.p_value is not None else s for s, b in self.blocks())
        return f"<simucal.Calibration {self.method!r} of {self.input!r}: {tested or 'no sensor'}>"

    def _repr_html_(self) -> str:
        """A notebook's view: the method, the input, and per sensor its model, test and verdict."""
        from simucal.api.tables import html_card
        rows: list[tuple[str, Any]] = [("method", self.method), ("input", self.input)]
        for s, b in self.blocks():
            test = "no test" if b.p_value is None else f"chi2 {b.chi2:.4g} on {b.dof:g} dof, p = {b.p_value:.2g}"
            rows.append((s, f"{b.model}: {b.verdict} ({test}); residual rms {b.residual_rms:.3g} {b.residual_unit}"
                         if b.residual_rms is not None else f"{b.model}: {b.verdict} ({test})"))
        rows += [(f"{s} not calibrated", why) for s, why in self.not_calibrated.items()]
        return html_card("simucal.Calibration", rows)

    @checked
    def parameters(self, vocabulary: str = "common", units: str = "spec") -> Any:
        """Every sensor's parameters as a table, in one vocabulary for every method (api/vocabulary.py): each
        sensor's M entries (M_xx .. M_zz: output per input, frame b) and bias (bias_x .. bias_z) with their stds,
        the library effects by their ids, and the method's own name for each (``own_name``: dK_x, theta_yx, b_x
        for dong2018's methods; M_xx, bias_x for the multi-position method). A thermal calibration gives them
        at T_ref and below them each one's coefficient of (T - T_ref)^k that the data hold (``bias_x.T1`` in
        unit/degC, ``M_yy.T2`` in 1/degC^2), M and bias through the model of every parameter's polynomial.
        `simucal.compare` sets calibrations side by side so.

        With ``vocabulary="own"``, the method's own parameters instead: `Parameter` rows ``(name, sensor,
        value, std, unit, meaning)``; an affine model (the multi-position method, a stream's gyro) gives M's
        entries (or T's, T = M^-1) and the bias, a thermal calibration each parameter's coefficients
        (``b_x.T1``). std is the file's (inflated by the misfit where the model fails its test).

        With ``units="si"``, each value and std with its unit in SI (a bias in g in m/s^2 with the set's
        gravity_mps2 where its meta.json is at hand, else 9.80665; deg/h in rad/s; a scale factor or an angle
        unchanged), as `simucal calibrate --units si` prints them; the calibration file keeps the spec's.

        Returns
        -------
        pandas.DataFrame or list of Entry (or of Parameter)
            A DataFrame where pandas is installed, else a list of NamedTuple rows: ``(sensor, name, value, std,
            unit, own_name)`` (``vocabulary="own"``: ``(name, sensor, value, std, unit, meaning)``).

        Examples
        --------
        >>> p = cal.parameters()  # doctest: +SKIP
        >>> p.set_index(["sensor", "name"]).loc[("acc", "bias_z"), ["value", "std", "own_name"]]  # doctest: +SKIP
        """
        from simucal.report.units import calibration_in
        shown = calibration_in(self, units)
        if vocabulary == "common":
            return common_table(shown)
        if vocabulary != "own":
            raise InputError(f"vocabulary {vocabulary!r}: 'own' (each method's parameters) or 'common' (M and bias)")
        return table([r for s, b in shown.blocks() for r in (_model_rows(s, b) if b.params else _affine_rows(s, b))],
                      Parameter._fields)

    @checked
    def apply_to_set(self, data: Any, *, where: str = "this calibration", units: str = "spec") -> Any:
        """The calibrated measurement set of a set's raw outputs (`simucal apply`): the samples in g and
        deg/h (``units="si"``: m/s^2 with the set's gravity_mps2, and rad/s, both units of the spec), frame b,
        its other columns and segments kept; rows outside the calibrated temperatures are said in
        ``meta["warnings"]``.

        Parameters
        ----------
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
        >>> calibrated = cal.apply_to_set("other")  # doctest: +SKIP
        >>> calibrated.write("calibrated")  # doctest: +SKIP
        """
        from simucal import io
        from simucal.api.sets import MeasurementSet, as_set
        from simucal.io import units as spec  # the module: `units` is the argument here
        spec.check_unit_system(units)
        ms = as_set(data)
        meta, samples, segments = fit_apply.apply(self, ms, where)
        if units == "si":  # the spec's own SI units: m/s^2 (the set's gravity) and rad/s
            si = {"acc_unit": "m/s^2", "gyro_unit": "rad/s", "gravity_mps2": spec.gravity(ms.meta)}
            for s, cols, to in (("acc", SAMPLE_COLS[:3], spec.g_to_acc), ("gyro", SAMPLE_COLS[3:], spec.dph_to_gyro)):
                if s in ms.sensors:
                    samples.update(zip(cols, to(np.column_stack([samples[c] for c in cols]), si).T))
            meta.update(acc_unit=si["acc_unit"], gyro_unit=si["gyro_unit"])
        calibrated = cast(Meta, {"format": io.FORMAT, **meta})  # the set's meta.json, its units the calibrated ones
        return MeasurementSet.of(io.MeasurementSet(ms.path, calibrated, samples, segments))

    @checked
    def autopilot_files(self, data: Any, *, px4: str | None = None,
                        ardupilot: str | None = None) -> list[AutopilotFile]:
        """A thermal calibration's bias polynomials as PX4's and ArduPilot's thermal compensation parameter files
        (`simucal calibrate --thermal --px4 FILE --ardupilot FILE`): their texts, made before anything is written.

        Parameters
        ----------
        data : str, os.PathLike or MeasurementSet
            A set it was calibrated from (its meta.json: g, the log's device ids).
        px4, ardupilot : str, optional
            The files asked for (.params for PX4's QGroundControl, .parm for ArduPilot's Mission Planner).

        Returns
        -------
        list of AutopilotFile
            (path, text, warnings, note) of each file asked for; the caller writes them.

        Examples
        --------
        >>> for f in cal.autopilot_files("plateau_25", px4="tc.params"):  # doctest: +SKIP
        ...     open(f.path, "w").write(f.text)
        """
        from simucal import io
        from simucal.io import autopilot
        meta = data.meta if isinstance(data, io.MeasurementSet) else io.read_meta(Path(data))
        return [AutopilotFile(*f) for f in autopilot.texts([(self, meta)], px4, ardupilot)] if px4 or ardupilot else []

    @checked
    def sensor(self, name: str) -> calibration.SensorBlock:
        """The block of sensor `name` ("acc" or "gyro"), never None: refused (CalibrationError) where this
        calibration holds none, saying why (`not_calibrated`).

        Examples
        --------
        >>> cal.sensor("acc").p_value  # doctest: +SKIP
        0.41
        """
        block: calibration.SensorBlock | None = getattr(self, name, None) if name in ("acc", "gyro") else None
        if block is None:
            why = self.not_calibrated.get(name)
            raise CalibrationError(f"this calibration ({self.method}) holds no {name!r} block"
                                   + (f": {why}" if why
                                      else f"; its sensors: {', '.join(s for s, _ in self.blocks())}"))
        return block

    @checked
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
        >>> calibrated = cal.apply(raw, acc_unit="counts", gyro_unit="counts")  # doctest: +SKIP
        """
        frame = hasattr(x, "columns") and not isinstance(x, np.ndarray)
        acc, gyro, names = _split(self, x, frame, sensor, columns)
        if frame and temp_c is None and "temp_c" in x.columns:
            temp_c = x["temp_c"].to_numpy(float)
        _needs(self, temp_c, t_s)
        given = _given_units(self, acc_unit, gyro_unit, gravity_mps2)
        scales = {k: v for k, v in self.layout.items() if k in LAYOUT_KEYS}
        mine = {"acc_unit": "g", "gyro_unit": "deg/h", **scales, "gravity_mps2": gravity_mps2}
        # the caller's units to the calibration's own (its check refuses any other): exact for physical units
        raw = [None if a is None else conv(back(a, {**scales, **given}), mine)
               for a, back, conv in ((acc, units.acc_to_g, units.g_to_acc),
                                     (gyro, units.gyro_to_dph, units.dph_to_gyro))]
        ms = arrays.from_arrays(*raw, acc_unit=mine["acc_unit"], gyro_unit=mine["gyro_unit"], temp_c=temp_c,
                                **({"t_s": t_s} if t_s is not None else {"rate_hz": 1.0}),
                                meta={**scales, "latitude_deg": 0.0, "gravity_mps2": gravity_mps2}, name="x")
        meta, out, _ = fit_apply.apply(self, ms, "this calibration")
        for w in meta.get("warnings", []):  # rows outside the calibrated temperatures (kelvin named): as the command
            warnings.warn(w.replace(" of samples.csv", " of x"), stacklevel=2)
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
                              f"Calibration.apply(acc_unit={given['acc_unit']!r}): calibrated")


def _given_units(cal: calibration.Calibration, acc_unit: str | None, gyro_unit: str | None,
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


def _split(cal: calibration.Calibration, x: Any, frame: bool, sensor: str | None,
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


def _needs(cal: calibration.Calibration, temp_c: Any, t_s: Any) -> None:
    """Refuse leaving out an input the model reads (it would be taken as 0, silently)."""
    reads = {r for _, b in cal.blocks() for e in b.library_effects() for r in EFFECTS[e].reads}
    if any(b.thermal is not None for _, b in cal.blocks()):
        reads.add("temp_c")
    if temp_c is None and reads & {"temp_c", "dtemp_c"}:
        raise CalibrationError("the calibration follows temperature: give each row's temp_c= (degC)")
    if t_s is None and "t_s" in reads:
        raise CalibrationError("the calibration has a bias drifting in time: give each row's t_s= (s)")
