"""The calibration file: one typed object (`Calibration`), written by every method, read back by `apply`.

Format `simucal.calibration/2` (JSON; `Calibration.to_json` / `from_json`, `save` / `load`).
Units everywhere: accelerometer in g, gyro in deg/h, after dividing the raw outputs by the
nominal scale factors of the data's meta.json (so for `counts` a raw ADC offset shows in
`bias` as offset / counts_per_g, in g). Top level:

    format, method, input, input_sha256 (lists for a thermal calibration: one per plateau)
    samples_sha256  a digest of each segment's sensor outputs (MeasurementSet.sample_digests):
                validate finds the calibration's own rows by them, whatever else was edited
    layout      the data's units and nominal scale factors; apply refuses data
                with another layout (another sensor or unit)
    formula     how an output relates to its input (below), per sensor
    acc, gyro   one block each (absent when the data had none)
    unification C_b^d and how it was found (turntable gyro)
    t_ref_c, temperature_range_c   where the data have temp_c: the reference
                temperature T_ref of temperature terms (they read temp_c - T_ref,
                so bias and M are the unit's at T_ref) and the range calibrated
    not_calibrated, warnings, and what the method reports (consistency, field, ...)

Each sensor block (`SensorBlock`):

    model        the generated model of the forward function h ("affine" for
                 y = M u + bias), model_source "built-in" or the user's file
    effects      {id: {value, std, unit, meaning}}: candidate effects added
                 (a model file's own terms carry term_of, the model's name)
    params, std, param_units   every parameter of h (std inflated by the misfit
                 when the model fails; std_raw then holds the unscaled ones)
    M, bias      the linear part in frame b: output = M u_b + bias + nonlinear terms
    C_b_model    the rotation from b to the model's own frame (gyro: C_b^d), so
                 output = h(C_b_model u_b, p)
    thermal      a thermal calibration's polynomials (fit/thermal.py)
    residual_rms, residual_unit, chi2, dof, p_value, verdict (passes, fails, untested
                 or nominal: SensorBlock.verdict), and what the method reports
                 (test, noise, cross_validation, auto, ...; a norm fit's
                 `covariance` {names, matrix} of its parameters, unscaled by a misfit,
                 which validate propagates into its floors)

Direction: the calibration maps input to output (the sensor model). `apply`
inverts it: u_b = C_b_model^T h^-1(output), Newton per sample for nonlinear terms.
The checks of a file read from disk are in calibration_checks.py.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, cast
from pathlib import Path

import numpy as np

from simucal.arguments import checked
from simucal.errors import CalibrationError
from simucal.io import MeasurementSet, autopilot, outputs, read_meta, records
from simucal.io.autopilot import AutopilotFile
from simucal.io.calibration_checks import CalibrationFileError, check_file, layout
from simucal.io.calibration_versions import upgraded
from simucal.io.details import SensorDetails, as_details
from simucal.io.text_files import unique_keys
from simucal.notebook import html_card

FORMAT = "simucal.calibration/2"
FORMULA = {
    "acc": "a_g = a_raw / nominal scale (meta.json); a_g = h_acc(f_b, p) = M f_b + bias + effects; "
           "f_b: specific force in the accelerometer frame b, g",
    "gyro": "w_out = w_raw / nominal scale; w_out = h_gyro(C_b_model w_b, p) = M w_b + bias + effects; "
            "w_b: angular rate in b, deg/h; g-sensitivity terms take the specific force in the model's frame, g",
}
UNITS = {"acc": "g", "gyro": "deg/h", "angles": "rad"}
# The one level at which a model fails its test (fit/results.ModelTest.fails): the file's verdict, the console's
# THE MODEL FAILS, the std inflation, the advice, diagnose's gate and `--add auto` all use it. 1e-3 rather than
# 0.01: a lot of units is calibrated set after set, two tests each, so at 0.01 one good unit in 50 would be called
# failing, its stds inflated and an effect advised; every missing effect this tool was measured on fails far
# below 1e-3 (the planted ones at p < 1e-6), and the thermal fit's model test uses the same level.
ALPHA = 1e-3
SENSORS = ("acc", "gyro")
MOVED = {"apply": "simucal.apply(cal, x, ...)", "apply_to_set": "simucal.apply_set(cal, data, ...)",
         "parameters": "simucal.parameters(cal, ...)"}  # methods that need the floors above io


@dataclass
class EffectValue:
    """One added effect: a library effect (by its id), or a term of a user's model file beyond the
    baseline (by its parameter name; term_of the model's name)."""
    value: float
    std: float
    unit: str
    meaning: str
    term_of: str | None = None

    def to_json(self) -> records.EffectRecord:
        return {"value": float(self.value), "std": float(self.std), "unit": self.unit, "meaning": self.meaning,
                **({"term_of": self.term_of} if self.term_of else {})}

    @classmethod
    def from_json(cls, d: dict) -> EffectValue:
        return cls(d["value"], d.get("std", float("nan")), d.get("unit", ""), d.get("meaning", ""), d.get("term_of"))


def _plain(x):
    """JSON's view of a value: arrays as lists."""
    return np.asarray(x).tolist() if isinstance(x, np.ndarray) else x


@dataclass(eq=False)
class SensorBlock:
    """One sensor's calibration (module doc). details: what the method reports about its fit,
    written beside the fields (test, noise, auto, moves, ...)."""
    model: str                 # a generated model's name, or "affine"
    M: np.ndarray              # (3, 3), frame b
    bias: np.ndarray           # (3,), bias_unit
    bias_unit: str
    effects: dict[str, EffectValue] = field(default_factory=dict)
    model_source: str = "built-in"
    params: dict[str, float] = field(default_factory=dict)
    std: dict[str, records.Std] = field(default_factory=dict)
    param_units: dict[str, str] = field(default_factory=dict)
    C_b_model: np.ndarray | None = None
    residual_rms: float | None = None
    residual_unit: str | None = None
    chi2: float | None = None
    dof: float | None = None
    p_value: float | None = None
    description: str | None = None   # a method without a generated model: what its affine model is
    thermal: records.Thermal | None = None
    nominal: bool = False            # left at the nominal scale factors (not calibrated)
    details: SensorDetails = field(default_factory=lambda: SensorDetails())  # mypy 1.10 takes no class here

    def __post_init__(self):
        self.M, self.bias = np.asarray(self.M, float), np.asarray(self.bias, float)
        if self.C_b_model is not None:
            self.C_b_model = np.asarray(self.C_b_model, float)

    @property
    def C(self) -> np.ndarray:
        """C_b_model, the identity where the model's frame is b."""
        return np.eye(3) if self.C_b_model is None else self.C_b_model

    def library_effects(self) -> tuple[str, ...]:
        """The library effect ids the model adds (its effects less a model file's own terms)."""
        return tuple(e for e, v in self.effects.items() if not v.term_of)

    ALWAYS = ("residual_rms", "residual_unit", "chi2", "dof", "p_value")  # written as null where there is no test

    def __repr__(self) -> str:
        """One line (the dataclass's printed every array and record, 6 kB): the model, its test and verdict, the
        effects added; the numbers are in the fields and the calibration's parameters()."""
        test = ("no test" if self.p_value is None
                else f"chi2 {self.chi2:.4g} on {self.dof:g} dof, p = {self.p_value:.2g}")
        effects = f"; effects {', '.join(self.effects)}" if self.effects else ""
        return f"<SensorBlock {self.model}: {self.verdict} ({test}){effects}; bias in {self.bias_unit}>"

    @property
    def verdict(self) -> str:
        """The model test's verdict, written as the block's `verdict`: "passes", "fails" (p below
        ALPHA: the console says THE MODEL FAILS), "untested" (no test: an affine method without a
        noise estimate) or "nominal" (not calibrated, kept at the nominal scale factors)."""
        if self.nominal:
            return "nominal"
        if self.p_value is None:
            return "untested"
        return "fails" if self.p_value < ALPHA else "passes"

    def to_json(self) -> records.JSONObject:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "details":
                out.update({k: _plain(x) for k, x in v.items()})
            elif f.name == "effects":
                out["effects"] = {e: x.to_json() for e, x in v.items()}
            elif f.name == "nominal":
                if v:
                    out["nominal"] = True
            elif f.name in ("params", "param_units"):
                if v:  # an affine block has none
                    out[f.name] = dict(v)
            elif v is not None or f.name in self.ALWAYS:
                out[f.name] = _plain(v)
        out["verdict"] = self.verdict
        return out

    @classmethod
    def from_json(cls, d: dict, sensor: str) -> SensorBlock:
        names = {f.name for f in fields(cls)} - {"details", "effects"}
        given = {k: v for k, v in d.items() if k in names}
        given.setdefault("bias_unit", UNITS[sensor])  # files written before it was a field may lack it
        details = {k: v for k, v in d.items() if k not in names and k not in ("effects", "verdict")}
        return cls(**given, effects={e: EffectValue.from_json(x) for e, x in d.get("effects", {}).items()},
                   details=as_details(details))


@dataclass(eq=False)
class Calibration:
    """A calibration of one unit (simucal.Calibration; the file: module doc): per sensor the model
    output = h(input, p), its parameters with their stds, the test of the model and what the method
    reports; details: what the method reports beyond the blocks (consistency, unification's checks,
    static_detection, field, excluded_segments, ...).

    Returned by `simucal.calibrate` and `simucal.load`; written by `simucal.save`; applied by
    `simucal.apply` (arrays, DataFrames) and `simucal.apply_set` (a measurement set); its parameters
    tabled by `simucal.parameters`.

    Examples
    --------
    >>> import simucal
    >>> cal = simucal.load("calibration.json")  # doctest: +SKIP
    >>> cal.acc.p_value, cal.sensors  # doctest: +SKIP
    (0.41, ['acc', 'gyro'])
    """
    method: str
    input: str | list[str]
    input_sha256: str | list[str | None] | None  # None: a hand-edited file, or a set made without its digest (simulate)
    layout: records.Layout
    acc: SensorBlock | None = None
    gyro: SensorBlock | None = None
    t_ref_c: float | None = None
    temperature_range_c: list[float] | None = None
    unification: records.Unification | None = None
    not_calibrated: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    details: records.CalibrationDetails = field(default_factory=lambda: records.CalibrationDetails())
    format: str = FORMAT
    samples_sha256: list[str] | None = None  # MeasurementSet.sample_digests of the data; None: an older file

    @property
    def sensors(self) -> list[str]:
        """The sensors calibrated (or kept at nominal), as the layout names them."""
        return list(self.layout["sensors"])

    def blocks(self) -> list[tuple[str, SensorBlock]]:
        """(sensor, block) for each block present."""
        return [(s, getattr(self, s)) for s in SENSORS if getattr(self, s) is not None]

    def __repr__(self) -> str:  # a notebook cell shows this: the file's every array is for parameters()
        tested = ", ".join(f"{s} (p = {b.p_value:.2g})" if b.p_value is not None else s for s, b in self.blocks())
        return f"<simucal.Calibration {self.method!r} of {self.input!r}: {tested or 'no sensor'}>"

    def _repr_html_(self) -> str:
        """A notebook's view: the method, the input, and per sensor its model, test and verdict."""
        rows: list[tuple[str, Any]] = [("method", self.method), ("input", self.input)]
        for s, b in self.blocks():
            test = "no test" if b.p_value is None else f"chi2 {b.chi2:.4g} on {b.dof:g} dof, p = {b.p_value:.2g}"
            rows.append((s, f"{b.model}: {b.verdict} ({test}); residual rms {b.residual_rms:.3g} {b.residual_unit}"
                         if b.residual_rms is not None else f"{b.model}: {b.verdict} ({test})"))
        rows += [(f"{s} not calibrated", why) for s, why in self.not_calibrated.items()]
        return html_card("simucal.Calibration", rows)

    if not TYPE_CHECKING:  # a type checker then still refuses cal.apply and any misspelt attribute
        def __getattr__(self, name: str) -> Any:
            """A method that became a function of the API (docs/api.md): named with its new call."""
            if name in MOVED:
                raise AttributeError(f"Calibration.{name} is now {MOVED[name]}")
            raise AttributeError(f"'Calibration' object has no attribute {name!r}")

    @checked
    def sensor(self, name: str) -> SensorBlock:
        """The block of sensor `name` ("acc" or "gyro"), never None: refused (CalibrationError) where this
        calibration holds none, saying why (`not_calibrated`).

        Examples
        --------
        >>> cal.sensor("acc").p_value  # doctest: +SKIP
        0.41
        """
        block: SensorBlock | None = getattr(self, name, None) if name in SENSORS else None
        if block is None:
            why = self.not_calibrated.get(name)
            raise CalibrationError(f"this calibration ({self.method}) holds no {name!r} block"
                                   + (f": {why}" if why
                                      else f"; its sensors: {', '.join(s for s, _ in self.blocks())}"))
        return block

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
        meta = data.meta if isinstance(data, MeasurementSet) else read_meta(Path(data))
        return autopilot.files([(self, meta)], px4, ardupilot)

    def drop_sensor(self, sensor: str, why: str) -> None:
        """The data hold `sensor` but the method could not calibrate it: no block, said under not_calibrated."""
        setattr(self, sensor, None)
        self.layout["sensors"] = [s for s in self.layout["sensors"] if s != sensor]
        self.not_calibrated[sensor] = why

    def to_json(self) -> records.JSONObject:
        out: dict[str, Any] = {"format": self.format, "method": self.method, "input": self.input,
                               "input_sha256": self.input_sha256,
               "layout": self.layout, "formula": {s: FORMULA[s] for s in self.sensors},
               "units": UNITS}
        for s, b in self.blocks():
            out[s] = b.to_json()
        residual = {s: b.residual_rms for s, b in self.blocks() if b.residual_rms is not None}
        if residual:
            out["residual_rms"] = residual
        for k in ("samples_sha256", "t_ref_c", "temperature_range_c", "unification"):
            if getattr(self, k) is not None:
                out[k] = getattr(self, k)
        if self.not_calibrated:
            out["not_calibrated"] = self.not_calibrated
        if self.warnings:
            out["warnings"] = self.warnings
        out.update({k: _plain(v) for k, v in self.details.items()})
        return out

    @classmethod
    def from_json(cls, d: dict) -> Calibration:
        """The file's dict (checked by calibration_checks.check_file) as the object; a block the layout
        does not name is left out (check_layout then refuses data that have that sensor)."""
        derived = {"formula", "units", "residual_rms"}  # written from the layout and the blocks
        names = {f.name for f in fields(cls)} - {"details", "acc", "gyro"}
        given = {k: v for k, v in d.items() if k in names}
        for k, default in (("method", "unknown"), ("input", ""), ("input_sha256", None)):  # hand-edited files
            given.setdefault(k, default)
        blocks: dict[str, Any] = {s: SensorBlock.from_json(d[s], s) for s in d["layout"]["sensors"]}  # acc, gyro
        return cls(**given, **blocks,
                   details=cast(records.CalibrationDetails,  # check_file has read it: its keys are the file's
                                {k: v for k, v in d.items() if k not in names | derived | set(SENSORS)}))


def header(method: str, ms) -> Calibration:
    """A calibration of set ms by `method`, its blocks still to fill."""
    cal = Calibration(method, str(ms.path), ms.sha256, layout(ms), samples_sha256=ms.sample_digests())
    if ms.t_ref_c is not None:  # temperature terms read dtemp_c = temp_c - t_ref_c; apply takes it from here
        temp = ms.samples["temp_c"]
        cal.t_ref_c, cal.temperature_range_c = ms.t_ref_c, [float(np.min(temp)), float(np.max(temp))]
    return cal


def save(path, cal: Calibration) -> None:
    path = Path(path)
    if not path.parent.is_dir():
        raise CalibrationFileError(f"{path}: the folder {path.parent} does not exist")
    outputs.write_text(path, dumps(cal))


def dumps(cal: Calibration) -> str:
    """The calibration file's text, as save writes it (a store records these bytes)."""
    return json.dumps(cal.to_json(), indent=2, default=float) + "\n"


def load(path) -> Calibration:
    """A calibration file, checked before any of it is used (calibration_checks.check_file); a file of an
    earlier format is read as this one (io/calibration_versions.py)."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationFileError(f"{path}: not a readable calibration file ({str(e)[:120]})") from None
    return loads(text, path)


def loads(text: str, path) -> Calibration:
    """A calibration file's text (from a file, or a store's record), checked as load checks it; path: what the
    messages name."""
    try:
        d = json.loads(text, object_pairs_hook=unique_keys)
    except ValueError as e:  # bad JSON, a key twice, a number of 5000 digits
        raise CalibrationFileError(f"{path}: not a readable calibration file ({str(e)[:120]})") from None
    except RecursionError:
        raise CalibrationFileError(f"{path}: not a calibration file: nested too deep to read (objects within each "
                                   "other thousands of levels down); calibrate again") from None
    if not isinstance(d, dict):
        raise CalibrationFileError(f"{path}: format None, expected {FORMAT!r}")
    d = upgraded(path, d, FORMAT)  # a file of an earlier format, read as this one
    check_file(path, d)
    try:
        return Calibration.from_json(d)
    except (TypeError, ValueError, KeyError, AttributeError) as e:  # a hand edit the checks did not foresee
        raise CalibrationFileError(f"{path}: not a calibration file this version can read ({type(e).__name__}: "
                                   f"{e}); calibrate again rather than edit a calibration") from None
