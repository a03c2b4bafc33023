"""samples.parquet beside samples.csv, and either read in chunks (issue 41: recordings of hours).

A set holds its samples in samples.csv or, as a compatible extension of the spec
(docs/notes/samples-parquet.md), in samples.parquet: the same columns, named as in samples.csv,
each a column of integers or floats without nulls (columns of anything else, a note or a label,
are left out, as samples.csv's columns that are not numbers). Every rule of samples.csv holds;
a break names the row (counted from 1 after the header) where samples.csv names the line.

`chunks` reads either a few hundred thousand rows at a time, each chunk checked as the whole file
would be, so that a long recording is never held as a table in memory (`simucal noise`,
`simucal convert`); `read_parquet` reads the whole file for the commands that need every row.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from simucal.io import MeasurementSetError, _check_samples, _header, _sample_columns, read_samples
from simucal.io.text_files import body_of, not_a_folder

BLOCK_BYTES = 32 << 20  # CSV read this many bytes at a time (about 300,000 rows of a six-channel stream)
BATCH_ROWS = 1 << 18    # parquet read this many rows at a time


def samples_path(folder: Path) -> Path:
    """The set's samples file: samples.csv, or samples.parquet where that is there instead."""
    folder = Path(folder)
    csv_path, parquet = folder / "samples.csv", folder / "samples.parquet"
    if parquet.exists() or parquet.is_symlink():
        if csv_path.exists():
            raise MeasurementSetError(folder, None, "holds both samples.csv and samples.parquet: a set holds its "
                                                    "samples once; remove one (simucal convert writes either)")
        return not_a_folder(parquet)
    return csv_path


def is_parquet(path: Path) -> bool:
    return Path(path).suffix == ".parquet"


def _where(path, e: MeasurementSetError, before: int) -> MeasurementSetError:
    """A chunk's refusal (its line counted in the chunk) moved to the file's line, or row of a parquet."""
    if e.line is None:
        return e
    if is_parquet(path):
        return MeasurementSetError(path, None, f"row {e.line - 1 + before}: {e.rule}")
    return MeasurementSetError(path, e.line + before, e.rule)


def _parquet_file(path):
    import pyarrow as pa
    import pyarrow.parquet as pq
    try:
        return pq.ParquetFile(path)
    except (pa.ArrowException, OSError) as e:
        raise MeasurementSetError(path, None, f"not a readable Parquet file ({str(e)[:120]}); write it with "
                                              "simucal convert --to parquet") from None


def _numeric(field) -> bool:
    import pyarrow as pa
    return pa.types.is_integer(field.type) or pa.types.is_floating(field.type)


def columns_of(path, segments) -> tuple[list, list]:
    """(the spec's columns present, the other numeric columns) of samples.csv or samples.parquet, with
    the header's rules checked; a spec column of a Parquet file must hold numbers."""
    if not is_parquet(path):
        if not path.is_file():
            raise MeasurementSetError(path, None, "missing: a measurement set needs samples.csv (or samples.parquet)")
        with open(path, "rb") as fh:
            head = fh.read(65536)
        body = body_of(path, head)
        if not len(body):
            raise MeasurementSetError(path, 1, "empty file")
        return _sample_columns(path, _header(path, body), segments)
    schema = _parquet_file(path).schema_arrow
    cols, others = _sample_columns(path, list(schema.names), segments)
    for c in cols:
        if not _numeric(schema.field(c)):
            raise MeasurementSetError(path, None, f"column {c} holds {schema.field(c).type}, not numbers: the spec's "
                                                  "columns hold integers or floats")
    return cols, [c for c in others if _numeric(schema.field(c))]


def _floats(batch, names) -> dict | None:
    """The batch's columns as float64 arrays; None where one holds a null or a value not finite."""
    import pyarrow as pa

    from simucal.io import _column_floats
    out = {}
    for c in names:
        col = pa.chunked_array([batch.column(c)])
        if col.null_count:
            return None
        out[c] = _column_floats(col)
        if not np.all(np.isfinite(out[c])):
            return None
    return out


def _batches(path, names):
    """Record batches of the named columns (CSV: parsed as float64, one thread, see io._fast_numeric)."""
    import pyarrow as pa
    if is_parquet(path):
        yield from _parquet_file(path).iter_batches(batch_size=BATCH_ROWS, columns=names)
        return
    import pyarrow.csv as pa_csv
    reader = pa_csv.open_csv(path, read_options=pa_csv.ReadOptions(use_threads=False, block_size=BLOCK_BYTES),
                             convert_options=pa_csv.ConvertOptions(include_columns=names,
                                                                   column_types={c: pa.float64() for c in names}))
    yield from reader


