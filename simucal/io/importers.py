"""`simucal import`: other tools' recordings to measurement sets.

Formats:
- imu_tk: two text files (acc, gyro), each line `t x y z`, raw counts.
- imucal-ferraris: imucal's session CSV (n_samples, gyr_*, acc_*; m/s^2 and
  deg/s) at a given sample rate; its section list is not needed (the poses
  are found by static detection).
- csv: any CSV with a column map, units, nominal scales and sample rate.
Every error names the original file and line.
"""
from __future__ import annotations

import csv
import io as _io
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from simucal import io
from simucal.errors import SimucalError
from simucal.io import units
from simucal.io.meta import Meta
from simucal.io.text_files import ends_with_a_line_end


class ImportError_(SimucalError):
    pass


def _text(path, lines=True) -> str:
    """A source file's text; binary files and other encodings refused, naming the line, and (lines: a
    recording of lines) one whose last line has no line end: it may have been cut mid-number."""
    try:
        text = io.read_text(Path(path))
        if lines:
            ends_with_a_line_end(Path(path), text[-64:].encode(), text.count("\n") + 1)
        return text
    except io.MeasurementSetError as e:
        raise ImportError_(str(e)) from None


def _read_numeric(path, ncols=None, skip_header=False):
    path = Path(path)
    rows = []
    with _io.StringIO(_text(path)) as fh:
        for line_no, line in enumerate(fh, start=1):
            if skip_header and line_no == 1:
                continue
            parts = line.replace(",", " ").split()
            if not parts:
                continue
            try:
                vals = [float(p) for p in parts]
            except ValueError:
                raise ImportError_(f"{path}, line {line_no}: not numbers: {line.strip()[:60]!r}") from None
            if ncols is not None and len(vals) != ncols:
                raise ImportError_(f"{path}, line {line_no}: {len(vals)} values, expected {ncols}")
            if not all(math.isfinite(v) for v in vals):
                raise ImportError_(f"{path}, line {line_no}: NaN or infinite value")
            rows.append(vals)
    if not rows:
        raise ImportError_(f"{path}: no data")
    return np.array(rows)


def import_meta(acc_unit, gyro_unit, latitude_deg, extra, has_gyro=True) -> Meta:
    """meta.json of an imported set: its units, extra (the importer's keys) and the latitude where it has gyros."""
    meta: Meta = {"acc_unit": acc_unit, "gyro_unit": gyro_unit, **extra}
    if latitude_deg is None and has_gyro:
        raise ImportError_("give --latitude-deg: the spec needs the latitude when gyro data are present "
                           "(where the Earth rate is below the gyro noise any nearby value will do)")
    if latitude_deg is not None:
        meta["latitude_deg"] = latitude_deg
    return meta


def import_imu_tk(acc_path: str | os.PathLike[str], gyro_path: str | os.PathLike[str], out: str | os.PathLike[str],
                  acc_counts_per_g: float, gyro_counts_per_dps: float, latitude_deg: float | None,
                  gravity_mps2: float | None = None) -> Meta:
    a = _read_numeric(acc_path, 4)
    g = _read_numeric(gyro_path, 4)
    if len(a) != len(g) or np.any(np.abs(a[:, 0] - g[:, 0]) > 1e-9):
        raise ImportError_(f"{gyro_path}: its time column differs from {acc_path}'s (imu_tk files pair row for row)")
    bad = np.nonzero(np.diff(a[:, 0]) <= 0)[0]
    if bad.size:
        raise ImportError_(f"{acc_path}, line {bad[0] + 2}: time does not increase")
    extra: dict[str, Any] = {"acc_counts_per_g": [acc_counts_per_g] * 3,
                             "gyro_counts_per_dps": [gyro_counts_per_dps] * 3,
             "description": f"imported from imu_tk files {Path(acc_path).name}, {Path(gyro_path).name}"}
    if gravity_mps2:
        extra["gravity_mps2"] = gravity_mps2
    meta = import_meta("counts", "counts", latitude_deg, extra)
    samples = {"t_s": a[:, 0], "ax": a[:, 1], "ay": a[:, 2], "az": a[:, 3], "gx": g[:, 1], "gy": g[:, 2], "gz": g[:, 3]}
    io.write_set(out, meta, samples)
    return meta


