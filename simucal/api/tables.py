"""The API's tables: a pandas DataFrame where pandas is installed (simucal[pandas]), else a list of
rows (NamedTuples, or a diagnosis's Candidate records: the same columns, each row's fields by name), so that
the API works on numpy alone."""
from __future__ import annotations

from typing import Any, Sequence

from simucal.arguments import checked


def table(rows: Sequence[Any], columns: Sequence[str]) -> Any:
    """rows as a DataFrame with these columns (the rows' attributes of those names; also when there are no
    rows), or the list itself without pandas."""
    try:
        import pandas as pd
    except ImportError:  # pandas is an extra: the rows are the table
        return list(rows)
    return pd.DataFrame([[getattr(r, c) for c in columns] for r in rows], columns=list(columns))


class TableOf:
    """A result's table, built from its rows (the field rows_field) when first read: pandas is imported
    then, not by the commands, which write the report and never read the table (0.4 s a process)."""

    def __init__(self, rows_field: str, columns: Sequence[str]):
        self.rows_field, self.columns = rows_field, columns

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        made = obj.__dict__.setdefault("_tables", {})
        if self.name not in made:
            made[self.name] = table(getattr(obj, self.rows_field), self.columns)
        return made[self.name]


@checked
def table_rows(t: Any) -> list[Any]:
    """A table's rows, each with its fields by name, whichever type the API gave (``simucal.table_rows``): for
    code that runs with pandas and without.

    Parameters
    ----------
    t : pandas.DataFrame or list of NamedTuple
        A table of the API (``simucal.parameters(cal)``, ``Validation.checks``, ...).

    Returns
    -------
    list of NamedTuple (or of Candidate, a diagnosis's without pandas)
        One per row, its fields by the table's columns.

    Examples
    --------
    >>> import simucal
    >>> p = simucal.table_rows(simucal.parameters(simucal.calibrate(simucal.simulate(seed=1))))
    >>> p[0].sensor, p[0].name, p[0].unit, p[0].own_name
    ('acc', 'M_xx', '1', 'dK_x')
    """
    if hasattr(t, "itertuples"):
        return list(t.itertuples(index=False))
    return list(t)
