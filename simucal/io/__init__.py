"""Read and write measurement sets (spec: docs/spec/measurement-set.md).

Every rule the spec states is checked; a break is reported as
MeasurementSetError naming the file, the line and the rule.
"""
from __future__ import annotations

import csv
import io as _io
import json
import re
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import cast


from simucal.io import csv_columns, results, sensor_checks, units
from simucal.io import meta as meta_keys
from simucal.io.csv_columns import Columns, Extremes, arrow_floats, read_columns
from simucal.io.measurement_set import MeasurementSet as MeasurementSet
from simucal.io.set_rules import (FORMAT as FORMAT, PLAUSIBLE as PLAUSIBLE, SAMPLE_COLS as SAMPLE_COLS,
                                  SEGMENT_COLS as SEGMENT_COLS, SENSOR_COLS as SENSOR_COLS, check_samples,
                                  group_rows as group_rows, run_or_rows as run_or_rows)
from simucal.io.set_writer import write_set as write_set
from simucal.io.segments import Segment as Segment, read_segments  # Segment: the API names it simucal.io.Segment
from simucal.io.text_files import (MeasurementSetError, RepeatedKey, body_of, check_delimiter, csv_refusal,
                                     decoded, ends_with_a_line_end, files_sha256, no_repeated_columns, not_a_folder,
                                     careful_rows, is_ascii, json_object_or_none, mapped, read_text,
                                     unique_keys)


def read_meta(folder: Path) -> meta_keys.Meta:
    path = not_a_folder(folder / "meta.json")
    if not path.is_file():
        raise MeasurementSetError(path, None, "missing: a measurement set needs meta.json")
    text = read_text(path)
    try:
        meta = json.loads(text, object_pairs_hook=unique_keys)
    except json.JSONDecodeError as e:
        raise MeasurementSetError(path, e.lineno, f"not valid JSON: {e.msg}") from None
    except RepeatedKey as e:
        raise MeasurementSetError(path, None, str(e)) from None
    except ValueError as e:  # a number of thousands of digits
        raise MeasurementSetError(path, None, f"not readable JSON ({str(e)[:80]})") from None
    except RecursionError:
        raise MeasurementSetError(path, None, "nested too deep to read (arrays or objects within each other "
                                              "thousands of levels down): meta.json is one flat object of the "
                                              "spec's keys") from None
    if not isinstance(meta, dict):
        raise MeasurementSetError(path, None, "must hold a JSON object ({...})")
    if meta.get("format") != FORMAT:
        raise MeasurementSetError(path, None, f'"format" must be "{FORMAT}", got {meta.get("format")!r}')
    units.check_meta(meta, path, MeasurementSetError)
    return cast(meta_keys.Meta, meta)  # the spec's keys, checked


def read_samples(folder: Path, segments) -> tuple[Columns, str, dict[str, Extremes] | None]:
    """(column -> array, files_sha256 of the set's files as read: hashed on a thread of its own while
    the numbers are parsed, as hashlib frees the GIL, each column's (least, greatest, rows at the least,
    rows at the greatest) where the parser found them, else None) of samples.csv, or samples.parquet
    (_read_parquet). The numbers are parsed by csv_columns (C or pyarrow), and only where that finds anything unusual by
    the careful reader, which names the line; the whole file is checked to be UTF-8 either way (an ASCII file, the usual
    one, is UTF-8 without decoding it)."""
    path = samples_path(folder)
    if path.suffix == ".parquet":
        return _read_parquet(folder, path, segments)
    path = not_a_folder(path)
    if not path.is_file():
        raise MeasurementSetError(path, None, "missing: a measurement set needs samples.csv (or samples.parquet)")
    with open(path, "rb") as fh, ThreadPoolExecutor(1) as pool:
        raw = mapped(fh)
        hashing = pool.submit(files_sha256, folder, raw)
        csv_columns.prepare()
        samples, extremes = _parsed(path, raw, segments)
        sha256 = hashing.result()
    del raw  # the file's pages let go before the checks' temporaries: the peak of reading is the file and the arrays
    return check_samples(samples, path, segments, extremes is not None), sha256, extremes


