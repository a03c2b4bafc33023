"""Raw-output checks every method makes before fitting: clipped (saturated) rows and
stuck channels. A clipped sample would pull a mean toward the rail; a stuck column is
no sensor at all."""
from __future__ import annotations

from typing import Any

import numpy as np

from simucal.errors import CalibrationError

TRIADS = (("acc", ("ax", "ay", "az")), ("gyro", ("gx", "gy", "gz")))


def saturated_rows(ms, sensor, min_run=3):
    """Rows of one sensor's raw outputs that are clipped: at or beyond meta.json's full_scale,
    or equal to a column's extreme in a run of min_run or more (a clipped sensor repeats its
    rail; two equal extremes of quantised noise are common, three are not). Raw counts without
    full_scale: any such run (their rails are the data's own). Otherwise a repeated extreme
    counts only where it piles up (repeat_is_clipping): an amplifier or a range setting can clip
    below the rails meta.json gives, and a unit in g or deg/s states none. Found once per set and
    sensor (a method's checks ask three times); the mask is read-only."""
    cols = ("ax", "ay", "az") if sensor == "acc" else ("gx", "gy", "gz")
    bad, report = ms._once(("saturated", sensor, min_run), cols, lambda: _saturated_rows(ms, sensor, min_run))
    return bad, [dict(r) for r in report]


def _saturated_rows(ms, sensor, min_run):
    raw = ms.raw(sensor)
    full_scale = ms.meta.get("full_scale", {}).get(sensor)
    any_repeat = full_scale is None and ms.meta.get(f"{sensor}_unit") == "counts"
    bad = np.zeros(len(raw), bool)
    report = []
    held = _extreme_rows(ms, sensor) or [(min_run, min_run)] * 3
    for j, extremes in enumerate(column_extremes(ms, sensor)):
        col = raw[:, j]
        hit = np.zeros(len(col), bool)
        if full_scale is not None:
            hit |= (col <= full_scale[0]) | (col >= full_scale[1])
            outside = np.mean((col < full_scale[0]) | (col > full_scale[1]))
            if outside > 0.05:  # a clipped sensor stops at its rails; it cannot read past them
                raise CalibrationError(
                    f"{ms.path / 'meta.json'}: {100 * outside:.0f} % of the {sensor} {'xyz'[j]} samples lie outside "
                    f"full_scale {list(full_scale)}, which no sensor can read: full_scale does not match these data "
                    f"(signed against unsigned counts, or another {sensor}_unit?); correct it or leave it out")
        for ext, n in zip(extremes, held[j]):
            if n < min_run:
                continue  # fewer rows at it than a run of min_run holds
            runs = _runs(col == ext, min_run)
            if runs and (any_repeat or repeat_is_clipping(col, ext, runs)):
                for a, b in runs:
                    hit[a:b] = True
        if hit.any():
            report.append({"axis": "xyz"[j], "count": int(hit.sum()), "first_row": int(np.argmax(hit))})
        bad |= hit
    return bad, report


def column_extremes(ms, sensor) -> list[tuple]:
    """(min, max) of each column of one sensor's raw outputs, found once per set and sensor (the
    clipping and stuck checks both ask): a column at a time, as reducing the (n, 3) block along its
    rows costs 65 ms at 1.6 million rows against 3.5 ms a column."""
    cols = ("ax", "ay", "az") if sensor == "acc" else ("gx", "gy", "gz")
    raw = ms.raw(sensor)
    return ms._once(("extremes", sensor), cols, lambda: [(raw[:, j].min(), raw[:, j].max()) for j in range(3)],
                    meta=False)


def known_extremes(ms, extremes: dict) -> None:
    """column_extremes' answer where the reader found it ({column: (least, greatest, rows at the least,
    rows at the greatest)}: csv_columns keeps them as it parses), so that no pass over the columns
    repeats it, and the rows at each (_saturated_rows scans for a run only where there can be one)."""
    for sensor, cols in TRIADS:
        if all(c in extremes and c in ms.samples for c in cols):
            ms._once(("extremes", sensor), cols, lambda cols=cols: [extremes[c][:2] for c in cols], meta=False)
            ms._once(("extreme_rows", sensor), cols, lambda cols=cols: [extremes[c][2:] for c in cols], meta=False)


def _extreme_rows(ms, sensor):
    """Per column, the rows at its (least, greatest) where the reader counted them (known_extremes), else None."""
    return ms._once(("extreme_rows", sensor), dict(TRIADS)[sensor], lambda: None, meta=False)


def _runs(mask, min_run):
    """[(start, stop)] of the runs of True at least min_run long (found among the True rows only:
    an extreme value is rare)."""
    idx = np.flatnonzero(mask)
    if len(idx) < min_run:
        return []
    gaps = np.flatnonzero(np.diff(idx) != 1)
    starts, stops = np.r_[idx[0], idx[gaps + 1]], np.r_[idx[gaps] + 1, idx[-1] + 1]
    return [(int(a), int(b)) for a, b in zip(starts, stops) if b - a >= min_run]


def repeat_is_clipping(col, ext, runs) -> bool:
    """A signal clipped at ext reaches it in several separate runs (several moves or poses hit
    the rail) and piles up there: more rows at ext than at the next value inward. Noise at rest
    thins out toward its extreme instead."""
    inner = col[col < ext] if ext == col.max() else col[col > ext]
    if len(runs) < 2 or not len(inner):
        return False
    nxt = inner.max() if ext == col.max() else inner.min()
    return int(np.sum(col == ext)) > int(np.sum(col == nxt))


