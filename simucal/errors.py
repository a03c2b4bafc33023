"""The refusals: one base, SimucalError, for everything the tool refuses because of what it was given.

Its message says why and what to do; the command line prints it as one line (exit 2), and anything
else that escapes a command is a bug (exit 3, with the traceback: cli/common.py). Its kinds:
- CalibrationError: the data cannot give a trustworthy calibration (every method);
- InputError: an option or argument the tool cannot use (a simulation's scenario, a plan, a count);
  ArgumentError, one of them: a Python function's argument of the wrong type or name (also a TypeError);
- io.MeasurementSetError: a set that breaks the measurement-set spec (file, line, rule);
- io.calibration_checks.CalibrationFileError: a calibration file that cannot be read or does not fit;
- fit.catalog.ModelFileError: a user's model file that cannot be derived (file, line);
- io.outputs.OutputError: an output that would lose or corrupt a user's data;
- io.importers.ImportError_: another tool's recording that cannot be imported;
- StoreError: a calibration store that cannot be opened or written (not the tool's, a newer schema, a
  record already there), its URL shown without its password (simucal/store/).
SimucalError subclasses ValueError, so code that caught ValueError before still catches a refusal.
"""


class SimucalError(ValueError):
    """Something the tool was given that it refuses; the message says why and what to do."""


class InputError(SimucalError):
    """An option or argument the tool cannot use; the message names it and the fix."""


class ArgumentError(InputError, TypeError):
    """A public function's argument of the wrong type or name (arguments.checked): a refusal like any other,
    and a TypeError to code that catches one (what Python raises for an unknown keyword)."""


class CalibrationError(SimucalError):
    """The data cannot give a trustworthy calibration; the message says why."""

    def naming(self, path) -> "CalibrationError":
        """The same refusal, its message starting with the data's path where it does not name it."""
        return self if str(path) in str(self) else CalibrationError(f"{path}: {self}")


class StoreError(SimucalError):
    """A calibration store refused (simucal/store/): the message names the store, password hidden, and the fix."""


class NotConverged(CalibrationError):
    """An iterative fit stopped at its iteration limit: a caller may offer a method that needs no iteration."""


class CacheWarning(UserWarning):
    """A library of the cache not loaded (the numpy module runs) or rebuilt, and why: one line (io/cache.py warns
    it, the command line prints it as a line)."""


class LogWarning(UserWarning):
    """What a log's import kept but a user must know (a cut end, gaps, a low rate, a magnitude far from g): one
    line naming the file; also in the set's meta.json `warnings` (io/logs.py)."""
