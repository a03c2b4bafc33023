"""A measurement set written as its folder (meta.json, segments.csv, samples.csv; spec:
docs/spec/measurement-set.md), each file by a temporary name and a rename."""
from __future__ import annotations

import csv
import io as _io
import json
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from simucal.io import outputs
from simucal.io.segments import Segment
from simucal.io.set_rules import FORMAT, SAMPLE_COLS, SEGMENT_COLS


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
