"""The spec's files as text (docs/spec/measurement-set.md): UTF-8 without binary bytes, commas
between columns, finite numbers and non-empty cells, each break a MeasurementSetError naming the
file and the line; the SHA-256 of a set's files, which calibrations record; a file's bytes mapped
for reading; and the careful reader of samples.csv, which names the line where the fast one stops."""
from __future__ import annotations

import hashlib
import json
import math
import mmap
import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from simucal.errors import SimucalError
from simucal.io.records import JSONObject


class MeasurementSetError(SimucalError):
    def __init__(self, path, line, rule):
        where = f"{path}" + (f", line {line}" if line else "")
        super().__init__(f"{where}: {rule}")
        self.path, self.line, self.rule = path, line, rule


def number(text, path, line, col):
    try:
        v = float(text)
    except ValueError:
        raise MeasurementSetError(path, line, f"column {col}: {text!r} is not a number") from None
    if not math.isfinite(v):
        raise MeasurementSetError(path, line, f"column {col}: {text} is not finite (NaN and infinities are errors)")
    return v


def cell(row, col, path, line, required=True):
    text = (row.get(col) or "").strip()
    if text == "":
        if required:
            raise MeasurementSetError(path, line, f"column {col} is empty (empty cells are errors)")
        return None
    return text


def read_text(path: Path) -> str:
    """A file's text: UTF-8 (a byte-order mark is dropped); binary files and other encodings
    are refused, naming the line."""
    return decoded(path, body_of(path, path.read_bytes()))


def body_of(path: Path, data: bytes | mmap.mmap) -> memoryview:
    """A text file's bytes without a byte-order mark (a view: a large file is not copied); binary
    files are refused."""
    if b"\0" in data[:65536]:
        raise MeasurementSetError(path, None, "a binary file, not text (the spec's files are UTF-8 CSV and JSON)")
    return memoryview(data)[3:] if data[:3] == b"\xef\xbb\xbf" else memoryview(data)  # data: bytes or an mmap


def decoded(path: Path, body: memoryview) -> str:
    try:
        return str(body, "utf-8")
    except UnicodeDecodeError as e:
        line = bytes(body[:e.start]).count(b"\n") + 1
        raise MeasurementSetError(path, line, f"not UTF-8 text (byte 0x{body[e.start]:02x}): save the file as "
                                              "UTF-8") from None


def files_sha256(folder: Path, samples_csv: bytes | mmap.mmap, samples_name="samples.csv") -> str:
    """SHA-256 over meta.json, segments.csv and samples.csv (each its name, a NUL and its bytes):
    what a calibration records as input_sha256 and validate compares. samples_csv: that file's
    bytes as read (hashed once, not read again); samples_name: samples.parquet where the set holds that."""
    h = hashlib.sha256()
    for name in ("meta.json", "segments.csv"):
        if (folder / name).is_file():
            h.update(name.encode() + b"\0" + (folder / name).read_bytes())
    h.update(samples_name.encode() + b"\0")
    h.update(samples_csv)
    return h.hexdigest()


def check_delimiter(path, text):
    """The spec's CSV is comma-separated: name another delimiter instead of a missing column."""
    first = text[:text.find("\n")] if "\n" in text else text
    if "," not in first:
        for sep, name in (("\t", "tabs"), (";", "semicolons"), ("|", "bars")):
            if sep in first:
                raise MeasurementSetError(path, 1, f"the columns are separated by {name}; the spec's CSV uses commas "
                                                   "(convert it, or use simucal import csv)")


def not_a_folder(path: Path) -> Path:
    """path, refused where it is a folder or a symbolic link that leads nowhere (a loop, or a missing
    target), which would otherwise read as a file that is missing."""
    if path.is_dir():
        raise MeasurementSetError(path, None, f"is a folder; {path.name} must be a file (see the spec)")
    if path.is_symlink() and not path.exists():
        raise MeasurementSetError(path, None, "is a symbolic link that leads nowhere (a loop of links, or its "
                                              "target is missing); put the file itself there")
    return path


