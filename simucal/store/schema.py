"""The store's tables at each version of its schema, the rows they hold, and what a URL names.

A store is one database (a SQLite file, by the standard library's driver, or any SQL server SQLAlchemy
reaches; PostgreSQL through psycopg). Its table `simucal_schema` holds one row per migration applied
(version, when, what): it marks the database as the tool's and gives its version (opening.py opens a store,
checks and migrates its schema).
"""
from __future__ import annotations

import re
from datetime import datetime, timezone
from pathlib import Path
from typing import TypedDict

from simucal.errors import StoreError

SCHEMA = 3  # this version's schema; opening.MIGRATIONS leads to it from an empty database
TOOL_TABLE = "simucal_schema"
TIME_FORMAT = "%Y-%m-%dT%H:%M:%S.%fZ"  # every time the store writes: UTC, fixed width, so text order is time order


def utc_now() -> str:
    """Now in UTC as the store writes times: ISO 8601 with Z, which sorts as the times do."""
    return datetime.now(timezone.utc).strftime(TIME_FORMAT)


def tables(version: int):
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
                   Column("unit", String(32), nullable=False),
                   *([Column("own_name", String(64))] if version >= 3 else []))
    if version >= 2:
        Index("ix_calibrations_serial_time", cals.c.serial, cals.c.calibrated_utc)
        Index("ix_parameters_calibration", params.c.calibration_id)
    return meta, schema, cals, params


_, SCHEMA_TABLE, CALIBRATIONS, PARAMETERS = tables(SCHEMA)  # what records.py and queries.py read and write


class NewParameter(TypedDict):
    """A row of `parameters` as records.py writes it: one entry of one sensor in the one vocabulary
    (report/vocabulary.py: M_xx, bias_x, an effect's id), in its unit, with the method's own name of it."""
    sensor: str
    name: str
    value: float
    std: float
    unit: str
    own_name: str | None  # dK_x, theta_yx, b_x (None: no parameter of the method is it)


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
