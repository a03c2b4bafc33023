"""`simucal.compare` and `Calibration.parameters()`'s table: the one vocabulary (simucal/report/vocabulary.py: a
sensor's M, bias and effects with their stds whatever the method, its own names beside them) as the API's tables."""
from __future__ import annotations

from typing import Any, Mapping

from simucal.api.arguments import checked
from simucal.api.tables import table
from simucal.io.calibration import Calibration
from simucal.report.vocabulary import Entry, entries, in_accelerometer_frame


@checked
def compare(calibrations: Mapping[str, Calibration]) -> Any:
    """Calibrations of one unit side by side in the one vocabulary: a row per sensor and entry (M_xx ..
    bias_z, effects), for each calibration its value and std (columns ``LABEL`` and ``LABEL std``), and
    the unit; every M in the accelerometers' own frame (module doc), so that the misalignments of a
    method that works in the table's frame line up with the norm methods'.

    Parameters
    ----------
    calibrations : mapping of str to Calibration
        ``{label: calibration}``, e.g. ``{"exact": cal1, "multiposition": cal2}``.

    Returns
    -------
    pandas.DataFrame or list of dict
        A DataFrame indexed by (sensor, name) where pandas is installed, else the rows as dicts.

    Examples
    --------
    >>> import simucal
    >>> ms = simucal.simulate(seed=1)
    >>> t = simucal.compare({m: simucal.calibrate(ms, method=m) for m in ("exact", "multiposition")})
    >>> d = t["exact"] - t["multiposition"]
    >>> bool((d.abs() < 4 * t["multiposition std"]).loc["acc"].all())
    True
    """
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    for label, cal in calibrations.items():
        for e in in_accelerometer_frame([e for s, block in cal.blocks() for e in entries(s, block)]):
            row = rows.setdefault((e.sensor, e.name), {"sensor": e.sensor, "name": e.name, "unit": e.unit})
            row[label], row[f"{label} std"] = e.value, e.std
    out = list(rows.values())
    try:
        import pandas as pd
    except ImportError:
        return out
    return pd.DataFrame(out).set_index(["sensor", "name"])


def common_table(cal: Any) -> Any:
    """`Calibration.parameters()`: every block's entries as a table."""
    return table([e for s, b in cal.blocks() for e in entries(s, b, cal.temperature_range_c)], Entry._fields)
