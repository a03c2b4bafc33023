"""The store's tables, its versioned schema and the migrations between versions, and how a URL is opened.

A store is one database (a SQLite file, by the standard library's driver, or any SQL server SQLAlchemy
reaches; PostgreSQL through psycopg). Its table `simucal_schema` holds one row per migration applied
(version, when, what): it marks the database as the tool's and gives its version. A database with other
tables and no `simucal_schema` is not the tool's and is refused; so is a schema newer than SCHEMA (a later
simucal wrote it). An older one is migrated on opening, each step in one transaction under a lock (SQLite:
BEGIN IMMEDIATE; PostgreSQL: an advisory lock), so two stations opening it at once migrate it once.
"""
from __future__ import annotations

import re
from datetime import datetime, timezone
from pathlib import Path
from typing import TypedDict

from simucal.errors import StoreError
from simucal.store.sqlite_file import how_to_open

SCHEMA = 2  # this version's schema; MIGRATIONS below leads to it from an empty database
TOOL_TABLE = "simucal_schema"
_PG_LOCK = 0x51AC  # the advisory lock's key, one for every simucal store of a server
TIME_FORMAT = "%Y-%m-%dT%H:%M:%S.%fZ"  # every time the store writes: UTC, fixed width, so text order is time order


def utc_now() -> str:
    """Now in UTC as the store writes times: ISO 8601 with Z, which sorts as the times do."""
    return datetime.now(timezone.utc).strftime(TIME_FORMAT)


def _tables(version: int):
    """The tables as schema `version` has them (SQLAlchemy Core): (metadata, schema, calibrations, parameters)."""
    from sqlalchemy import Column, Float, ForeignKey, Index, Integer, LargeBinary, MetaData, String, Table, Text
    meta = MetaData()
    schema = Table(TOOL_TABLE, meta, Column("version", Integer, primary_key=True, autoincrement=False),
                   Column("applied_utc", String(32), nullable=False), Column("what", Text, nullable=False))
    later = [Column("calibrated_utc", String(32))] if version >= 2 else []
    cals = Table("calibrations", meta,
                 Column("id", Integer, primary_key=True, autoincrement=True),
                 Column("serial", String(200), nullable=False),
                 Column("file", LargeBinary, nullable=False),  # the calibration file, byte for byte
                 Column("file_sha256", String(64), nullable=False, unique=True),  # one record per file
                 Column("method", String(64), nullable=False), Column("model", Text, nullable=False),
                 Column("tool_version", String(64), nullable=False),
                 Column("input_sha256", Text),  # the measurement set's files (a JSON list for plateaus)
                 Column("station", String(200), nullable=False),
                 Column("recorded_utc", String(32), nullable=False), *later)
    params = Table("parameters", meta,
                   Column("calibration_id", Integer, ForeignKey("calibrations.id"), nullable=False),
                   Column("sensor", String(16), nullable=False), Column("name", String(64), nullable=False),
                   Column("value", Float, nullable=False), Column("std", Float, nullable=False),
                   Column("unit", String(32), nullable=False))
    if version >= 2:
        Index("ix_calibrations_serial_time", cals.c.serial, cals.c.calibrated_utc)
        Index("ix_parameters_calibration", params.c.calibration_id)
    return meta, schema, cals, params


_, SCHEMA_TABLE, CALIBRATIONS, PARAMETERS = _tables(SCHEMA)  # what records.py and queries.py read and write


class NewParameter(TypedDict):
    """A row of `parameters` as records.py writes it: one parameter of one sensor, in its unit."""
    sensor: str
    name: str
    value: float
    std: float
    unit: str


class ParameterRow(NewParameter):
    """A row of `parameters` as queries.py reads it, with its record's id, serial and time."""
    calibration_id: int
    serial: str
    calibrated_utc: str


class NewRecord(TypedDict):
    """A row of `calibrations` as records.py writes it (module doc)."""
    serial: str
    file: bytes               # the calibration file, byte for byte
    file_sha256: str
    method: str
    model: str
    tool_version: str
    input_sha256: str | None  # the set's files' (a JSON list for plateaus)
    station: str
    recorded_utc: str
    calibrated_utc: str


class RecordRow(TypedDict):
    """A row of `calibrations` as queries.py reads it (queries.RECORD_COLUMNS: the file itself from files())."""
    id: int
    serial: str
    calibrated_utc: str
    recorded_utc: str
    station: str
    method: str
    model: str
    tool_version: str
    input_sha256: str | None
    file_sha256: str


def _to_1(conn) -> None:
    _tables(1)[0].create_all(conn)


def _to_2(conn) -> None:
    """The time of the calibration beside the time it was recorded (an earlier record: the same), and indexes
    for a unit's history."""
    from sqlalchemy import text
    conn.execute(text("ALTER TABLE calibrations ADD COLUMN calibrated_utc VARCHAR(32)"))
    conn.execute(text("UPDATE calibrations SET calibrated_utc = recorded_utc"))
    for index in _tables(2)[2].indexes | _tables(2)[3].indexes:
        index.create(conn)


MIGRATIONS = {1: ("calibrations and their parameters", _to_1),
              2: ("calibrated_utc; indexes by serial and time", _to_2)}


