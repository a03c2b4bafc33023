"""The API's tables: a pandas DataFrame where pandas is installed (simucal[pandas]), else a list of
NamedTuple rows (the same columns, each row's fields by name), so that the API works on numpy alone."""
from __future__ import annotations

from typing import Any, NamedTuple, Sequence


def table(rows: Sequence[NamedTuple], columns: Sequence[str]) -> Any:
    """rows as a DataFrame with these columns (the rows' fields; also when there are no rows), or the
    list itself without pandas."""
    try:
        import pandas as pd
    except ImportError:  # pandas is an extra: the rows are the table
        return list(rows)
    return pd.DataFrame(list(rows), columns=list(columns))


def rows(t: Any) -> list:
    """A table's rows as NamedTuples, whichever type the API gave (``simucal.table_rows``): for code that
    runs with pandas and without.

    Parameters
    ----------
    t : pandas.DataFrame or list of NamedTuple
        A table of the API (``Calibration.parameters()``, ``Validation.checks``, ...).

    Returns
    -------
    list of NamedTuple
        One per row, its fields by the table's columns.

    Examples
    --------
    >>> import simucal
    >>> p = simucal.table_rows(simucal.calibrate(simucal.simulate(seed=1)).parameters())
    >>> p[0].sensor, p[0].name, p[0].unit
    ('acc', 'dK_x', '1')
    """
    if hasattr(t, "itertuples"):
        return list(t.itertuples(index=False))
    return list(t)
