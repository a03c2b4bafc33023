"""simucal: strapdown IMU calibration (turntable and field), from derived models.

Runtime package: reads measurement sets (spec measurement-set.md), simulates,
calibrates, audits. It imports the generated modules (simucal.generated) and
never SymPy on the hot path.
"""
from simucal.version import __version__

# The Python API (simucal/api/), imported on first use so that `import simucal` and the command
# line's start stay light: simucal.read_set, simucal.calibrate, ... (README, "Python API").
_API = ("read_set", "simulate", "calibrate", "validate", "diagnose", "noise", "save", "load", "table_rows", "compare",
        "parameters", "apply", "apply_set", "import_recording", "import_instances", "calibrate_instances",
        "autopilot_files", "ImuCalibration", "convert",
        "montecarlo", "calibrate_each", "Calibrated", "plan", "sequence_observability", "design_sequence",
        "derive_model", "audit", "DetectSettings", "CalibrateOptions",
        "MeasurementSet", "Calibration", "Parameter", "Entry", "Validation", "Check", "Diagnosis", "Candidate",
        "Suggestion", "NextStep", "Noise", "Term", "lot", "Store", "certificate")
__all__ = ["__version__", "read_set", "simulate", "calibrate", "validate", "diagnose", "noise", "save", "load",
           "table_rows", "compare", "parameters", "apply", "apply_set", "import_recording", "import_instances",
           "calibrate_instances", "autopilot_files",
           "ImuCalibration", "convert", "montecarlo", "calibrate_each", "Calibrated", "plan",
           "sequence_observability", "design_sequence", "derive_model", "audit", "DetectSettings", "CalibrateOptions",
           "MeasurementSet", "Calibration", "Parameter", "Entry", "Validation", "Check",
           "Diagnosis", "Candidate", "Suggestion", "NextStep", "Noise", "Term", "lot", "Store",
           "certificate"]  # the public names (_API, spelt out for type checkers)
TYPE_CHECKING = False  # typing's constant without importing typing (2 ms); type checkers read it as True
if TYPE_CHECKING:
    from simucal.api import (CalibrateOptions, Calibrated, Calibration, Candidate, Check, DetectSettings,  # noqa: F401
                             Diagnosis, Entry, NextStep, Suggestion, apply, apply_set, parameters,
                             MeasurementSet, Noise, Parameter, Store, Term, Validation, audit, calibrate,
                             calibrate_each, compare, convert, derive_model, diagnose,
                             import_instances, import_recording, load, calibrate_instances, autopilot_files,
                             ImuCalibration, certificate, lot, montecarlo, noise, plan, read_set, save,
                             sequence_observability, design_sequence, simulate, table_rows, validate)


def __getattr__(name):
    if name in _API:
        from simucal import api
        return getattr(api, name)
    raise AttributeError(f"module 'simucal' has no attribute {name!r}")


def __dir__():  # a notebook's completion lists the API (not the module's own machinery)
    return sorted([*(n for n in globals() if n.startswith("__") or n in __all__), *_API])