def shown(url: str) -> str:
    """The URL as a message may show it: its password never (***)."""
    from sqlalchemy.engine import make_url
    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # not even a URL: show no part that could be a password
        return re.sub(r"://[^@/]*@", "://***@", url)


def engine_url(url: str) -> str:
    """A URL SQLAlchemy opens: a plain path is a SQLite file; postgresql:// is psycopg (version 3)."""
    if "://" not in url:
        return f"sqlite:///{Path(url).expanduser().resolve()}"
    if url.startswith(("postgresql://", "postgres://")):
        return "postgresql+psycopg://" + url.split("://", 1)[1]
    return url


def local_file(url: str) -> Path | None:
    """A SQLite store's file (an input that no command writes over); None: a server's database, or in memory."""
    target = engine_url(url)
    path = target.split(":///", 1)[1] if target.startswith("sqlite") and ":///" in target else ""
    return Path(path) if path and path != ":memory:" else None


def failure(url: str, e: Exception, doing: str) -> StoreError:
    """A database's error as one line naming the store (password hidden) and what was being done."""
    from sqlalchemy.engine import make_url
    why = str(getattr(e, "orig", None) or e).strip().splitlines()[0][:300]
    try:
        password = make_url(engine_url(url)).password
    except Exception:
        password = None
    if password:
        why = why.replace(str(password), "***")
    return StoreError(f"{shown(url)}: {doing}: {type(getattr(e, 'orig', None) or e).__name__}: {why}")


def open_engine(url: str, create: bool):
    """The store's engine, its schema checked and migrated to SCHEMA (created where create and the database is
    empty). Refused in one line: no store there (not create), not the tool's, a newer schema, no driver."""
    from sqlalchemy import create_engine, event
    from sqlalchemy.exc import SQLAlchemyError
    target = engine_url(url)
    sqlite = target.startswith("sqlite")
    path = local_file(url) if sqlite else None
    journal: str | None = "WAL"  # a SQLite file's journal (sqlite_file.py: by where it lives; None: read only)
    if path and not create and not path.is_file():
        raise StoreError(f"{shown(url)}: no store there; record into it first: simucal store add CAL.json "
                         f"--store {shown(url)}")
    if path:
        target, journal = how_to_open(path, shown(url), write=create)
    try:
        engine = create_engine(target, **({"connect_args": {"timeout": 60}} if sqlite else {}))
    except (SQLAlchemyError, ImportError, ValueError) as e:
        raise failure(url, e, "cannot open (a URL such as sqlite:///lab.db or postgresql://user@host/db)") from None
    if sqlite:  # the transactions the store asks for, not the driver's own: a writer's BEGIN IMMEDIATE waits
        @event.listens_for(engine, "connect")
        def _no_driver_transactions(dbapi_connection, _record):
            dbapi_connection.isolation_level = None
            if journal:  # WAL: a station reading neither waits for a writer nor blocks one (sqlite_file.py)
                dbapi_connection.execute(f"PRAGMA journal_mode={journal}")

        @event.listens_for(engine, "begin")
        def _begin(conn):
            conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.get_execution_options().get("write") else "BEGIN")
    try:
        _migrate(engine, url, create)
    except SQLAlchemyError as e:
        engine.dispose()
        raise failure(url, e, "cannot read its schema") from None
    except StoreError:
        engine.dispose()
        raise
    return engine


def version_of(conn, url: str) -> int:
    """The store's schema version: 0 for an empty database; refused where it is not the tool's."""
    from sqlalchemy import func, inspect, select
    names = set(inspect(conn).get_table_names())
    if TOOL_TABLE not in names:
        if names:
            raise StoreError(f"{shown(url)}: not a simucal calibration store (it has the tables "
                             f"{', '.join(sorted(names)[:8])} and no {TOOL_TABLE}); give a new file or an empty "
                             "database")
        return 0
    return int(conn.execute(select(func.max(SCHEMA_TABLE.c.version))).scalar() or 0)


def _migrate(engine, url: str, create: bool, upto: int = SCHEMA) -> None:
    """Bring the store to schema `upto`, one migration per transaction, under the store's lock."""
    with engine.connect() as conn:
        found = version_of(conn, url)
        conn.rollback()
    if found > SCHEMA:
        raise StoreError(f"{shown(url)}: schema {found} is newer than this simucal's {SCHEMA}; open it with the "
                         "simucal that wrote it, or a later one")
    if found == 0 and not create:
        raise StoreError(f"{shown(url)}: holds no calibration store yet; record into it first: simucal store add "
                         f"CAL.json --store {shown(url)}")
    while found < upto:
        with engine.connect().execution_options(write=True) as conn, conn.begin():
            if engine.dialect.name == "postgresql":
                conn.exec_driver_sql(f"SELECT pg_advisory_xact_lock({_PG_LOCK})")
            found = version_of(conn, url)  # another station may have migrated it meanwhile
            if found >= upto:
                break
            what, step = MIGRATIONS[found + 1]
            step(conn)
            conn.execute(SCHEMA_TABLE.insert().values(version=found + 1, applied_utc=utc_now(), what=what))
            found += 1


def make_at(url: str, version: int) -> None:
    """A store created at an earlier schema `version` (the migrations' test: a store as an earlier simucal made it)."""
    from sqlalchemy import create_engine
    engine = create_engine(engine_url(url))
    try:
        _migrate(engine, url, create=True, upto=version)
    finally:
        engine.dispose()
