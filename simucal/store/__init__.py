"""A lab's calibration store: every unit's calibrations in one database, behind one small interface.

    CalibrationStore(url).add(CAL.json, serial=, station=, calibrated_utc=) -> record id
    .records(serial=, method=, model=, station=, since=, until=), .parameters(...)  -> rows
    .calibrations(...) -> (name, Calibration) for `simucal lot`;  .history(serial) -> the unit's history and trend

url: a SQLite file (a plain path or sqlite:///path; the standard library's driver) or any SQL server
SQLAlchemy reaches (postgresql://user@host/db through psycopg). schema.py holds the tables, opening.py how a
store is opened (its schema checked and migrated), records.py a record and its insertion, queries.py the reads,
history.py a unit's changes, trend.py its drift and due date.
The engine is opened (and the schema checked, migrated or created) on first use, once per object.
"""
from __future__ import annotations

from pathlib import Path

from simucal.errors import StoreError
from simucal.io.calibration import Calibration, loads
from simucal.report.unit_history import History
from simucal.store import history as _history
from simucal.store import queries, records
from simucal.store.opening import open_engine
from simucal.store.schema import ParameterRow, RecordRow, shown


class CalibrationStore:
    """The store at `url` (module doc); its URL as shown (password hidden) is `.shown`."""

    def __init__(self, url: str):
        self.url, self.shown = str(url), shown(str(url))
        self._engine = None
        self._created = False

    def _db(self, create: bool = False):
        if self._engine is None or (create and not self._created):
            if self._engine is not None:
                self._engine.dispose()
            self._engine = open_engine(self.url, create)
            self._created = create
        return self._engine

    def close(self) -> None:
        """Let go of its connections (a later call opens them again)."""
        if self._engine is not None:
            self._engine.dispose()
            self._engine = None

    def add(self, path, serial: str | None = None, station: str | None = None,
            calibrated_utc: str | None = None) -> int:
        """Record the calibration file at path (the store created where the database is empty); its record id."""
        if not Path(path).is_file():
            raise StoreError(f"{path}: no such calibration file")
        return self.add_bytes(Path(path).read_bytes(), path, serial, station, calibrated_utc)

    def add_bytes(self, raw: bytes, where, serial: str | None = None, station: str | None = None,
                  calibrated_utc: str | None = None) -> int:
        """Record a calibration file's bytes (io.calibration.dumps of one not yet on disk); where: its name."""
        row, params = records.record_of(raw, where, serial, station, calibrated_utc)
        return records.insert(self._db(create=True), self.url, row, params, where)

    def records(self, **where) -> list[RecordRow]:
        """queries.records: the records matching serial, method, model, station, since, until."""
        return queries.records(self._db(), self.url, **where)

    def parameters(self, **where) -> list[ParameterRow]:
        """queries.parameters: the parameters' rows of the records matching `where`."""
        return queries.parameters(self._db(), self.url, **where)

    def files(self, ids) -> dict[int, bytes]:
        """The calibration files of records `ids`, byte for byte."""
        return queries.files(self._db(), self.url, ids)

    def calibrations(self, **where) -> list[tuple[str, Calibration]]:
        """The matching records as (name, calibration), the name `<serial>_<calibrated_utc>_<id>.json` sorting as
        the times do (so `simucal lot` takes each unit's last)."""
        recs = self.records(**where)
        raw = self.files(r["id"] for r in recs)
        return [(f"{r['serial']}_{r['calibrated_utc']}_{r['id']:08d}.json",
                 loads(raw[r["id"]].decode("utf-8"), f"{self.shown} record {r['id']}")) for r in recs]

    def history(self, serial: str, limits=None, spec=None) -> History:
        """history.history: the unit's calibrations, their changes and flags, and its trend by the spec."""
        return _history.history(self._db(), self.url, serial, limits, spec)
