"""A measurement set's columns and the rules its samples follow (spec: docs/spec/measurement-set.md), whoever made
them: the reader of samples.csv or samples.parquet, the columnar reader and the constructors from arrays."""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from simucal.io.text_files import MeasurementSetError

FORMAT = "simucal.measurements/1"
SAMPLE_COLS = ("ax", "ay", "az", "gx", "gy", "gz")
SENSOR_COLS = {"acc": SAMPLE_COLS[:3], "gyro": SAMPLE_COLS[3:]}
SEGMENT_COLS = ("segment", "kind", "outer_deg", "middle_deg", "inner_deg", "outer_rate_dps")
PLAUSIBLE = 1e12  # no output, time or temperature of a real unit is this large (counts and pulse/s included)


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


def check_samples(out, path, segments, plausible=False):
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
