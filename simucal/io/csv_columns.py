"""samples.csv's numbers straight into the arrays a set keeps: each triad (ax ay az, gx gy gz) one
(n, 3) float64 block whose columns the samples dict views (the raw outputs formed once:
MeasurementSet.raw returns the block), every other column one float64 array.

The file is cut in pieces of PIECE_BYTES at line ends, parsed two at a time on two Python threads
(each parser frees the GIL). Where a C compiler is found, by csv_numbers.c, built into the cache
(io/cache.py) at first use: plain decimal numbers, each correctly rounded as pyarrow and float()
round it, 4x faster than pyarrow's parse and with no table copied out; anything else it stops at
(a blank line, text, NaN, a quote) sends the whole file to pyarrow's C++ CSV reader, as where no
compiler is found. pyarrow parses the spec's columns as float64 from the start (type inference
and a conversion cost 2.8x the parse), each piece's table copied out and dropped. Each piece with
use_threads=False: Arrow's own CPU pool left std::threads alive at exit, about one exit in a
hundred a SIGABRT (apache/arrow#34314), while these threads are joined before the
function returns."""
from __future__ import annotations

import ctypes
import functools
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from simucal.io.text_files import MeasurementSetError

TRIADS = (("ax", "ay", "az"), ("gx", "gy", "gz"))
PIECE_BYTES = 4 << 20  # parsed two at a time: the tables held at once are two pieces', not the file's
Columns = dict[str, NDArray[np.float64]]  # {column: its values}
Extremes = tuple[float, float, int, int]  # a column's (least, greatest, rows at the least, rows at the greatest)


def read_columns(body: memoryview, header: list[str], spec_cols: list[str], others: list[str],
                 bound: float) -> tuple[Columns | None, dict[str, Extremes] | None]:
    """({column: float64 array} of spec_cols and others, or None if anything is unusual (a cell that
    is not a number, an empty cell, a ragged row, a NaN or an infinity): the careful reader then names
    the line and the column; {column: (least, greatest, rows at the least, rows at the greatest)} where
    every number is known to lie within +-bound, else None). A column of others holding text also gives
    None, as before. The pieces go into arrays sized by the file's line count: no table of the whole file is held.
    csv_numbers.c checks each number against bound and keeps each column's extremes as it parses it (no further
    pass over the columns); pyarrow's numbers are checked to be finite here, and against bound by the
    caller, which names the row."""
    names = spec_cols + others
    with ThreadPoolExecutor(2) as pool:
        pieces, quoted = _pieces(body, pool)
        counts = [lines - skip for _, _, skip, lines in pieces]
        out = _allocate(names, sum(counts))
        starts = np.cumsum([0] + counts[:-1]).tolist()
        native = _native()[0] if _native() and not quoted and sorted(header) == sorted(names) else None
        extremes = np.tile([np.inf, -np.inf, 0, 0], (len(pieces), len(header)))  # a piece's _merged, a column
        rows: list | None  # each piece's rows; a piece pyarrow refuses gives None
        rows = list(pool.map(lambda k: _parse_native(native, body, pieces[k], header, out, starts[k], counts[k],
                                                     bound, extremes[k]), range(len(pieces)))) if native else None
        if rows == counts and sum(counts):  # no rows: the careful reader says so
            return out, {c: _merged(extremes[:, 4 * j:4 * j + 4]) for j, c in enumerate(header)}
        buf = _arrow_buffer(body)  # no compiler, or a cell the C parser does not take: pyarrow reads the file
        rows = list(pool.map(lambda k: _parse_into(buf.slice(pieces[k][0], pieces[k][1] - pieces[k][0]),
                                                   pieces[k][2], header, spec_cols, out, starts[k], counts[k]),
                             range(len(pieces))))
    if None in rows or sum(rows) == 0:
        return None, None
    if rows != counts:  # blank lines (the parser skips them): the pieces' rows moved together
        out = {c: np.concatenate([v[a:a + r] for a, r in zip(starts, rows)]) for c, v in out.items()}
        out = _triads_formed(out)
    if not all(np.isfinite(v).all() for v in out.values()):
        return None, None
    return out, None


def _merged(pieces) -> Extremes:
    """A column's (least, greatest, rows at the least, rows at the greatest) from its pieces' own (k, 4)."""
    least, greatest = float(pieces[:, 0].min()), float(pieces[:, 1].max())
    return least, greatest, int(pieces[pieces[:, 0] == least, 2].sum()), int(pieces[pieces[:, 1] == greatest, 3].sum())


