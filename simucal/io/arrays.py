"""A measurement set from arrays or a DataFrame, held in memory (no folder): the same set
`read_set` gives, checked by the same rules (the spec, docs/spec/measurement-set.md), each
refusal naming the argument, the row and the fix.

Without `segments` the rows are one stream (a hand-placed session: the static poses are found
from the data); with `segments` (the table of segments.csv) and each row's `segment` id, a
turntable test (table angles) or a field set (heading_ref_deg).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Callable, Mapping, TypeVar

import numpy as np

from simucal.io import units
from simucal.io.segments import KINDS, Segment
from simucal.io.set_rules import SAMPLE_COLS, check_samples
from simucal.io.text_files import MeasurementSetError

KEYS = ("segment", "t_s", "temp_c") + SAMPLE_COLS  # the spec's columns, as a DataFrame may name them

T = TypeVar("T")  # the set's class (io.MeasurementSet, whose constructors these are)


def _triad(x, what, n=None) -> np.ndarray | None:
    """x as a finite (n, 3) float array, or None."""
    if x is None:
        return None
    a = np.asarray(x, float)
    if a.ndim != 2 or a.shape[1] != 3 or (n is not None and len(a) != n):
        want = f"({n}, 3)" if n is not None else "(n, 3)"
        raise MeasurementSetError(what, None, f"shape {a.shape}, expected {want}: one row per sample, columns x y z")
    return a


def _column(x, what, n) -> np.ndarray:
    a = np.asarray(x, float).ravel()
    if a.shape != (n,):
        raise MeasurementSetError(what, None, f"{a.size} values for {n} samples: give one per row")
    return a


def _times(n, rate_hz, t_s) -> np.ndarray:
    if (rate_hz is None) == (t_s is None):
        raise MeasurementSetError("t_s", None, "give the sample times either as rate_hz= (Hz, evenly sampled from 0 s) "
                                               "or as t_s= (s, one per row), not both and not neither")
    if t_s is not None:
        return _column(t_s, "t_s", n)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise MeasurementSetError("rate_hz", None, f"{rate_hz!r}: the sample rate must be a number > 0 (Hz)")
    return np.arange(n) / float(rate_hz)


def _segment_table(segments) -> list[Segment]:
    """Segments from Segment objects, mappings with segments.csv's columns, or a DataFrame of them
    (as pandas reads segments.csv: an empty cell NaN, here None)."""
    if hasattr(segments, "to_dict") and hasattr(segments, "columns"):
        segments = [{k: None if isinstance(v, float) and v != v else v for k, v in row.items()}
                    for row in segments.to_dict("records")]
    out = []
    for i, s in enumerate(segments):
        if isinstance(s, Segment):
            out.append(s)
            continue
        try:
            out.append(Segment(int(s["segment"]), str(s["kind"]), s.get("outer_deg"), s.get("middle_deg"),
                               s.get("inner_deg"), float(s.get("outer_rate_dps") or 0.0), s.get("heading_ref_deg")))
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise MeasurementSetError("segments", i + 1, f"{e!r}: each segment is a Segment or a mapping with "
                                                         "segment, kind and segments.csv's other columns") from None
        if out[-1].kind not in KINDS:
            raise MeasurementSetError("segments", i + 1,
                                      f"kind must be one of {', '.join(KINDS)}, got {out[-1].kind!r}")
    return out


def _finite(samples: dict, name: str) -> None:
    for c, v in samples.items():
        bad = np.nonzero(~np.isfinite(v))[0]
        if bad.size:
            raise MeasurementSetError(name, None, f"row {int(bad[0])}, column {c}: {v[bad[0]]} is not finite (NaN and "
                                                  "infinities are errors: drop or fill those rows first)")


def digest(meta: Mapping[str, Any], samples: dict, segments) -> str:
    """sha256 of the set's content (what input_sha256 holds for a set read from files): validate tells
    a calibration's own data from independent data by it."""
    h = hashlib.sha256(json.dumps(meta, sort_keys=True, default=str).encode())
    for c in sorted(samples):
        h.update(c.encode() + np.ascontiguousarray(samples[c], float).tobytes())
    h.update(repr(segments).encode())
    return h.hexdigest()