def _parsed(path, raw, segments) -> tuple[dict, dict | None]:
    """(samples.csv's columns, {column: (least, greatest, rows at each)} where their numbers are known to
    be within +-PLAUSIBLE (read_columns), else None)."""
    body = body_of(path, raw)
    if not len(body):
        raise MeasurementSetError(path, 1, "empty file")
    ends_with_a_line_end(path, body)
    header = _header(path, body)  # its first line checked to be UTF-8
    cols, others = _sample_columns(path, header, segments)
    fast, extremes = read_columns(body, header, cols, others, PLAUSIBLE)
    # where csv_numbers.c took every line (extremes given), it read ASCII digits, signs and commas alone
    if extremes is None and not is_ascii(raw):
        decoded(path, body)  # names the line of a byte that is not UTF-8
    if fast is not None:
        return fast, extremes
    with _io.StringIO(decoded(path, body), newline="") as fh:
        reader = csv.reader(fh)
        try:
            next(reader)
            return careful_rows(reader, path, header, cols, others), None
        except csv.Error as e:
            raise csv_refusal(path, reader.line_num, e) from None


def _header(path, body) -> list[str]:
    """The header's cells. A plain first line (no quotes, ended by a newline within 64 KiB) is read
    alone; any other through csv over the whole text, as the careful reader reads it."""
    first = bytes(body[:65536])
    end = first.find(b"\n")
    if end >= 0 and b'"' not in first[:end]:
        text = decoded(path, memoryview(first)[:end])
        check_delimiter(path, text)
        return [h.strip() for h in next(csv.reader([text]), [])]
    text = decoded(path, body)
    check_delimiter(path, text)
    with _io.StringIO(text, newline="") as fh:
        try:
            return [h.strip() for h in next(csv.reader(fh), [])]
        except csv.Error as e:
            raise csv_refusal(path, 1, e) from None


def _sample_columns(path, header, segments) -> tuple[list, list]:
    """(the spec's columns present, further numeric columns: auxiliary inputs a user's error model
    may read, such as supply_v; a column holding anything else, a note or a label, is left out),
    with the header's rules checked."""
    no_repeated_columns(path, header)
    _sensor_like_columns(path, header)
    if "t_s" not in header:
        raise MeasurementSetError(path, 1, "header lacks column t_s")
    for group in (("ax", "ay", "az"), ("gx", "gy", "gz")):
        present = [c for c in group if c in header]
        if present and len(present) != 3:
            raise MeasurementSetError(path, 1, f"columns {group} must all be present or all absent")
    if "ax" not in header and "gx" not in header:
        raise MeasurementSetError(path, 1, "neither accelerometer (ax ay az) nor gyro (gx gy gz) columns")
    if segments is not None and "segment" not in header:
        raise MeasurementSetError(path, 1, "segments.csv exists, so samples.csv needs a segment column")
    cols = [c for c in header if c in ("segment", "t_s", "temp_c") + SAMPLE_COLS]
    return cols, [c for c in dict.fromkeys(header) if c.isidentifier() and c not in cols]


_LOOKS_LIKE = {"acc": re.compile(r"^(acc|accel|accelerometer|a|f)[ _.-]?(x|y|z)(_.*)?$", re.I),
               "gyro": re.compile(r"^(gyr|gyro|gyroscope|g|w|omega|rate)[ _.-]?(x|y|z)(_.*)?$", re.I)}