def ends_with_a_line_end(path: Path, body, line=None) -> None:
    """Refuse a CSV whose last line has no line end: a recording cut short while it was written (the
    last number may have lost digits) reads as a valid one. Every writer the spec knows ends each line.
    line: the last line's number, where body is only the file's end."""
    if len(body) and bytes(body[-1:]) not in (b"\n", b"\r"):
        line = line or bytes(body).count(b"\n") + 1
        last = bytes(body[-40:]).decode("utf-8", "replace").rsplit("\n", 1)[-1]
        raise MeasurementSetError(path, line, f"the last line has no line end (it ends ...{last[-24:]!r}): the "
                                              "file may be cut short mid-number; if the line is whole, end it with "
                                              "a newline")


class RepeatedKey(ValueError):
    """A JSON object that names a key twice."""


def unique_keys(pairs) -> JSONObject:
    """json's object_pairs_hook: an object that names a key twice is refused (json keeps the last one
    silently; which value was meant cannot be told)."""
    seen = set()
    for k, _ in pairs:
        if k in seen:
            raise RepeatedKey(f"key {k[:40]!r} appears twice in one object: which value is meant? keep one")
        seen.add(k)
    return dict(pairs)


def csv_refusal(path: Path, line, e) -> MeasurementSetError:
    """csv's own error (a cell beyond its field limit of 131072 characters, a quote left open) as the
    spec's refusal naming the line."""
    return MeasurementSetError(path, line or None, f"not readable as CSV ({str(e)[:80]}): a cell that long, or "
                                                   "a quote left open, holds no number; check the file")


def no_repeated_columns(path: Path, header: list) -> None:
    """Refuse a header that names a column twice: which of them is the data cannot be told."""
    dup = [c for c in dict.fromkeys(header) if header.count(c) > 1]
    if dup:
        where = [i + 1 for i, c in enumerate(header) if c == dup[0]]
        more = f" and {len(dup) - 1} more names" if len(dup) > 1 else ""
        raise MeasurementSetError(path, 1, f"column {dup[0][:40]} appears {len(where)} times (columns "
                                           f"{', '.join(map(str, where[:5]))}{', ...' if len(where) > 5 else ''})"
                                           f"{more}: which one is the data? keep one")


def mapped(fh) -> bytes | mmap.mmap:
    """A file's bytes, mapped read-only where it has any: the parse and the hash read the page cache in
    place, where read_bytes copied the 104 MB of the 400 Hz set into fresh pages first (0.1 s of system
    time, 26,700 page faults against 1,700)."""
    if not os.fstat(fh.fileno()).st_size:
        return b""
    try:
        return mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
    except (OSError, ValueError):  # a file system that cannot map it: read it
        return fh.read()


def is_ascii(raw) -> bool:
    """Whether every byte is below 128 (bytes.isascii, which an mmap lacks): the usual file, UTF-8 without
    decoding it."""
    return raw.isascii() if isinstance(raw, bytes) else not len(raw) or int(np.frombuffer(raw, np.uint8).max()) < 128


def careful_rows(reader, path, header, cols, others) -> dict[str, NDArray[np.float64]]:
    """samples.csv's rows (a csv.reader after the header) one by one, naming the line and the column of
    any cell that is not a number."""
    idx = {c: header.index(c) for c in cols + others}
    data: dict[str, list[float]] = {c: [] for c in cols + others}
    for line, row in enumerate(reader, start=2):
        if not row or all(not x.strip() for x in row):
            continue
        if len(row) != len(header):
            raise MeasurementSetError(path, line, f"{len(row)} cells, header has {len(header)}")
        for c in cols:
            text = row[idx[c]].strip()
            if text == "":
                raise MeasurementSetError(path, line, f"column {c} is empty (empty cells are errors)")
            data[c].append(number(text, path, line, c))
        for c in list(others):
            try:
                data[c].append(number(row[idx[c]].strip(), path, line, c))
            except MeasurementSetError:
                others.remove(c)
                del data[c]
    if not data["t_s"]:
        raise MeasurementSetError(path, None, "no samples")
    return {c: np.asarray(v, float) for c, v in data.items()}


def json_object_or_none(path) -> JSONObject | None:
    """The JSON object a file holds, None where it is missing or holds none (unreadable, damaged, not JSON, too
    deep): for a file that is never an input, such as a simulator's truth.json beside a set."""
    try:
        d = json.loads(Path(path).read_text()) if Path(path).is_file() else None
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return None
    return d if isinstance(d, dict) else None