def from_arrays(acc=None, gyro=None, *, acc_unit, gyro_unit, rate_hz=None, t_s=None, temp_c=None, segment=None,
                segments=None, columns=None, meta=None, name="arrays", cls: Callable[..., T]) -> T:
    """The set of raw outputs acc and gyro ((n, 3) each, either may be None) in acc_unit and
    gyro_unit (the spec's units); the times from rate_hz or t_s; temp_c (degC) and further named
    columns (a user's model's inputs) one value per row; meta: meta.json's other keys
    (latitude_deg, required with gyro data; nominal scale factors for pulse/s and counts; noise)."""
    if acc is None and gyro is None:
        raise MeasurementSetError(name, None, "neither acc nor gyro given: a set needs one of them")
    n = len(acc if acc is not None else gyro)
    meta = {**(meta or {}), "acc_unit": acc_unit, "gyro_unit": gyro_unit}
    units.check_meta(meta, f"{name} (meta)", MeasurementSetError)
    if gyro is not None and "latitude_deg" not in meta:
        raise MeasurementSetError(f"{name} (meta)", None, "latitude_deg is required with gyro data (the Earth rate "
                                                          "the gyros see): pass meta={'latitude_deg': ...}")
    samples = {"t_s": _times(n, rate_hz, t_s)}
    for sensor, x in (("a", _triad(acc, "acc", n)), ("g", _triad(gyro, "gyro", n))):
        if x is not None:
            samples.update({sensor + c: x[:, j] for j, c in enumerate("xyz")})
    for c, v in {**({"temp_c": temp_c} if temp_c is not None else {}), **(columns or {})}.items():
        samples[c] = _column(v, c, n)
    table = None
    if segments is not None or segment is not None:
        if segments is None or segment is None:
            raise MeasurementSetError("segments", None,
                                      "segments= (the table) and segment= (each row's id) go together")
        table = _segment_table(segments)
        samples["segment"] = _column(segment, "segment", n)
    _finite(samples, name)
    try:
        samples = check_samples(samples, Path(name), table)
    except MeasurementSetError as e:  # its line of samples.csv is row line - 2 here
        raise MeasurementSetError(name, None, (f"row {e.line - 2}: " if e.line else "") + e.rule) from None
    return cls(Path(name), meta, samples, table, sha256=digest(meta, samples, table))


def from_dataframe(df, *, acc_unit, gyro_unit, columns=None, rate_hz=None, t_s=None, segments=None, meta=None,
                   name="dataframe", cls: Callable[..., T]) -> T:
    """from_arrays on a DataFrame's columns. columns: {spec name: the frame's column} for the ones
    named otherwise (ax ay az gx gy gz, t_s, temp_c, segment); a t_s column is used unless rate_hz
    or t_s is given; with segments= (the table) the segment column gives each row's. pandas is needed only to hand the
    frame in (simucal[pandas])."""
    cols = {k: k for k in KEYS if k in df.columns} | dict(columns or {})
    missing = [v for v in cols.values() if v not in df.columns]
    if missing:
        raise MeasurementSetError(name, None, f"no column {missing[0]!r} (columns: {list(df.columns)}): fix columns=")

    if "segment" in cols and segments is None:
        raise MeasurementSetError(name, None,
                                  f"the column {cols['segment']!r} gives each row a segment, but no segments= "
                                              "table says what the segments are: give segments= (segments.csv's rows: "
                                              "segment, kind, the table's angles) for a turntable test, or leave the "
                                              "column out for a stream")
    if not any(k in cols for k in SAMPLE_COLS):
        raise MeasurementSetError(name, None,
                                  f"no accelerometer or gyro columns among {list(df.columns)}: name them ax ay "
                                              "az gx gy gz, or map them with columns={'ax': 'acc_x', ...}")

    def numbers(key):
        """The column of spec name key as float64, refused at its first cell that is not a number."""
        try:
            return df[cols[key]].to_numpy(float)
        except (TypeError, ValueError):
            for row, cell in enumerate(df[cols[key]]):
                try:
                    float(cell)
                except (TypeError, ValueError):
                    raise MeasurementSetError(name, None, f"column {cols[key]!r}, row {row}: {cell!r} is not a "
                                                          "number") from None
            raise

    def get(keys):
        present = [k for k in keys if k in cols]
        if present and len(present) != len(keys):
            raise MeasurementSetError(name, None, f"columns {keys} must all be present or all absent (map them with "
                                                  "columns={'ax': ..., ...})")
        return np.column_stack([numbers(k) for k in keys]) if present else None
    if rate_hz is None and t_s is None and "t_s" in cols:
        t_s = numbers("t_s")
    return from_arrays(get(SAMPLE_COLS[:3]), get(SAMPLE_COLS[3:]), acc_unit=acc_unit, gyro_unit=gyro_unit,
                       rate_hz=rate_hz, t_s=t_s, temp_c=numbers("temp_c") if "temp_c" in cols else None,
                       segment=numbers("segment") if segments is not None and "segment" in cols else None,
                       segments=segments, meta=meta, name=name, cls=cls)
