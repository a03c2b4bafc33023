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
    """A table's rows as NamedTuples, whichever type `table` gave (DataFrame.itertuples names them)."""
    if hasattr(t, "itertuples"):
        return list(t.itertuples(index=False))
    return list(t)
