"""Read and write measurement sets (spec: docs/spec/measurement-set.md).

Every rule the spec states is checked; a break is reported as
MeasurementSetError naming the file, the line and the rule.
"""
from __future__ import annotations

import csv
import dataclasses
import io as _io
import hashlib
import json
import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, cast

import numpy as np

from simucal.io import csv_columns, outputs, sensor_checks, units
from simucal.io import meta as meta_keys
from simucal.io.csv_columns import Columns, Extremes, arrow_floats, read_columns, triad_block
from simucal.io.segments import Segment as Segment, read_segments  # Segment: the API names it simucal.io.Segment
from simucal.io.text_files import (MeasurementSetError, RepeatedKey, body_of, check_delimiter, csv_refusal,
                                     decoded, ends_with_a_line_end, files_sha256, no_repeated_columns, not_a_folder,
                                     careful_rows, is_ascii, mapped, read_text, unique_keys)

FORMAT = "simucal.measurements/1"
SAMPLE_COLS = ("ax", "ay", "az", "gx", "gy", "gz")
SENSOR_COLS = {"acc": SAMPLE_COLS[:3], "gyro": SAMPLE_COLS[3:]}
SEGMENT_COLS = ("segment", "kind", "outer_deg", "middle_deg", "inner_deg", "outer_rate_dps")
PLAUSIBLE = 1e12  # no output, time or temperature of a real unit is this large (counts and pulse/s included)


@dataclass
class MeasurementSet:
    path: Path
    meta: meta_keys.Meta
    samples: dict[str, np.ndarray]    # column -> float array (segment as int array)
    segments: list[Segment] | None    # None: one continuous stream
    temperature_ref_c: float | None = None  # T_ref chosen by the user (calibrate --t-ref-c); None: t_ref_c's default
    sha256: str | None = None         # of the files as read (files_sha256): a calibration's input_sha256

    @property
    def t_ref_c(self) -> float | None:
        """T_ref of temperature terms (degC): the user's, else the mean of temp_c over every row; None
        without a temp_c column. Calibrations write it (t_ref_c) and apply reads it back."""
        if "temp_c" not in self.samples:
            return None
        if self.temperature_ref_c is not None:
            return float(self.temperature_ref_c)
        return float(np.mean(self.samples["temp_c"]))

    def copy(self, **changes) -> MeasurementSet:
        """dataclasses.replace, keeping what _once found where only T_ref changes (an entry that depends on
        T_ref has it in its key): a copy for its own T_ref keeps the reader's column extremes and row groups."""
        out = dataclasses.replace(self, **changes)
        if set(changes) <= {"temperature_ref_c"}:
            out.__dict__["_cache"] = dict(self.__dict__.get("_cache", {}))
        return out

    @property
    def has_acc(self):
        return "ax" in self.samples

    @property
    def has_gyro(self):
        return "gx" in self.samples

    @property
    def sensors(self) -> list[str]:
        """The sensors the set records: acc, gyro or both."""
        return [s for s, cols in SENSOR_COLS.items() if cols[0] in self.samples]

    def raw(self, sensor: str) -> np.ndarray:
        """The outputs of 'acc' (ax ay az) or 'gyro' (gx gy gz) as recorded, in their own unit (n, 3),
        read-only."""
        cols = SAMPLE_COLS[:3] if sensor == "acc" else SAMPLE_COLS[3:]
        return self._once(("raw", sensor), cols, lambda: _block_or_stack(self.samples, cols))

    def acc_g(self) -> np.ndarray:
        """Accelerometer outputs in g (n, 3), read-only."""
        return self._once(("g", "acc"), SAMPLE_COLS[:3], lambda: self.in_units("acc", slice(None)))

    def gyro_dph(self) -> np.ndarray:
        """Gyro outputs in deg/h (n, 3), read-only."""
        return self._once(("g", "gyro"), SAMPLE_COLS[3:], lambda: self.in_units("gyro", slice(None)))

    def in_units(self, sensor: str, rows) -> np.ndarray:
        """acc_g() or gyro_dph() of some rows alone (a slice or indices): the same numbers, without the whole
        set converted (38 MB a sensor at 1.6 million rows, and as many page faults): elementwise, the same bits."""
        return (units.acc_to_g if sensor == "acc" else units.gyro_to_dph)(self.raw(sensor)[rows], self.meta)

    def rows(self, segment: int) -> np.ndarray:
        """The indices (ascending) of one segment's rows; empty if it has none."""
        groups = self._once("rows", ("segment",), lambda: group_rows(self.samples["segment"]), meta=False)
        return groups.get(segment, np.zeros(0, int))

    def sample_digests(self) -> list[str]:
        """Per segment (a stream: one for the whole), the first 16 hex digits of the SHA-256 of its sensor
        outputs' numbers (float64, the columns of ax..gz present, one after the other): the samples themselves,
        whatever meta.json, segments.csv, t_s or the number format say. A calibration records them
        (samples_sha256) and validate finds its own rows by them. Found once per set (on a thread of
        its own while a turntable method averages the segments: hashlib frees the GIL)."""
        names = tuple(c for c in ("segment", *SAMPLE_COLS) if c in self.samples)
        return list(self._once("digests", names, self._digests, meta=False))

    def _digests(self) -> list[str]:
        cols = [np.asarray(self.samples[c], "<f8") for c in SAMPLE_COLS if c in self.samples]
        out = []
        for rows in [slice(None)] if self.segments is None else [run_or_rows(self.rows(s.segment))
                                                                 for s in self.segments]:
            h = hashlib.sha256()
            for c in cols:  # column by column
                h.update(np.ascontiguousarray(c[rows]).data)
            if len(cols[0][rows]):
                out.append(h.hexdigest()[:16])
        return out

    def _once(self, name, cols, make, meta=True):
        """make(), formed once per set of columns and (meta=True: it reads it) meta.json (the methods ask
        many times; at 300,000 rows each costs milliseconds). Arrays are made read-only: callers share them."""
        key = (tuple(id(self.samples[c]) for c in cols), json.dumps(self.meta, sort_keys=True, default=str) if meta
               else None)
        cache = self.__dict__.setdefault("_cache", {})
        if cache.get(name, (None,))[0] != key:
            out = make()
            for a in (out.values() if isinstance(out, dict) else out if isinstance(out, tuple) else [out]):
                if isinstance(a, np.ndarray):
                    a.flags.writeable = False
            cache[name] = (key, out)
        return cache[name][1]