def _careful_refusal(path, folder, segments, detail):
    """A CSV the chunked reader cannot take: the careful reader names the line (it reads the whole
    file once, as every command did before chunks); a Parquet file: its row is not known."""
    if not is_parquet(path):
        read_samples(Path(folder), segments)
    return MeasurementSetError(path, None, f"holds a value that is not a finite number ({detail}): the spec's "
                                           "columns hold numbers in every row")


def chunks(folder, names, segments=None):
    """The named columns (float64) of the set's samples file, a chunk at a time, each checked by the
    spec's rules (numbers, plausible, t_s increasing through a stream, also across chunks), a
    break named by its line (samples.csv) or row (samples.parquet)."""
    import pyarrow as pa
    path = samples_path(folder)
    before, last_t = 0, None
    try:
        for batch in _batches(path, names):
            out = _floats(batch, names)
            if out is None:
                raise _careful_refusal(path, folder, segments, "a null, an empty cell, NaN or infinity")
            try:
                out = _check_samples(out, path, segments)
            except MeasurementSetError as e:
                raise _where(path, e, before) from None
            if segments is None and last_t is not None and len(out["t_s"]) and out["t_s"][0] <= last_t:
                raise _where(path, MeasurementSetError(path, 2, f"t_s must increase through a stream: "
                                                                f"{out['t_s'][0]:g} s follows {last_t:g} s"), before)
            before += len(out["t_s"])
            last_t = out["t_s"][-1] if len(out["t_s"]) else last_t
            yield out
    except (pa.ArrowException, ValueError) as e:
        if isinstance(e, MeasurementSetError):
            raise
        raise _careful_refusal(path, folder, segments, str(e).splitlines()[0][:120]) from None
    if before == 0:
        raise MeasurementSetError(path, None, "no samples")


def read_parquet(folder: Path, segments) -> tuple[dict, bytes]:
    """(column -> array, the file's bytes) of samples.parquet: read_samples for a Parquet file."""
    path = samples_path(folder)
    cols, others = columns_of(path, segments)
    parts = list(chunks(folder, cols + others, segments))
    samples = {c: np.concatenate([p[c] for p in parts]) for c in cols + others}
    del parts
    try:
        samples = _check_samples(samples, path, segments)
    except MeasurementSetError as e:
        raise _where(path, e, 0) from None
    return samples, path.read_bytes()


def _table(chunk: dict, names):
    import pyarrow as pa
    return pa.table({c: pa.array(chunk[c], pa.int64() if c == "segment" else pa.float64()) for c in names})


def write_samples(path: Path, parts, names) -> int:
    """Write the chunks (dicts of the named columns) to path, samples.csv or samples.parquet, by a
    temporary name and a rename (io/outputs.py); the rows written. CSV: a plain header and each
    number as Python's repr writes it (the shortest that reads back the same float)."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    from simucal.io import outputs
    rows = 0
    with outputs.replacing(path) as tmp, open(tmp, "wb") as fh:
        if is_parquet(path):
            schema = pa.schema([(c, pa.int64() if c == "segment" else pa.float64()) for c in names])
            writer = pq.ParquetWriter(fh, schema)
        else:
            fh.write((",".join(names) + "\n").encode())
            writer = pa_csv.CSVWriter(fh, _table({c: np.zeros(0) for c in names}, names).schema,
                                      write_options=pa_csv.WriteOptions(include_header=False, quoting_style="none"))
        with writer:
            for chunk in parts:
                writer.write_table(_table(chunk, names))
                rows += len(chunk[names[0]])
    return rows


def convert(folder, out, to: str) -> tuple[Path, int]:
    """Copy the set in folder to out (a new folder), its samples written as samples.{to} ("csv" or
    "parquet"), read and written a chunk at a time, every row checked as it is read; meta.json and
    segments.csv are copied as they are. (the samples file written, its rows)."""
    from simucal.io import outputs, read_meta, read_segments
    folder, out = Path(folder), Path(out)
    read_meta(folder)
    segments = read_segments(folder)
    source = samples_path(folder)
    cols, others = columns_of(source, segments)
    names = cols + others
    out.mkdir(parents=True, exist_ok=True)
    for name in ("meta.json", "segments.csv"):
        if (folder / name).is_file():
            with outputs.replacing(out / name) as tmp:
                tmp.write_bytes((folder / name).read_bytes())
    target = out / f"samples.{to}"
    rows = write_samples(target, chunks(folder, names, segments), names)
    # a set replaced (--force): its other samples file, or a segments.csv the input lacks, would be stale
    for stale in [out / ("samples.csv" if to == "parquet" else "samples.parquet")] + [out / "segments.csv"] * (
            segments is None):
        stale.unlink(missing_ok=True)
    return target, rows
