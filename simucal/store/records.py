"""A record: one calibration file as the store keeps it, and its insertion.

The record holds the file byte for byte (its sha256 unique: a file is recorded once), the unit's serial
(the file's unit_serial from meta.json, or given), its method and model, the tool's version, the sha256 of
the measurement set's files, the station and the times (recorded, and of the calibration), and each entry
of the one vocabulary with its std and the method's own name as a row of `parameters` (parameter_rows).
Nothing updates or deletes a record: a recalibration is a new one.
"""
from __future__ import annotations

import hashlib
import json
import re
import socket
from datetime import datetime

from simucal.errors import StoreError
from simucal.io.calibration import Calibration, loads
from simucal.io.calibration_checks import SERIAL
from simucal.report.lot_figures import model_name
from simucal.report.vocabulary import entries, is_determined
from simucal.store.schema import (CALIBRATIONS, PARAMETERS, TIME_FORMAT, NewParameter, NewRecord, failure,
                                  utc_now)
from simucal.version import __version__

_TIME = re.compile(r"^\d{4}-\d{2}-\d{2}(T\d{2}:\d{2}(:\d{2}(\.\d{1,6})?)?Z?)?$")


def parameter_rows(cal: Calibration) -> list[NewParameter]:
    """Every entry of the one vocabulary at T_ref (report/vocabulary.entries: M_xx .. bias_z, effects by id) that
    the file determines (a finite std above 0) or that a parameter the file holds fixed is (std 0: the trend says
    so), with the method's own name, as the rows of `parameters`."""
    return [{"sensor": s, "name": e.name, "value": e.value, "std": e.std, "unit": e.unit, "own_name": e.own_name}
            for s, b in cal.blocks() for e in entries(s, b, terms=False)
            if is_determined(e) or (e.std == 0 and e.own_name is not None)]


def _time(value: str | None, what: str) -> str | None:
    """A time given (--time): ISO 8601 in UTC (2026-03-01 or 2026-03-01T09:30:00Z), written as the store writes
    its own times (so that they sort as the times do)."""
    if value is None:
        return None
    if not isinstance(value, str) or not _TIME.match(value):
        raise StoreError(f"{what} {value!r}: not a UTC time as 2026-03-01 or 2026-03-01T09:30:00Z")
    return datetime.fromisoformat(value.rstrip("Z")).strftime(TIME_FORMAT)


def record_of(raw: bytes, where, serial: str | None = None, station: str | None = None,
              calibrated_utc: str | None = None) -> tuple[NewRecord, list[NewParameter]]:
    """The record of a calibration file's bytes (checked as `simucal.load` checks a file; where: what messages
    name) and its parameters' rows. Refused where the file has no serial and none is given, or where the one
    given is another unit's."""
    cal = loads(raw.decode("utf-8", errors="replace"), where)
    own = cal.layout.get(SERIAL)
    if serial is not None and own is not None and str(own) != str(serial):
        raise StoreError(f"--serial {serial}: {where} was made for unit {own!r} (its meta.json's unit_serial); "
                         "record it under its own serial")
    serial = serial if serial is not None else own
    if serial is None or not str(serial).strip():
        raise StoreError(f"{where}: no unit_serial in its layout (meta.json of the set had none); give the unit's "
                         "serial: --serial S")
    now = utc_now()
    sha = cal.input_sha256
    row: NewRecord = {"serial": str(serial), "file": raw, "file_sha256": hashlib.sha256(raw).hexdigest(),
                      "method": cal.method, "model": model_name(cal), "tool_version": __version__,
                      "input_sha256": json.dumps(sha) if isinstance(sha, list) else sha,
                      "station": station or socket.gethostname(), "recorded_utc": now,
                      "calibrated_utc": _time(calibrated_utc, "--time") or now}
    return row, parameter_rows(cal)


def insert(engine, url: str, row: NewRecord, params: list[NewParameter], where) -> int:
    """The record and its parameters in one transaction; its id. A file recorded before is refused, naming
    its record (the unique sha256 decides, so two stations adding one file at once record it once)."""
    from sqlalchemy import select
    from sqlalchemy.exc import IntegrityError, SQLAlchemyError
    try:
        with engine.connect().execution_options(write=True) as conn, conn.begin():
            record_id = conn.execute(CALIBRATIONS.insert().values(**row)).inserted_primary_key[0]
            if params:
                conn.execute(PARAMETERS.insert(), [{"calibration_id": record_id, **p} for p in params])
    except IntegrityError:
        with engine.connect() as conn:
            there = conn.execute(select(CALIBRATIONS.c.id, CALIBRATIONS.c.serial, CALIBRATIONS.c.recorded_utc)
                                 .where(CALIBRATIONS.c.file_sha256 == row["file_sha256"])).first()
        if there is None:
            raise
        raise StoreError(f"{where}: this calibration file is already recorded (record {there.id}, unit {there.serial}, "
                         f"{there.recorded_utc}); a record is never replaced: a recalibration is a new file") from None
    except SQLAlchemyError as e:
        raise failure(url, e, "cannot record") from None
    return int(record_id)