def parse_columns(text: str) -> dict[str, str]:
    """--columns 'SPEC=SOURCE,...' -> {spec column: source column}, refusing anything malformed."""
    allowed = ("t_s", "segment", "temp_c", "ax", "ay", "az", "gx", "gy", "gz")
    out: dict[str, str] = {}
    for item in text.split(","):
        spec, eq, src = (x.strip() for x in item.partition("="))
        if not eq or not spec or not src:
            raise ImportError_(f"--columns item {item!r}: write SPEC=SOURCE (t_s=NAME, ax=NAME, ...), comma-separated")
        if spec not in allowed:
            raise ImportError_(f"--columns: {spec!r} is not a spec column; use {', '.join(allowed)}")
        if spec in out:
            raise ImportError_(f"--columns: {spec} is mapped twice")
        if src in out.values():
            raise ImportError_(f"--columns: source column {src!r} is mapped to both "
                               f"{[k for k, v in out.items() if v == src][0]} and {spec}: "
                               "each axis needs its own column")
        out[spec] = src
    for group in (("ax", "ay", "az"), ("gx", "gy", "gz")):
        got = [c for c in group if c in out]
        if got and len(got) < 3:
            raise ImportError_(f"--columns maps {got} but not {[c for c in group if c not in out]}: a triad needs all "
                               "three axes")
    if not any(c in out for c in ("ax", "gx")):
        raise ImportError_("--columns maps no sensor: give ax, ay, az and/or gx, gy, gz")
    return out


def _table_rows(path):
    """(header, [(line number, {column: cell})]) of a CSV, or of whitespace-separated text whose header
    line starts with '#' (as many loggers write: `# t ax ay az gx gy gz`); later '#' lines and blank
    lines of such text are comments. A short row's missing cells are None."""
    text = _text(path)
    lines = text.splitlines()
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None or not lines[first].lstrip().startswith("#") or "," in lines[first]:
        reader = csv.DictReader(_io.StringIO(text, newline=""))
        return reader.fieldnames or [], ((n, row) for n, row in enumerate(reader, start=2))
    header = lines[first].lstrip()[1:].split()
    rows = ((i + 1, dict(zip(header, ln.split() + [None] * (len(header) - len(ln.split())))))
            for i, ln in enumerate(lines) if i > first and ln.strip() and not ln.lstrip().startswith("#"))
    return header, rows


def _read_columns(path, columns: dict, strings=()) -> dict:
    """{key: array} of a CSV's named columns ({key: source column}); `strings` are keys kept as text.
    Every error names the file, the line and the column."""
    path = Path(path)
    header, rows = _table_rows(path)
    missing = [src for src in columns.values() if src not in header]
    if missing:
        raise ImportError_(f"{path}, line 1: no columns {missing}; the header has {header}")
    dup = sorted({c for c in header if header.count(c) > 1} & set(columns.values()))
    if dup:
        raise ImportError_(f"{path}, line 1: column {dup[0]} appears more than once; which one is the data?")
    data: dict[str, list[float | str]] = {k: [] for k in columns}
    for line_no, row in rows:
        for k, src in columns.items():
            if row[src] is None:
                raise ImportError_(f"{path}, line {line_no}: the row ends before column {src}")
            if k in strings:
                data[k].append(row[src])
                continue
            try:
                v = float(row[src])
            except ValueError:
                raise ImportError_(f"{path}, line {line_no}: column {src}: {row[src]!r} is not a number") from None
            if not math.isfinite(v):
                raise ImportError_(f"{path}, line {line_no}: column {src} is not finite")
            data[k].append(v)
    if not data or not next(iter(data.values())):
        raise ImportError_(f"{path}: no data rows")
    return {k: np.array(v) for k, v in data.items()}


