"""How a store is opened: its schema checked, and an older one migrated to schema.SCHEMA.

A database with other tables and no `simucal_schema` is not the tool's and is refused; so is a schema newer
than SCHEMA (a later simucal wrote it). An older one is migrated on opening, each step in one transaction under
a lock (SQLite: BEGIN IMMEDIATE; PostgreSQL: an advisory lock), so two stations opening it at once migrate it
once.
"""
from __future__ import annotations

from simucal.errors import SimucalError, StoreError
from simucal.io.calibration import loads
from simucal.store.records import parameter_rows
from simucal.store.schema import (SCHEMA, SCHEMA_TABLE, TOOL_TABLE, engine_url, failure,
                                  local_file, shown, tables, utc_now)
from simucal.store.sqlite_file import how_to_open

_PG_LOCK = 0x51AC  # the advisory lock's key, one for every simucal store of a server


def _to_1(conn) -> None:
    tables(1)[0].create_all(conn)


def _to_2(conn) -> None:
    """The time of the calibration beside the time it was recorded (an earlier record: the same), and indexes
    for a unit's history."""
    from sqlalchemy import text
    conn.execute(text("ALTER TABLE calibrations ADD COLUMN calibrated_utc VARCHAR(32)"))
    conn.execute(text("UPDATE calibrations SET calibrated_utc = recorded_utc"))
    for index in tables(2)[2].indexes | tables(2)[3].indexes:
        index.create(conn)


def _to_3(conn) -> None:
    """The parameters' rows in the one vocabulary, each with the method's own name: every record's rows rewritten
    from its file, which the store keeps byte for byte (the records themselves are not touched)."""
    from sqlalchemy import delete, select, text
    _, _, cals, params = tables(3)
    conn.execute(text("ALTER TABLE parameters ADD COLUMN own_name VARCHAR(64)"))
    ids = [r.id for r in conn.execute(select(cals.c.id).order_by(cals.c.id))]
    for start in range(0, len(ids), 200):  # the files a batch at a time: a store's files need not fit in memory
        batch = conn.execute(select(cals.c.id, cals.c.file).where(cals.c.id.in_(ids[start:start + 200]))).all()
        for record in batch:
            try:
                rows = parameter_rows(loads(bytes(record.file).decode("utf-8"), f"record {record.id}"))
            except SimucalError as e:
                raise StoreError(f"record {record.id}'s file cannot be read in the one vocabulary ({e}); open the "
                                 "store with the simucal that recorded it, or one that reads that file") from None
            conn.execute(delete(params).where(params.c.calibration_id == record.id))
            if rows:
                conn.execute(params.insert(), [{"calibration_id": record.id, **r} for r in rows])


MIGRATIONS = {1: ("calibrations and their parameters", _to_1),
              2: ("calibrated_utc; indexes by serial and time", _to_2),
              3: ("parameters in the one vocabulary, with the method's own name", _to_3)}



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
            try:
                step(conn)
            except StoreError as e:  # the transaction rolls back: the store is left at schema `found`
                raise StoreError(f"{shown(url)}: its migration to schema {found + 1} ({what}) stopped, the store left "
                                 f"as it was: {e}") from None
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
