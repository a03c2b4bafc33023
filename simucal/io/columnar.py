"""samples.parquet beside samples.csv, and either read in chunks (recordings of hours).

A set holds its samples in samples.csv or, as a compatible extension of the spec
(docs/notes/samples-parquet.md), in samples.parquet: the same columns, named as in samples.csv,
each a column of integers or floats without nulls (columns of anything else, a note or a label,
are left out, as samples.csv's columns that are not numbers). Every rule of samples.csv holds;
a break names the row (counted from 1 after the header) where samples.csv names the line.

`chunks` reads either a few hundred thousand rows at a time, each chunk checked as the whole file
would be, so that a long recording is never held as a table in memory (`simucal noise`,
`simucal convert`); io.read_set reads either whole for the commands that need every row.
"""
from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from simucal.io import (MeasurementSetError, _header, _sample_columns, arrow_floats, at_row, parquet_columns,
                        parquet_file, read_samples, samples_path)
from simucal.io.set_rules import check_samples
from simucal.io.text_files import body_of

BLOCK_BYTES = 32 << 20  # CSV read this many bytes at a time (about 300,000 rows of a six-channel stream)
BATCH_ROWS = 1 << 18    # parquet read this many rows at a time


def columns_of(path, segments) -> tuple[list, list]:
    """(the spec's columns present, the other numeric columns) of samples.csv or samples.parquet, with
    the header's rules checked."""
    if path.suffix == ".parquet":
        return parquet_columns(path, segments)
    if not path.is_file():
        raise MeasurementSetError(path, None, "missing: a measurement set needs samples.csv (or samples.parquet)")
    with open(path, "rb") as fh:
        head = fh.read(65536)
    body = body_of(path, head)
    if not len(body):
        raise MeasurementSetError(path, 1, "empty file")
    return _sample_columns(path, _header(path, body), segments)


def _batches(path, names, others):
    """Record batches of the named columns and others (CSV: the named parsed as float64, the others'
    types inferred; one thread, see io._fast_numeric)."""
    if path.suffix == ".parquet":  # pre_buffer (Arrow's default) read the whole file ahead: 1.1 GB held at 24 h
        yield from parquet_file(path, pre_buffer=False).iter_batches(batch_size=BATCH_ROWS, columns=names + others)
        return
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    options = (pa_csv.ReadOptions(use_threads=False),
               pa_csv.ConvertOptions(include_columns=names + others, column_types={c: pa.float64() for c in names}))
    for block in _csv_blocks(path):
        # one batch a block (read_csv's are 1 MB each): convert writes a row group a batch, not 8,141 rows a group
        yield from pa_csv.read_csv(pa.py_buffer(block), read_options=options[0],
                                   convert_options=options[1]).combine_chunks().to_batches()


def _csv_blocks(path):
    """samples.csv as the header line followed by BLOCK_BYTES of whole lines, one block at a time:
    Arrow's streaming CSV reader read ahead of its consumer without bound (23 GB for a 2.3 GB file)."""
    with open(path, "rb") as fh:
        header = fh.readline().removeprefix(b"\xef\xbb\xbf")
        rest = b""
        while True:
            data = fh.read(BLOCK_BYTES)
            if not data:
                if rest.strip():
                    yield header + rest
                return
            block = rest + data
            cut = block.rfind(b"\n") + 1
            block, rest = block[:cut], block[cut:]
            if block:
                yield header + block


def _careful_refusal(path, folder, segments, detail):
    """A CSV the chunked reader cannot take: the careful reader names the line (it reads the whole
    file once, as every command did before chunks)."""
    read_samples(Path(folder), segments)
    return MeasurementSetError(path, None, f"not readable as the spec's CSV ({detail})")


def chunks(folder, names, segments=None, others=()):
    """The named columns (float64) of the set's samples file, a chunk at a time, each checked by the
    spec's rules (numbers, plausible, t_s increasing through a stream, also across chunks), a
    break named by its line (samples.csv) or row (samples.parquet); with them the columns `others`
    that the first chunk holds as numbers (a column of notes is left out, as the whole-file reader
    leaves it)."""
    import pyarrow as pa
    path = samples_path(folder)
    before, last_t, kept = 0, None, None
    try:
        for batch in _batches(path, list(names), list(others)):
            if kept is None:
                kept = [c for c in others if pa.types.is_integer(batch.schema.field(c).type)
                        or pa.types.is_floating(batch.schema.field(c).type)]
            try:
                out = check_samples(arrow_floats(path, batch, list(names) + kept, before), path, segments)
                if segments is None and last_t is not None and out["t_s"][0] <= last_t:
                    raise MeasurementSetError(path, 2, f"t_s must increase through a stream: {out['t_s'][0]:g} s "
                                                       f"follows {last_t:g} s")
            except MeasurementSetError as e:
                if e.line is None and path.suffix == ".csv":  # a null or NaN: the careful reader names its line
                    raise _careful_refusal(path, folder, segments, e.rule) from None
                raise at_row(path, e, before) from None
            before, last_t = before + len(out["t_s"]), out["t_s"][-1]
            yield out
    except pa.ArrowException as e:  # a CSV row that is not numbers, or ragged
        raise _careful_refusal(path, folder, segments, str(e).splitlines()[0][:120]) from None
    if before == 0:
        raise MeasurementSetError(path, None, "no samples")


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
        if path.suffix == ".parquet":
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
    parts = chunks(folder, cols, segments, others)
    first = next(parts)
    out.mkdir(parents=True, exist_ok=True)
    for name in ("meta.json", "segments.csv"):
        if (folder / name).is_file():
            with outputs.replacing(out / name) as tmp:
                tmp.write_bytes((folder / name).read_bytes())
    target = out / f"samples.{to}"
    rows = write_samples(target, itertools.chain([first], parts), list(first))
    # a set replaced (--force): its other samples file, or a segments.csv the input lacks, would be stale
    for stale in [out / ("samples.csv" if to == "parquet" else "samples.parquet")] + [out / "segments.csv"] * (
            segments is None):
        stale.unlink(missing_ok=True)
    return target, rows