def _sensor_like_columns(path, header):
    """Refuse sensor data under names the spec does not use (acc_x, gyro_z, ...): read as spec
    columns they would be lost silently (a gyro-only calibration of a unit with accelerometers)."""
    for sensor, names in (("acc", SAMPLE_COLS[:3]), ("gyro", SAMPLE_COLS[3:])):
        alike = [c for c in header if c not in SAMPLE_COLS and _LOOKS_LIKE[sensor].match(c)]
        if alike:
            raise MeasurementSetError(path, 1, f"columns {', '.join(alike)} look like {sensor} data, but the spec "
                                               f"names them {', '.join(names)}: rename them (or use simucal import "
                                               "csv --columns)")


def samples_path(folder: Path) -> Path:
    """The set's samples file: samples.csv, or samples.parquet where that is there instead (a compatible
    extension of the spec: docs/notes/samples-parquet.md)."""
    csv_path, parquet = Path(folder) / "samples.csv", Path(folder) / "samples.parquet"
    if parquet.exists() or parquet.is_symlink():
        if csv_path.exists():
            raise MeasurementSetError(folder, None, "holds both samples.csv and samples.parquet: a set holds its "
                                                    "samples once; remove one (simucal convert writes either)")
        return not_a_folder(parquet)
    return csv_path


def parquet_file(path, pre_buffer=True):
    import pyarrow as pa
    import pyarrow.parquet as pq
    try:
        return pq.ParquetFile(path, pre_buffer=pre_buffer)
    except (pa.ArrowException, OSError) as e:
        raise MeasurementSetError(path, None, f"not a readable Parquet file ({str(e)[:120]}); write it with "
                                              "simucal convert --to parquet") from None


def parquet_columns(path, segments) -> tuple[list, list]:
    """(the spec's columns, the other numeric columns) of samples.parquet, the header's rules checked;
    a spec column must hold numbers (a column of anything else among the others is left out)."""
    import pyarrow as pa
    schema = parquet_file(path).schema_arrow
    cols, others = _sample_columns(path, list(schema.names), segments)
    numeric = {f.name for f in schema if pa.types.is_integer(f.type) or pa.types.is_floating(f.type)}
    for c in cols:
        if c not in numeric:
            raise MeasurementSetError(path, None, f"column {c} holds {schema.field(c).type}, not numbers: the spec's "
                                                  "columns hold integers or floats")
    return cols, [c for c in others if c in numeric]


def at_row(path, e: MeasurementSetError, before: int) -> MeasurementSetError:
    """A refusal of rows read in batches (its line counted in the batch) at the file's line, or for
    samples.parquet its row (counted from 1)."""
    if e.line is None:
        return e
    if Path(path).suffix == ".parquet":
        return MeasurementSetError(path, None, f"row {e.line - 1 + before}: {e.rule}")
    return MeasurementSetError(path, e.line + before, e.rule)


def _read_parquet(folder, path, segments) -> tuple[Columns, str, None]:
    """read_samples of samples.parquet: the same columns and rules, a break named by its row."""
    cols, others = parquet_columns(path, segments)
    try:
        samples = arrow_floats(path, parquet_file(path).read(columns=cols + others), cols + others)
        return check_samples(samples, path, segments), files_sha256(folder, path.read_bytes(), path.name), None
    except MeasurementSetError as e:
        raise at_row(path, e, 0) from None


def read_set(folder) -> MeasurementSet:
    folder = Path(folder)
    if not folder.is_dir():
        raise MeasurementSetError(folder, None, "not a folder (a measurement set is a folder)")
    meta = read_meta(folder)
    segments = read_segments(folder)
    samples, sha256, extremes = read_samples(folder, segments)
    if "gx" in samples and "latitude_deg" not in meta:
        raise MeasurementSetError(folder / "meta.json", None,
                                  "latitude_deg is required when gyro data are present")
    # a simulator's truth.json, as MeasurementSet.write writes it: never an input (a damaged one leaves it None)
    truth = cast(results.Truth | None, json_object_or_none(folder / "truth.json"))
    ms = MeasurementSet(folder, meta, samples, segments, sha256=sha256, truth=truth)
    if extremes is not None:
        sensor_checks.known_extremes(ms, extremes)
    return ms