def import_csv(path, out, columns: dict[str, str], acc_unit, gyro_unit, rate_hz=None, latitude_deg=None,
               scales=None) -> Meta:
    """columns: {spec column: source column name}, e.g. {"ax": "acc_x", ...};
    without a t_s column, time is row / rate_hz."""
    path = Path(path)
    named = units.temperature_unit_in_name(columns.get("temp_c", ""))
    if named:
        raise ImportError_(f"{path}: column {columns['temp_c']} is named as {named}, but temp_c is degC: convert it "
                           "first (" + ("C = K - 273.15" if named == "kelvin" else "C = (F - 32) / 1.8") + ")")
    samples = _read_columns(path, columns)
    n = len(next(iter(samples.values())))
    if "t_s" not in samples:
        if not rate_hz:
            raise ImportError_(f"{path}: no time column mapped; give --rate-hz")
        samples["t_s"] = np.arange(n) / rate_hz
    has_gyro = "gx" in columns
    meta = import_meta(acc_unit or "g", gyro_unit or "deg/h", latitude_deg,  # the spec names both units; one is unused
                 dict(scales or {}, description=f"imported from {path.name}"), has_gyro)
    units.check_meta(meta, path, lambda p, line, rule: ImportError_(f"{p}: {rule}"))
    io.write_set(out, meta, samples)
    return meta


FERRARIS_COLUMNS = {"ax": "acc_x", "ay": "acc_y", "az": "acc_z", "gx": "gyr_x", "gy": "gyr_y", "gz": "gyr_z"}


def import_ferraris(path: str | os.PathLike[str], out: str | os.PathLike[str], rate_hz: float,
                    latitude_deg: float | None) -> Meta:
    return import_csv(path, out, FERRARIS_COLUMNS, "m/s^2", "deg/s", rate_hz, latitude_deg, {"gravity_mps2": 9.81})


# Ferraris poses as the middle/inner angles that put f^k along the labelled axis:
# f^k = [-cos(a) sin(b), sin(a), cos(a) cos(b)] (spec: C_k^n = Rz Rx Ry).
FERRARIS_POSES = {"x_p": (0.0, -90.0), "x_a": (0.0, 90.0), "y_p": (90.0, 0.0), "y_a": (-90.0, 0.0),
                  "z_p": (0.0, 0.0), "z_a": (0.0, 180.0)}
FERRARIS_TURNS = {"x_rot": "x_p", "y_rot": "y_p", "z_rot": "z_p"}


def _ferraris_set(out, sections, data, t, units_meta, latitude_deg, turn_deg, source) -> Meta:
    """sections: [(label, row indices)] in recording order. Static poses become static
    segments at their nominal orientation; each 360 deg turn a rate segment about the
    vertical (the pose's axis) at the protocol's mean rate turn_deg / duration."""
    if abs(turn_deg) < 1.0:
        raise ImportError_(f"--turn-deg {turn_deg:g}: the Ferraris turns need their angle (imucal's protocol turns "
                           "-360 deg); a turn of 0 deg carries no rate to calibrate the gyros with")
    segs, keep_rows, seg_col = [], [], []
    for sid, (label, rows) in enumerate(sections, start=1):
        if label in FERRARIS_POSES:
            a, b = FERRARIS_POSES[label]
            segs.append(io.Segment(sid, "static", None, a, b, 0.0))
        elif label in FERRARIS_TURNS:
            a, b = FERRARIS_POSES[FERRARIS_TURNS[label]]
            duration = float(t[rows[-1]] - t[rows[0]] + np.median(np.diff(t)))
            segs.append(io.Segment(sid, "rate", None, a, b, turn_deg / duration))
        else:
            raise ImportError_(f"{source}: unknown section label {label!r}; Ferraris labels are "
                               f"{sorted(FERRARIS_POSES) + sorted(FERRARIS_TURNS)}")
        keep_rows.append(rows)
        seg_col.append(np.full(len(rows), sid))
    rows = np.concatenate(keep_rows)
    samples = {"segment": np.concatenate(seg_col), "t_s": t[rows], **{k: v[rows] for k, v in data.items()}}
    meta = import_meta(units_meta["acc_unit"], units_meta["gyro_unit"], latitude_deg,
                 {k: v for k, v in units_meta.items() if k not in ("acc_unit", "gyro_unit")})
    meta["description"] = (f"imported from {source}: Ferraris protocol; static poses at their nominal orientation, "
                           f"each turn a rate segment at the protocol's {turn_deg:+.0f} deg over its duration")
    io.write_set(out, meta, samples, segs)
    return meta


