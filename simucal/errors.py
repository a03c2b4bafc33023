"""The refusal every method raises when the data cannot give a trustworthy calibration.

Its message says why and what to do; the command line prints it as one line (exit 2).
Reading errors of the measurement-set spec are io.MeasurementSetError (file, line, rule);
calibration files' are calibration.CalibrationFileError.
"""


class CalibrationError(ValueError):
    """The data cannot give a trustworthy calibration; the message says why."""

    def naming(self, path) -> "CalibrationError":
        """The same refusal, its message starting with the data's path where it does not name it."""
        return self if str(path) in str(self) else CalibrationError(f"{path}: {self}")


class NotConverged(CalibrationError):
    """An iterative fit stopped at its iteration limit: a caller may offer a method that needs no iteration."""