def _block_or_stack(samples, cols) -> np.ndarray:
    """The (n, 3) outputs of one triad: the block read_samples formed its columns in (no copy), else
    the columns stacked."""
    block = triad_block(samples, cols)
    return block if block is not None else np.column_stack([samples[c] for c in cols])


def run_or_rows(rows):
    """A segment's row indices as a slice where they are one run, as recorded (indexing then gives a
    view, not a copy), else themselves."""
    return slice(rows[0], rows[-1] + 1) if len(rows) and rows[-1] - rows[0] + 1 == len(rows) else rows


def group_rows(segment_ids: np.ndarray) -> dict[int, np.ndarray]:
    """{segment id: the indices (ascending) of its rows}, found by one stable sort; without one where
    the ids never decrease (a set recorded segment by segment: its rows in runs, found in one pass)."""
    if len(segment_ids) > 1 and np.all(segment_ids[1:] >= segment_ids[:-1]):
        start = np.flatnonzero(segment_ids[1:] != segment_ids[:-1]) + 1
        return dict(zip(segment_ids[np.r_[0, start]].tolist(), np.split(np.arange(len(segment_ids)), start)))
    order = np.argsort(segment_ids, kind="stable")
    ids, start = np.unique(segment_ids[order], return_index=True)
    return dict(zip(ids.tolist(), np.split(order, start[1:])))


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
    return _check_samples(samples, path, segments, extremes is not None), sha256, extremes


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
        return _check_samples(samples, path, segments), files_sha256(folder, path.read_bytes(), path.name), None
    except MeasurementSetError as e:
        raise at_row(path, e, 0) from None


