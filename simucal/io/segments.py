"""segments.csv (spec: docs/spec/measurement-set.md): its rows as Segments, each checked by the
spec (moved out of io/__init__.py for the room samples.parquet needed there; the package
re-exports Segment and read_segments)."""
from __future__ import annotations

import csv
import io as _io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simucal.io.text_files import (MeasurementSetError, cell, check_delimiter, csv_refusal, ends_with_a_line_end,
                                     no_repeated_columns, not_a_folder, number, read_text)


KINDS = ("static", "rate", "move")  # move: the table turning between two rests, any axis (a sequence's rows)


@dataclass
class Segment:
    segment: int
    kind: str
    outer_deg: float | None
    middle_deg: float | None
    inner_deg: float | None
    outer_rate_dps: float
    heading_ref_deg: float | None = None


def read_segments(folder: Path) -> list[Segment] | None:
    path = not_a_folder(folder / "segments.csv")
    if not path.is_file():
        return None
    text = read_text(path)
    check_delimiter(path, text)
    ends_with_a_line_end(path, text.encode())
    with _io.StringIO(text, newline="") as fh:
        reader = csv.DictReader(fh)
        try:
            return _segment_rows(path, reader)
        except csv.Error as e:
            raise csv_refusal(path, reader.line_num or 1, e) from None


def _segment_rows(path, reader) -> list[Segment]:
    """segments.csv's rows, each checked against the spec."""
    out, seen = [], set()
    no_repeated_columns(path, [h.strip() for h in reader.fieldnames or []])
    missing = [c for c in ("segment", "kind") if c not in (reader.fieldnames or [])]
    if missing:
        raise MeasurementSetError(path, 1, f"header lacks columns {missing}")
    for line, row in enumerate(reader, start=2):
        sid = cell(row, "segment", path, line)
        try:
            sid = int(sid)
        except ValueError:
            raise MeasurementSetError(path, line, f"segment {sid!r} is not an integer") from None
        if sid in seen:
            raise MeasurementSetError(path, line, f"segment {sid} appears twice (ids must be unique)")
        seen.add(sid)
        kind = cell(row, "kind", path, line)
        if kind not in KINDS:
            raise MeasurementSetError(path, line, f"kind must be 'static', 'rate' or 'move', got {kind!r}")
        vals = {}
        for col in ("outer_deg", "middle_deg", "inner_deg", "outer_rate_dps", "heading_ref_deg"):
            text = cell(row, col, path, line, required=False)
            vals[col] = None if text is None else number(text, path, line, col)
        for col, limit, what in (("heading_ref_deg", 360.0, "an azimuth in degrees, -360..360"),
                                 ("outer_rate_dps", 2000.0, "deg/s, |rate| <= 2000: no table turns faster")):
            value = vals[col]
            if value is not None and abs(value) > limit:
                raise MeasurementSetError(path, line, f"{col} is {value:g}, but it is {what}; check the "
                                                      "column's unit (degrees and deg/s)")
        rate = vals["outer_rate_dps"] or 0.0
        if kind == "rate" and rate == 0.0:
            raise MeasurementSetError(path, line, "a rate segment needs a non-zero outer_rate_dps")
        if kind == "move" and (rate != 0.0 or any(vals[c] is not None for c in ("outer_deg", "middle_deg",
                                                                                  "inner_deg"))):
            raise MeasurementSetError(path, line, "a move segment has no commanded angles or rate (the table "
                                                  "turning between rests): leave them blank")
        if kind == "static" and rate != 0.0:
            raise MeasurementSetError(path, line, f"a static segment with outer_rate_dps {rate:g}: static means "
                                                  "the table at rest (rate blank or 0); if it turned, make its "
                                                  "kind rate, else clear its rate")
        out.append(Segment(sid, kind, vals["outer_deg"], vals["middle_deg"], vals["inner_deg"],
                           rate, vals["heading_ref_deg"]))
    if not out:
        raise MeasurementSetError(path, None, "no segments")
    _angles_in_degrees(path, out)
    return out


def _angles_in_degrees(path, segments):
    """Refuse table angles that look like radians: no turntable plan of four or more positions keeps
    every angle within +-2 pi degrees, while a plan in radians always does."""
    angles = np.array([a for s in segments for a in (s.outer_deg, s.middle_deg, s.inner_deg) if a is not None])
    positions = sum(any(a is not None for a in (s.outer_deg, s.middle_deg, s.inner_deg)) for s in segments)
    if positions >= 4 and 0.5 < np.abs(angles).max() <= 2 * np.pi + 1e-6:
        raise MeasurementSetError(path, None, f"every table angle lies within +-{np.abs(angles).max():.4g}: they "
                                              "look like radians, but outer_deg, middle_deg and inner_deg are degrees "
                                              "(and outer_rate_dps deg/s): convert them")
