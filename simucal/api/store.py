"""A lab's calibration store in Python: `simucal.Store(url)`, DataFrames out (simucal/store/)."""
from __future__ import annotations

import os
from collections import namedtuple
from typing import Any, Mapping, Sequence

from simucal.arguments import checked
from simucal.api.tables import table
from simucal.io import calibration as _file
from simucal.store import CalibrationStore
from simucal.report.unit_history import History
from simucal.store.history import lines as history_lines  # noqa: F401 (the command line's words)
from simucal.store.queries import PARAMETER_COLUMNS, RECORD_COLUMNS
from simucal.store.schema import RecordRow, local_file

TREND_COLUMNS = ("name", "own_name", "unit", "calibrations", "last_value", "last_std", "slope_per_year", "slope_std",
                 "chi2", "dof", "p_value", "expected_utc", "earliest_utc")
CHANGE_COLUMNS = ("record", "calibrated_utc", "name", "own_name", "unit", "value_change_since_last", "z_since_last",
                  "value_change_since_first", "z_since_first", "flagged")


def history_page(report: History) -> str:
    """The unit's page of `Store.history`'s report (`simucal history --html`; report/history_html.py)."""
    from simucal.report.history_html import history_page as page  # matplotlib: only where a page is asked for
    return page(report)


def _table(rows: Sequence[Mapping[str, object]], columns: Sequence[str]) -> Any:
    """rows (dicts whose keys are `columns`, in that order: the query's) as the API's table."""
    row = namedtuple("Row", columns)  # type: ignore[misc]  # the columns are the query's
    assert not rows or tuple(rows[0]) == tuple(columns), (tuple(rows[0]), columns)
    return table([row._make(r.values()) for r in rows], columns)


