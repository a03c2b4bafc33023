"""The lot report in Python: `simucal lot CAL_FOLDER` as a function (simucal/lot_report.py)."""
from __future__ import annotations

import os

from simucal.api.arguments import checked
from simucal.io import records
from simucal.lot_report import lot as _lot


@checked
def lot(folder: str | os.PathLike, limits: str | os.PathLike | None = None) -> records.JSONObject:
    """The lot report of the calibration files in a folder: the dict `simucal lot -o lot.json` writes.

    Parameters
    ----------
    folder : str or os.PathLike
        A folder of calibration files, one per unit (``simucal calibrate DIR1 DIR2 ... -o FOLDER``);
        other files in it are named under ``not_calibrations``.
    limits : str or os.PathLike, optional
        A limits.json (format ``simucal.limits/1``): spec limits per parameter, in the calibrations' units.

    Returns
    -------
    dict
        ``verdict`` (lines: how many units pass, which fail and why), ``next`` (the command to run next),
        ``units`` (each unit's status, model tests, limits broken, outliers), ``groups`` (per method and
        model, each parameter's median, spread, spread of units, values, stds and z), ``drift`` (between
        calibrations of one unit_serial) and ``not_calibrations``.

    Raises
    ------
    simucal.errors.CalibrationError
        A folder with no calibration file, or a bad limits file, in one line naming the file and entry.

    Examples
    --------
    >>> import simucal.api
    >>> report = simucal.api.lot("cals")  # doctest: +SKIP
    >>> report["verdict"][0]  # doctest: +SKIP
    '11 of 12 units pass, 0 fail, 1 flagged'
    """
    return _lot(folder, limits)