def stuck_channels(ms: Any) -> None:  # a simucal.io.MeasurementSet: that package imports this module
    """Refuse a column that holds one value in every row (no sensor reads that, even at rest),
    or over part of the recording (_frozen), a sensor at a time (on one thread: on two, the 400 Hz
    set's took 0.1 s more CPU for no less wall)."""
    fs = ms.meta.get("full_scale", {})
    for c in ("ax", "ay", "az", "gx", "gy", "gz"):
        v = ms.samples.get(c)
        if v is not None and len(v) > 1 and _one_value(ms, c):
            rail = fs.get("acc" if c[0] == "a" else "gyro")
            at_rail = (rail is not None and v[0] in rail) or v[0] in (0.0, 65535.0, 32767.0, -32768.0)
            raise CalibrationError(f"{ms.path / 'samples.csv'}: column {c} holds {v[0]:g} in every row: a stuck "
                                   + ("(at the rail) " if at_rail else "") + "or unconnected channel; check the "
                                   "wiring or the column mapping")
    for sensor, cols in TRIADS:
        if not all(c in ms.samples for c in cols):
            continue
        X, groups, frozen = _frozen(ms, sensor, cols)  # a clipping refusal (full_scale) raised here
        for seg, rows, j in frozen:
            if ms.segments is not None and sum(f[2] == j for f in frozen) > len(groups) / 2:
                continue  # frozen nearly everywhere: a quiet channel, quantised coarser than its noise
            where = f"segment {seg}" if seg is not None else f"{len(rows)} rows from line {int(rows[0]) + 2}"
            raise CalibrationError(f"{ms.path / 'samples.csv'}: column {cols[j]} holds {X[rows, j][0]:g} in every row "
                                   f"of {where} while {' and '.join(c for k, c in enumerate(cols) if k != j)} vary: "
                                   "a channel stuck for that part (a dropout or a frozen value); "
                                   "cut or repair those rows")


def _one_value(ms, c) -> bool:
    """Whether column c holds one value in every row: its least and its greatest are equal (the
    samples are finite), from the extremes the clipping check uses too."""
    sensor, triad = ("acc", ("ax", "ay", "az")) if c[0] == "a" else ("gyro", ("gx", "gy", "gz"))
    if not all(t in ms.samples for t in triad):
        v = ms.samples[c]
        return bool(np.all(v == v[0]))
    lo, hi = column_extremes(ms, sensor)[triad.index(c)]
    return bool(lo == hi)


def _frozen(ms, sensor, cols, min_rows=20):
    """(raw outputs, groups, [(segment, rows, column)]) where one column of the triad is frozen over
    part of the recording while the others move: in a turntable set over a whole segment (refused
    where the same column is not frozen in most other segments, so it is no quiet, coarsely
    quantised channel); in a stream over a quarter of the rows or more."""
    X = ms.raw(sensor)
    groups = ([(s.segment, ms.rows(s.segment)) for s in ms.segments] if ms.segments is not None
              else [(None, _longest_run(X, j, max(min_rows, len(X) // 4))) for j in range(3)])
    clipped = saturated_rows(ms, sensor)[0]  # frozen at a rail is clipping, left out where it is met
    long = [(seg, rows) for seg, rows in groups if len(rows) >= min_rows]
    return X, groups, [(seg, rows, j) for (seg, rows), span in zip(long, _spans(X, [rows for _, rows in long]))
                       for j in range(3) if span[j] == 0 and np.delete(span, j).min() > 0 and not clipped[rows].all()]


def _spans(X, groups) -> np.ndarray:
    """Each group's (non-empty row indices) peak-to-peak of every column, (len(groups), 3): one
    reduceat over the rows in group order, not a reduction per group; over X itself (no copy)
    where every group is a run of rows, as a set recorded segment by segment has them."""
    if not groups:
        return np.zeros((0, X.shape[1]))
    if all(g[-1] - g[0] + 1 == len(g) for g in groups):
        lo, hi = min(g[0] for g in groups), max(g[-1] for g in groups) + 1
        bounds = np.array(sorted({b for g in groups for b in (g[0], g[-1] + 1) if b < hi}))  # disjoint runs: each
        pieces = np.searchsorted(bounds, [g[0] for g in groups])                     # starts a piece of its own
        return (np.maximum.reduceat(X[lo:hi], bounds - lo, axis=0)
                - np.minimum.reduceat(X[lo:hi], bounds - lo, axis=0))[pieces]
    starts = np.cumsum([0] + [len(g) for g in groups[:-1]])
    Xg = X[np.concatenate(groups)]
    return np.maximum.reduceat(Xg, starts, axis=0) - np.minimum.reduceat(Xg, starts, axis=0)


def _longest_run(X, j, min_len) -> np.ndarray:
    """The rows (indices) of the longest run over which column j holds one value, if min_len or
    longer; else none."""
    change = np.r_[True, X[1:, j] != X[:-1, j], True]
    starts = np.nonzero(change)[0]
    lengths = np.diff(starts)
    k = int(np.argmax(lengths))
    return np.arange(starts[k], starts[k] + lengths[k]) if lengths[k] >= min_len else np.zeros(0, int)