def _read_sections(path, n_rows) -> dict:
    """imucal's section list {label: {start, end}} (0-based rows, end exclusive), checked against the
    recording's rows."""
    import json
    text = _text(path, lines=False)
    try:
        sections = json.loads(text)
    except json.JSONDecodeError as e:
        raise ImportError_(f"{path}, line {e.lineno}: not valid JSON: {e.msg}") from None
    except (ValueError, RecursionError) as e:  # a number of 5000 digits; arrays thousands of levels deep
        raise ImportError_(f"{path}: not a section list ({type(e).__name__}: nested too deep or a number too "
                           "long to read)") from None
    if not isinstance(sections, dict) or not sections:
        raise ImportError_(f"{path}: must map each section label to {{\"start\": row, \"end\": row}}")
    for label, s in sections.items():
        ends: list[Any] = [s.get(k) if isinstance(s, dict) else None for k in ("start", "end")]  # checked next
        if not all(isinstance(x, int) and not isinstance(x, bool) for x in ends):
            raise ImportError_(f"{path}: section {label!r} needs whole-number \"start\" and \"end\" rows, got {s!r}")
        if not 0 <= ends[0] < ends[1] <= n_rows:
            raise ImportError_(f"{path}: section {label!r} spans rows {ends[0]}..{ends[1]}, outside the recording's "
                               f"{n_rows} rows (0-based, end exclusive): is it the section list of this session?")
    return sections


def import_ferraris_sections(csv_path: str | os.PathLike[str], json_path: str | os.PathLike[str],
                             out: str | os.PathLike[str], rate_hz: float,
                             latitude_deg: float | None, turn_deg: float = -360.0) -> Meta:
    """imucal's session CSV with its section list (0-based rows, end exclusive)."""
    data = _read_columns(csv_path, FERRARIS_COLUMNS)
    n = len(data["ax"])
    sections = _read_sections(json_path, n)
    t = np.arange(n) / rate_hz
    order = sorted(sections.items(), key=lambda kv: kv[1]["start"])
    for (la, a), (lb, b) in zip(order[:-1], order[1:]):
        if b["start"] < a["end"]:
            raise ImportError_(f"{json_path}: sections {la!r} (rows {a['start']}..{a['end']}) and {lb!r} (rows "
                               f"{b['start']}..{b['end']}) overlap: a row belongs to one pose or turn; fix the rows")
    secs = [(label, np.arange(s["start"], s["end"])) for label, s in order]
    return _ferraris_set(out, secs, data, t, {"acc_unit": "m/s^2", "gyro_unit": "deg/s", "gravity_mps2": 9.81},
                         latitude_deg, turn_deg, Path(csv_path).name)


def import_imucal_annotated(csv_path: str | os.PathLike[str], out: str | os.PathLike[str], rate_hz: float,
                            acc_counts_per_g: float, gyro_counts_per_dps: float,
                            latitude_deg: float | None, turn_deg: float = -360.0) -> Meta:
    """imucal's annotated session: sections already cut, sorted by label; `samples`
    gives the recording order."""
    path = Path(csv_path)
    cols = _read_columns(path, {"part": "part", "samples": "samples", **FERRARIS_COLUMNS}, strings=("part",))
    order = np.argsort(cols["samples"], kind="stable")
    labels = cols["part"][order]
    t = cols["samples"][order] / rate_hz
    data = {k: cols[k][order] for k in FERRARIS_COLUMNS}
    change = np.r_[0, np.nonzero(labels[1:] != labels[:-1])[0] + 1, len(labels)]
    secs = [(labels[a], np.arange(a, b)) for a, b in zip(change[:-1], change[1:])]
    units_meta = {"acc_unit": "counts", "gyro_unit": "counts", "acc_counts_per_g": [acc_counts_per_g] * 3,
                  "gyro_counts_per_dps": [gyro_counts_per_dps] * 3}
    return _ferraris_set(out, secs, data, t, units_meta, latitude_deg, turn_deg, path.name)
