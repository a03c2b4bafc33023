"""What the store is asked: its records (a unit's, or a lot's by time, model, method and station), their
parameters' rows and their files, each as plain rows (api/store.py makes DataFrames of them)."""
from __future__ import annotations

from typing import Any, cast

from simucal.store.schema import CALIBRATIONS, PARAMETERS, ParameterRow, RecordRow, failure

# a record's columns as a query gives them (the file itself only from files())
RECORD_COLUMNS = ("id", "serial", "calibrated_utc", "recorded_utc", "station", "method", "model", "tool_version",
                  "input_sha256", "file_sha256")
PARAMETER_COLUMNS = ("calibration_id", "serial", "calibrated_utc", "sensor", "name", "value", "std", "unit", "own_name")


def _where(serial=None, method=None, model=None, station=None, since=None, until=None, record_id=None) -> list:
    c = CALIBRATIONS.c
    tests = [(record_id, c.id.__eq__), (serial, c.serial.__eq__), (method, c.method.__eq__), (model, c.model.__eq__),
             (station, c.station.__eq__), (since, c.calibrated_utc.__ge__), (until, c.calibrated_utc.__le__)]
    return [test(value) for value, test in tests if value is not None]


def _rows(engine, url, query) -> list[dict[str, Any]]:  # a query's columns
    from sqlalchemy.exc import SQLAlchemyError
    try:
        with engine.connect() as conn:
            result = conn.execute(query)
            keys = list(result.keys())
            return [dict(zip(keys, r)) for r in result.all()]  # zip: a row's own mapping costs 20 us a row
    except SQLAlchemyError as e:
        raise failure(url, e, "cannot read") from None


def records(engine, url, **where) -> list[RecordRow]:
    """The records that match `where` (record_id, serial, method, model, station, since, until: calibrated_utc's
    range, inclusive), in calibration time order (then recording order)."""
    from sqlalchemy import select
    c = CALIBRATIONS.c
    query = select(*(getattr(c, k) for k in RECORD_COLUMNS)).where(*_where(**where))
    return cast(list[RecordRow], _rows(engine, url, query.order_by(c.calibrated_utc, c.id)))


def parameters(engine, url, **where) -> list[ParameterRow]:
    """The parameters' rows of the records that match `where` (as records), each with its record's serial and time."""
    from sqlalchemy import select
    c, p = CALIBRATIONS.c, PARAMETERS.c
    query = select(p.calibration_id, c.serial, c.calibrated_utc, p.sensor, p.name, p.value, p.std, p.unit,
                   p.own_name).join(
        CALIBRATIONS, c.id == p.calibration_id).where(*_where(**where))
    return cast(list[ParameterRow], _rows(engine, url, query.order_by(c.calibrated_utc, c.id, p.sensor, p.name)))


def files(engine, url, ids) -> dict[int, bytes]:
    """{record id: its calibration file, byte for byte}."""
    from sqlalchemy import select
    c = CALIBRATIONS.c
    ids = list(ids)
    out: dict[int, bytes] = {}
    for start in range(0, len(ids), 500):  # a bounded IN list: SQLite's limit on bound values
        query = select(c.id, c.file).where(c.id.in_(ids[start:start + 500]))
        out.update({r["id"]: bytes(r["file"]) for r in _rows(engine, url, query)})
    return out