@functools.cache
def _native():
    """csv_numbers.c's (parse, count lines), built into the cache at first use; None without a compiler."""
    from simucal.io.cache import compile_c
    built = compile_c("csv_numbers", Path(__file__).with_name("csv_numbers.c").read_text(), "pyarrow's parser")
    if built is None:
        return None
    lib = ctypes.CDLL(str(built))  # ctypes frees the GIL while a function of it runs
    parse, lines = lib.simucal_csv_numbers, lib.simucal_csv_lines
    parse.argtypes = [ctypes.c_void_p, ctypes.c_long, ctypes.c_int, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p),
                      ctypes.POINTER(ctypes.c_long), ctypes.c_long, ctypes.c_double, ctypes.c_void_p]
    lines.argtypes = [ctypes.c_void_p, ctypes.c_long, ctypes.POINTER(ctypes.c_int)]
    parse.restype = lines.restype = ctypes.c_long
    return parse, lines


def prepare():
    """The parser loaded: csv_numbers.c's (built at first use), else pyarrow's (imported)."""
    if _native() is None:
        import pyarrow.csv  # noqa: F401


def _parse_native(native, body, piece, header, out, start, count, bound, extremes) -> int:
    """One piece (a, b, skip, lines) parsed by csv_numbers.c into out[c][start:start + count] (every
    column of the header wanted), each column's least, greatest and the rows at each into extremes (4
    per column): the rows it held, or -1 where it stopped (or met a number beyond +-bound)."""
    a, b, skip, _ = piece
    cols = [out[c][start:] for c in header]
    at = np.frombuffer(body, np.uint8).ctypes.data + a
    return native(at, b - a, skip, len(cols), (ctypes.c_void_p * len(cols))(*[v.ctypes.data for v in cols]),
                  (ctypes.c_long * len(cols))(*[v.strides[0] // 8 for v in cols]), count, bound,
                  extremes.ctypes.data)


def _arrow_buffer(body):
    import pyarrow as pa
    return pa.py_buffer(body)


def _parse_into(buf, skip_rows, header, spec_cols, out, start, count) -> int | None:
    """One piece parsed and copied into out[c][start:start + count]: the rows it held, or None where
    pyarrow refuses it, a column is not numbers without gaps, or it holds more rows than lines. By
    read_csv on this thread: pyarrow's streaming reader (open_csv) starts threads of Arrow's pool
    even with use_threads=False, alive at exit (the SIGABRT above)."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    try:
        table = pa_csv.read_csv(
            buf, read_options=pa_csv.ReadOptions(use_threads=False, column_names=header, skip_rows=skip_rows),
            convert_options=pa_csv.ConvertOptions(column_types={c: pa.float64() for c in spec_cols}),
            memory_pool=pa.system_memory_pool())
    except (pa.ArrowException, ValueError):
        return None
    if table.num_rows > count:
        return None
    for c, v in out.items():
        col = table.column(header.index(c))
        if col.null_count or not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)):
            return None
        row = start
        for chunk in col.chunks:
            np.copyto(v[row:row + len(chunk)], _numbers(chunk))
            row += len(chunk)
    return table.num_rows


def _pieces(body, pool) -> tuple[list, bool]:
    """([(start, end, rows to skip, lines)] of each piece of about PIECE_BYTES, each cut after a line
    end (the first keeps the header line), whether the file holds a quote). One piece where it does
    (a quoted cell may hold a line end, so no cut is safe there). The pieces' line ends and quotes are
    counted on the pool's threads (_line_ends: numpy frees the GIL, where bytes.count and find held it
    for 0.17 s)."""
    cuts = [0]
    for k in range(1, len(body) // PIECE_BYTES + 1):
        end = _find_line_end(body, max(k * PIECE_BYTES, cuts[-1]))
        if end < 0 or end + 1 >= len(body):
            break
        cuts.append(end + 1)
    cuts.append(len(body))
    scans = list(pool.map(lambda ab: _line_ends(body[ab[0]:ab[1]]), zip(cuts, cuts[1:])))
    quoted = any(q for _, q in scans)
    if len(cuts) > 2 and quoted:
        cuts, scans = [0, len(body)], [(sum(lines for lines, _ in scans), True)]
    return [(a, b, int(a == 0), lines + (body[b - 1] != 10)) for a, b, (lines, _) in zip(cuts, cuts[1:], scans)], quoted


def _find_line_end(body, at) -> int:
    """The index of the first line end in body at or after at, or -1."""
    raw, offset = body.obj, len(body.obj) - len(body)  # the file's bytes, and where body starts (after a BOM)
    end = raw.find(b"\n", offset + at)
    return end - offset if end >= 0 else -1


SCAN_BYTES = 1 << 18  # a piece scanned this many bytes at a time: the comparisons' temporaries stay in the cache


def _line_ends(piece) -> tuple[int, bool]:
    """(the line ends in piece, whether it holds a quote): by csv_numbers.c, else by numpy."""
    a = np.frombuffer(piece, np.uint8)
    if _native():
        has_quote = ctypes.c_int(0)
        return _native()[1](a.ctypes.data, len(a), ctypes.byref(has_quote)), bool(has_quote.value)
    lines, quoted = 0, False
    for i in range(0, len(a), SCAN_BYTES):
        part = a[i:i + SCAN_BYTES]
        lines += int(np.count_nonzero(part == 10))
        quoted = quoted or bool((part == 34).any())
    return lines, quoted


def _allocate(names, n) -> dict:
    """The output arrays: a present triad's columns as views of one (n, 3) block."""
    return _triads_formed({c: None for c in names}, n)


def _triads_formed(columns, n=None) -> dict:
    """columns (arrays, or None with n: to be filled), a triad's as views of one (n, 3) block."""
    out = dict(columns)
    for triad in TRIADS:
        if all(c in out for c in triad):
            block = np.empty((n, 3)) if n is not None else np.column_stack([out[c] for c in triad])
            out.update({c: block[:, j] for j, c in enumerate(triad)})
    return {c: np.empty(n) if v is None else v for c, v in out.items()}


def _numbers(chunk) -> np.ndarray:
    """A numeric Arrow array without nulls as numbers, a view of its data buffer: pyarrow's to_numpy
    imports pandas where it is installed (0.25 s of a 1 s command)."""
    import pyarrow as pa
    kind = "f" if pa.types.is_floating(chunk.type) else "i" if pa.types.is_signed_integer(chunk.type) else "u"
    dtype = np.dtype(f"{kind}{chunk.type.bit_width // 8}")
    return np.frombuffer(chunk.buffers()[1], dtype=dtype, count=len(chunk), offset=chunk.offset * dtype.itemsize)


def triad_block(samples: dict, cols) -> np.ndarray | None:
    """The (n, 3) block whose columns samples[cols] are (as read_columns makes them), or None."""
    base = samples[cols[0]].base
    if not (isinstance(base, np.ndarray) and base.ndim == 2 and base.shape[1] == 3 and base.dtype == np.float64
            and base.flags.c_contiguous):
        return None
    at = base.__array_interface__["data"][0]
    for j, c in enumerate(cols):
        v = samples[c]
        if v.base is not base or v.shape != (len(base),) or v.__array_interface__["data"][0] != at + 8 * j:
            return None
    return base


def arrow_floats(path, data, names, before=0) -> dict[str, NDArray[np.float64]]:
    """The named numeric columns of an Arrow table or record batch as float64 arrays; a null, NaN or
    infinity refused naming its row (counted from 1; `before` rows came in earlier batches)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    out = {}
    for c in names:
        col = data.column(c)
        col = col if isinstance(col, pa.ChunkedArray) else pa.chunked_array([col])
        nulls = col.null_count
        out[c] = _column_floats(pc.fill_null(col.cast(pa.float64()), float("nan")) if nulls else col)
        bad = np.flatnonzero(~np.isfinite(out[c]))
        if bad.size:
            raise MeasurementSetError(path, None, f"row {before + int(bad[0]) + 1}, column {c}: "
                                                  f"{'empty' if nulls else out[c][bad[0]]} is not a finite number "
                                                  "(nulls, NaN and infinities are errors)")
    return out


def _column_floats(col) -> np.ndarray:
    """A numeric Arrow column without nulls as float64, read from its chunks' data buffers: pyarrow's
    to_numpy imports pandas where it is installed (0.25 s of a 1 s command)."""
    import pyarrow as pa
    kind = "f" if pa.types.is_floating(col.type) else "i" if pa.types.is_signed_integer(col.type) else "u"
    dtype = np.dtype(f"{kind}{col.type.bit_width // 8}")
    parts = [np.frombuffer(ch.buffers()[1], dtype=dtype, count=len(ch), offset=ch.offset * dtype.itemsize)
             for ch in col.chunks]
    return np.concatenate(parts).astype(float) if parts else np.zeros(0)