def _check_samples(out, path, segments, plausible=False):
    """The samples' rules (plausible: every number is known to be within +-PLAUSIBLE, as read_columns
    reports where its C parser checked them)."""
    if plausible:
        plausible = [len(v) > 0 for v in out.values()]
    else:
        with ThreadPoolExecutor(2) as pool:  # two reductions a column, no temporary: the usual file, on both cores
            plausible = list(pool.map(lambda v: bool(len(v) and -PLAUSIBLE <= v.min() and v.max() <= PLAUSIBLE),
                                      out.values()))
    for (c, v), fine in zip(out.items(), plausible):
        if fine:
            continue
        big = np.nonzero(np.abs(v) > PLAUSIBLE)[0]
        if big.size:
            raise MeasurementSetError(path, 2 + int(big[0]), f"column {c}: {v[big[0]]:g} is not a plausible value "
                                                             f"(|value| > {PLAUSIBLE:g})")
    if segments is None:  # one continuous stream: time runs forward over the whole file
        bad = np.nonzero(np.diff(out["t_s"]) <= 0)[0]
        if bad.size:
            i = int(bad[0]) + 1
            raise MeasurementSetError(path, 2 + i, f"t_s must increase through a stream: {out['t_s'][i]:g} s follows "
                                                   f"{out['t_s'][i - 1]:g} s (rows repeated, or files joined out of "
                                                   "order?)")
    if "segment" in out:
        seg = out["segment"].astype(int)
        if not np.array_equal(seg, out["segment"]):
            raise MeasurementSetError(path, None, "segment ids must be integers")
        out["segment"] = seg  # the float column freed at once: reading holds the file's bytes still
        if len(seg) > 1 and np.all(seg[1:] >= seg[:-1]):  # recorded segment by segment: no sort, no copies
            first = np.r_[0, np.flatnonzero(seg[1:] != seg[:-1]) + 1]
            groups = dict(zip(seg[first].tolist(), first[:, None]))  # each segment's first row
            seg_t: tuple[np.ndarray, np.ndarray, np.ndarray | None] = (seg, out["t_s"], None)
        else:
            groups = group_rows(seg)
            order = np.concatenate(list(groups.values()))  # the rows segment by segment, ascending ids
            seg_t = (seg[order], out["t_s"][order], order)
        unknown = sorted(set(groups) - {s.segment for s in segments}) if segments is not None else []
        if unknown:
            raise MeasurementSetError(path, 2 + int(groups[unknown[0]][0]),
                                      f"segment {unknown[0]} is not in segments.csv")
        _time_runs_forward(path, *seg_t)
    return out


def _time_runs_forward(path, seg, t, order):
    """Refuse a row whose t_s does not follow its segment's row before (seg, t: the rows segment by
    segment; order: their rows in the file, None where they are in the file's order)."""
    bad = np.flatnonzero((t[1:] <= t[:-1]) & (seg[1:] == seg[:-1]))
    if bad.size:
        row = bad[0] + 1 if order is None else order[bad[0] + 1]
        raise MeasurementSetError(path, 2 + int(row), f"t_s must increase within segment {seg[bad[0]]}")


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
    ms = MeasurementSet(folder, meta, samples, segments, sha256=sha256)
    if extremes is not None:
        sensor_checks.known_extremes(ms, extremes)
    return ms


def _fmt(v):
    return "" if v is None else repr(float(v))


def write_set(folder, meta: Mapping[str, Any], samples: dict, segments: list[Segment] | None = None, extra_files=None):
    """Write a measurement set; extra_files: {name: json-able} (e.g. truth.json). Each file by a
    temporary name and a rename (io/outputs.py); the caller has checked the folder with outputs.check."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    outputs.write_text(folder / "meta.json", json.dumps({"format": FORMAT, **meta}, indent=2) + "\n")
    if segments is not None:
        with outputs.replacing(folder / "segments.csv") as tmp, tmp.open("w", newline="") as fh:
            w = csv.writer(fh)
            has_ref = any(s.heading_ref_deg is not None for s in segments)
            w.writerow(SEGMENT_COLS + (("heading_ref_deg",) if has_ref else ()))
            for s in segments:
                row = [s.segment, s.kind, _fmt(s.outer_deg), _fmt(s.middle_deg), _fmt(s.inner_deg),
                       _fmt(s.outer_rate_dps) if s.kind == "rate" else ""]
                w.writerow(row + ([_fmt(s.heading_ref_deg)] if has_ref else []))
    elif (folder / "segments.csv").is_file():  # a stream replacing a segmented set (--force): no stale segments
        (folder / "segments.csv").unlink()
    cols = [c for c in ("segment", "t_s", *SAMPLE_COLS, "temp_c") if c in samples]
    cols += [c for c in samples if c not in cols]  # auxiliary inputs (supply_v, ...)
    import pyarrow as pa  # Arrow's writer: each number the shortest text that reads back to it, 3x faster
    # than repr and csv.writer row by row
    import pyarrow.csv as pa_csv
    table = pa.table({c: np.asarray(samples[c], np.int64 if c == "segment" else np.float64) for c in cols})
    with outputs.replacing(folder / "samples.csv") as tmp, tmp.open("wb") as fh:
        header = _io.StringIO()
        csv.writer(header, lineterminator="\n").writerow(cols)  # a name holding a comma or a quote quoted
        fh.write(header.getvalue().encode())
        pa_csv.write_csv(table, fh, pa_csv.WriteOptions(include_header=False, batch_size=1 << 16))
    (folder / "samples.parquet").unlink(missing_ok=True)  # a set replaced (--force): it would hold its samples twice
    for name, obj in (extra_files or {}).items():
        outputs.write_text(folder / name, json.dumps(obj, indent=2) + "\n")