class Store:
    """The calibration store at `url`: a SQLite file (a path, or ``sqlite:///path``) or a SQL server
    (``postgresql://user@host/db``, with ``simucal[store-postgres]``). Created on the first `add`; a record is
    never replaced; a database that is not simucal's, or of a newer schema, is refused (StoreError), its URL
    shown without its password.

    Examples
    --------
    >>> import simucal
    >>> store = simucal.Store("lab.db")  # doctest: +SKIP
    >>> store.add("cal.json", station="bench 2")  # doctest: +SKIP
    1
    >>> store.records(serial="SN-0001")[["id", "calibrated_utc", "method"]]  # doctest: +SKIP
    """

    @checked
    def __init__(self, url: str | os.PathLike[str]):
        self._store = CalibrationStore(os.fspath(url))

    def __repr__(self) -> str:
        store = self.__dict__.get("_store")  # an instance never initialised shows as one
        return f"Store({store.shown!r})" if store else "Store(?)"

    @checked
    def add(self, calibration: str | os.PathLike[str] | _file.Calibration, serial: str | None = None,
            station: str | None = None, time: str | None = None) -> int:
        """Record a calibration (a file, byte for byte; or a Calibration, as `simucal.save` would write it:
        `simucal store add`, `calibrate --store`); its record id.

        serial: the unit's (default the file's unit_serial); station: where (default this host's name);
        time: when it was calibrated, UTC (``2026-03-01T09:30:00Z``; default now)."""
        if isinstance(calibration, _file.Calibration):
            where = f"the calibration of {calibration.input}"
            return self._store.add_bytes(_file.dumps(calibration).encode(), where, serial, station, time)
        return self._store.add(calibration, serial, station, time)

    @checked
    def records(self, serial: str | None = None, method: str | None = None, model: str | None = None,
                station: str | None = None, since: str | None = None, until: str | None = None) -> Any:
        """The records that match (each given filter; since and until bound calibrated_utc), in time order: a
        DataFrame (columns id, serial, calibrated_utc, recorded_utc, station, method, model, tool_version,
        input_sha256, file_sha256)."""
        return _table(self._store.records(serial=serial, method=method, model=model, station=station, since=since,
                                          until=until), RECORD_COLUMNS)

    @checked
    def parameters(self, serial: str | None = None, method: str | None = None, model: str | None = None,
                   station: str | None = None, since: str | None = None, until: str | None = None) -> Any:
        """Every entry of the one vocabulary of the matching records with its std: a DataFrame (calibration_id,
        serial, calibrated_utc, sensor, name (M_xx, bias_x, an effect's id), value, std, unit, own_name (the
        method's own parameter of it: dK_x, b_x))."""
        return _table(self._store.parameters(serial=serial, method=method, model=model, station=station, since=since,
                                             until=until), PARAMETER_COLUMNS)

    @staticmethod
    @checked
    def local_file(url: str | os.PathLike[str]) -> str | None:
        """The SQLite file a store URL names (an input: no command writes over it); None for a server's database."""
        path = local_file(os.fspath(url))
        return None if path is None else str(path)

    @checked
    def file(self, record: int) -> bytes:
        """Record `record`'s calibration file, byte for byte as it was recorded."""
        found = self._store.files([record])
        if record not in found:
            raise self._no_record(record)
        return found[record]

    @checked
    def record(self, record: int) -> RecordRow:
        """Record `record`'s row as records() gives it (id, serial, calibrated_utc, station, ...), as a dict."""
        rows = self._store.records(record_id=record)
        if not rows:
            raise self._no_record(record)
        return rows[0]

    def _no_record(self, record: int) -> Exception:
        from simucal.errors import StoreError
        return StoreError(f"{self._store.shown}: no record {record}; Store.records() lists them")

    @checked
    def history(self, serial: str, limits: str | os.PathLike[str] | None = None,
                spec: str | os.PathLike[str] | None = None) -> History:
        """Unit `serial`'s history as `simucal history SERIAL -o history.json` writes it: each calibration's change
        since the last and the first in std, the flags and why (simucal/store/history.py), and its trend with the
        due date by `spec` (a limits.json bounding each parameter's value; simucal/store/trend.py).

        limits: a limits.json bounding each parameter's change since the first calibration, in its unit."""
        return self._store.history(serial, limits, spec)

    @checked
    def trend(self, serial: str, spec: str | os.PathLike[str] | None = None) -> Any:
        """Each parameter's trend over the unit's calibrations as a DataFrame: the weighted line's slope per year
        with its std, chi2 of the line on dof (from three calibrations), and the dates at which the line
        (expected_utc) and its k = 2 band (earliest_utc) first reach the spec's limits (simucal/store/trend.py)."""
        rows = [{"name": p["name"], "own_name": p.get("own_name"), "unit": p["unit"], "calibrations": len(p["values"]),
                 "last_value": p["values"][-1], "last_std": p["stds"][-1], **{k: p.get(k) for k in TREND_COLUMNS[6:]}}
                for p in self._store.history(serial, spec=spec)["trend"]["parameters"]]
        return _table(rows, TREND_COLUMNS)

    @checked
    def changes(self, serial: str, limits: str | os.PathLike[str] | None = None) -> Any:
        """The history as a DataFrame: one row per later calibration and parameter, its change since the last and
        since the first (value and z, the change in the combined std) and whether its record is flagged."""
        rows = []
        for e in self._store.history(serial, limits)["records"]:
            first = {p["name"]: p for p in (e.get("since_first") or e.get("since_last") or {"parameters": []})[
                "parameters"]}
            for p in (e.get("since_last") or {"parameters": []})["parameters"]:
                f = first.get(p["name"], p)
                rows.append({"record": e["id"], "calibrated_utc": e["calibrated_utc"], "name": p["name"],
                             "own_name": p["own_name"], "unit": p["unit"], "value_change_since_last": p["change"],
                             "z_since_last": p["z"], "value_change_since_first": f["change"], "z_since_first": f["z"],
                             "flagged": e["flagged"]})
        return _table(rows, CHANGE_COLUMNS)

    @checked
    def close(self) -> None:
        """Let go of the database's connections."""
        self._store.close()
