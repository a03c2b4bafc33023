"""The spec's files as text (shared/spec/measurement-set.md): UTF-8 without binary bytes, commas
between columns, finite numbers and non-empty cells, each break a MeasurementSetError naming the
file and the line; and the SHA-256 of a set's files, which calibrations record."""
from __future__ import annotations

import hashlib
import math
from pathlib import Path


class MeasurementSetError(ValueError):
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


def body_of(path: Path, data: bytes) -> memoryview:
    """A text file's bytes without a byte-order mark (a view: a large file is not copied); binary
    files are refused."""
    if b"\0" in data[:65536]:
        raise MeasurementSetError(path, None, "a binary file, not text (the spec's files are UTF-8 CSV and JSON)")
    return memoryview(data)[3:] if data.startswith(b"\xef\xbb\xbf") else memoryview(data)


def decoded(path: Path, body: memoryview) -> str:
    try:
        return str(body, "utf-8")
    except UnicodeDecodeError as e:
        line = bytes(body[:e.start]).count(b"\n") + 1
        raise MeasurementSetError(path, line, f"not UTF-8 text (byte 0x{body[e.start]:02x}): save the file as "
                                              "UTF-8") from None


def files_sha256(folder: Path, samples_csv: bytes) -> str:
    """SHA-256 over meta.json, segments.csv and samples.csv (each its name, a NUL and its bytes):
    what a calibration records as input_sha256 and validate compares. samples_csv: that file's
    bytes as read (hashed once, not read again)."""
    h = hashlib.sha256()
    for name in ("meta.json", "segments.csv"):
        if (folder / name).is_file():
            h.update(name.encode() + b"\0" + (folder / name).read_bytes())
    h.update(b"samples.csv\0")
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
    if path.is_dir():
        raise MeasurementSetError(path, None, f"is a folder; {path.name} must be a file (see the spec)")
    return path
