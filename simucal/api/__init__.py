"""The public Python API: `import simucal` and call

    read_set, MeasurementSet.from_arrays / .from_dataframe / .write, simulate, calibrate -> Calibration,
    apply, apply_set, parameters, Calibration.sensor, compare (calibrations side by side in one vocabulary),
    validate -> Validation, diagnose -> Diagnosis, noise -> Noise, save, load

on folders, numpy arrays or (with simucal[pandas]) DataFrames. Each verb is defined once, in a module of
this package (calibrating.py, validating.py, diagnosing.py, lot_reporting.py, ...); the command line calls
it, so both write the same files. A table is a pandas DataFrame where pandas is installed,
else a list of NamedTuple rows (api/tables.py).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

from simucal.errors import InputError
from simucal import io
from simucal.api.analyses import Noise, Term, noise
from simucal.api.calibrating import calibrate
from simucal.api.diagnosing import Candidate, Diagnosis, NextStep, Suggestion, diagnose, save_diagnosis
from simucal.api.simulation import montecarlo, simulate
from simucal.api.tables import table_rows
from simucal.api.applying import apply, apply_set
from simucal.api.batch import Calibrated, calibrate_each
from simucal.api.certificates import certificate
from simucal.arguments import checked
from simucal.options import CalibrateOptions
from simucal.api.imports import convert, import_instances, import_recording
from simucal.api.instances import ImuCalibration, autopilot_files, calibrate_instances
from simucal.api.instances import imus_of as imus_of  # the command line's, beside the public names
from simucal.api.lot_reporting import lot
from simucal.api.planning import design_sequence, plan, sequence_observability
from simucal.api.tools import audit, derive_model
from simucal.api.validating import Check, Validation, validate
from simucal.handheld.static_detect import DetectSettings
from simucal.api.vocabulary import Parameter, compare, parameters
from simucal.report.vocabulary import Entry
from simucal.io import calibration as _file
from simucal.io.calibration import Calibration
from simucal.io.measurement_set import MeasurementSet

if TYPE_CHECKING:
    from simucal.api.store import Store

__all__ = ["read_set", "simulate", "calibrate", "validate", "diagnose", "noise", "save", "load", "table_rows",
           "compare", "parameters", "apply", "apply_set", "import_recording", "import_instances", "calibrate_instances",
           "autopilot_files",
           "ImuCalibration", "convert", "montecarlo", "calibrate_each", "Calibrated", "plan",
           "sequence_observability", "design_sequence", "derive_model", "audit", "DetectSettings", "CalibrateOptions",
           "MeasurementSet", "Calibration", "Parameter", "Entry",
           "Validation", "Check", "Diagnosis", "Candidate", "Suggestion", "NextStep", "Noise", "Term", "lot", "Store",
           "certificate"]


def __getattr__(name: str) -> Any:
    """Store on first use: SQLAlchemy takes 0.3-0.8 s to import, which no other command should wait for."""
    if name == "Store":
        from simucal.api.store import Store
        return Store
    raise AttributeError(f"module 'simucal.api' has no attribute {name!r}")


@checked
def read_set(path: str | os.PathLike[str]) -> MeasurementSet:
    """Read a measurement set (a folder: meta.json, samples.csv, segments.csv), checked by the spec.

    Parameters
    ----------
    path : str or os.PathLike
        The set's folder.

    Returns
    -------
    MeasurementSet

    Raises
    ------
    simucal.io.MeasurementSetError
        A rule of the spec broken, naming the file, the line and the rule.

    Examples
    --------
    >>> import simucal
    >>> ms = simucal.read_set("set")  # doctest: +SKIP
    >>> ms.segments is None  # a stream: a hand-placed session  # doctest: +SKIP
    False
    """
    return io.read_set(path)


@checked
def save(path: str | os.PathLike[str], result: Calibration | Validation | Diagnosis | Noise,
         calibration_path: str | os.PathLike[str] = "thermal_calibration.json", units: str = "spec",
         written: Mapping[str, str | None] | None = None) -> None:
    """Write a result as its command writes it: a calibration file (``simucal.calibration/2``, as
    `simucal calibrate -o`), or the report of `simucal validate`, `diagnose` or `noise` (``-o``); a
    path ending in .html: the page of ``--html`` (a calibration's: a thermal one's, as `calibrate
    --thermal --html`, or a field one's, as `field-drift --html`).

    A diagnosis also writes each found term's model file beside it (<stem>_<sensor>_model.py).
    Refused (simucal.io.outputs.OutputError, one line) where path is inside or is one of the data the
    result was made from, or a file of a measurement set (meta.json, samples.csv, ...).
    calibration_path: where the calibration file is, for a thermal or field page's next command.
    written: a noise page's: the files its command wrote beside it ({"-o": noise.json, "--kalibr": imu.yaml}),
    so that the page's next step is the console's (not the command just run).
    units: a page's numbers, its tables, verdicts and plots, in the spec's units ("spec") or in SI ("si": m/s^2,
    rad/s, rad/sqrt(s), ...); a .json file is always in the spec's (docs/calibration-file.md).

    Parameters
    ----------
    path : str or os.PathLike
        The file written: .json (the calibration file or the report) or .html (the page).
    result : Calibration, Validation, Diagnosis or Noise
        What is written.
    calibration_path : str or os.PathLike
        A thermal or field page's: where the calibration file is, for its next command.
    units : {"spec", "si"}
        A page's numbers in the spec's units or in SI.
    written : mapping, optional
        A noise page's: the files its command wrote beside it.

    Examples
    --------
    >>> simucal.save("calibration.json", cal)  # doctest: +SKIP
    >>> simucal.save("validation.html", simucal.validate(cal, "other"))  # doctest: +SKIP
    """
    from simucal.io import outputs
    _refuse_suffix(path)
    # as every command: never into or over what the result was made from, nor over a set's own files
    outputs.check(_inputs(result), files={str(path): path})
    io.units.check_unit_system(units)
    if Path(path).suffix.lower() in (".html", ".htm"):
        return outputs.write_text(path, _page(result, str(calibration_path), units, written))
    if isinstance(result, _file.Calibration):
        return _file.save(path, result)
    if isinstance(result, Diagnosis):
        save_diagnosis(path, result)
        return None
    return outputs.write_text(path, json.dumps(result.report, indent=1) + "\n")


SAVED_AS = (".json", ".html", ".htm")  # the report or calibration as JSON, or its page
OTHER_FORMATS = {".params": "PX4's parameters: simucal.autopilot_files(imus, px4=PATH)",
                 ".param": "ArduPilot's parameters: simucal.autopilot_files(imus, ardupilot=PATH)",
                 ".yaml": "Kalibr's imu.yaml: Noise.kalibr_yaml()", ".yml": "Kalibr's imu.yaml: Noise.kalibr_yaml()"}


def _refuse_suffix(path: str | os.PathLike[str]) -> None:
    """Refuse a file name whose suffix names a format save does not write (it would write JSON under it)."""
    suffix = Path(path).suffix.lower()
    if suffix and suffix not in SAVED_AS:
        other = OTHER_FORMATS.get(suffix)
        raise InputError(f"{path}: save writes a result as JSON (.json) or its page (.html), not {suffix}"
                         + (f"; {other}" if other else "; name the file .json or .html"))


def _inputs(result: _file.Calibration | Validation | Diagnosis | Noise) -> list[str]:
    """The folders and files a result was made from (as its report names them)."""
    given: list[Any] = ([result.input] if not isinstance(result.input, list) else list(result.input)) \
        if isinstance(result, _file.Calibration) else [result.report.get(k) for k in ("input", "data", "calibration")]
    return [str(p) for p in given if isinstance(p, str) and Path(p).exists()]


def _page(result: _file.Calibration | Validation | Diagnosis | Noise, calibration_path: str, units: str,
          written: Mapping[str, str | None] | None = None) -> str:
    """The self-contained HTML page of a result (the commands' --html), in the unit system asked."""
    from simucal.report import units as shown
    if isinstance(result, _file.Calibration):
        if result.method == "field":
            from simucal.report.field_html import field_page
            return field_page(result, calibration_path, units)
        if not any(b.thermal is not None for _, b in result.blocks()):
            raise InputError("a page is a thermal or field calibration's (calibrate([plateaus...]) or method='field'): "
                             "save this calibration as .json; for one set's page use simucal.diagnose or "
                             "simucal.validate")
        from simucal.report.thermal_html import thermal_page
        return thermal_page(shown.calibration_in(result, units), cal_path=calibration_path)
    if isinstance(result, Validation):
        from simucal.api.validating import html_page
        return html_page(shown.validation_in(result.report, units))
    if isinstance(result, Diagnosis):
        from simucal.report.html import render
        return render(shown.diagnosis_in(result.report, units))
    from simucal.report.noise_html import noise_page
    return noise_page(result.report, units, written)


@checked
def load(path: str | os.PathLike[str]) -> Calibration:
    """Read a calibration file, checked before any of it is used.

    Parameters
    ----------
    path : str or os.PathLike
        The calibration file (any format version simucal wrote: io/calibration_versions.py).

    Examples
    --------
    >>> cal = simucal.load("calibration.json")  # doctest: +SKIP
    """
    return _file.load(path)
