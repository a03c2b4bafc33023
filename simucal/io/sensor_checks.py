"""Raw-output checks every method makes before fitting: clipped (saturated) rows and
stuck channels. A clipped sample would pull a mean toward the rail; a stuck column is
no sensor at all."""
from __future__ import annotations

import numpy as np

from simucal.errors import CalibrationError


def saturated_rows(raw, full_scale=None, min_run=3):
    """Rows at or beyond full scale; without it, rows equal to a column's extreme
    in a run of min_run or more (a clipped sensor repeats its rail; two equal
    extremes of quantised noise are common, three are not)."""
    bad = np.zeros(len(raw), bool)
    report = []
    for j in range(raw.shape[1]):
        col = raw[:, j]
        if full_scale is not None:
            hit = (col <= full_scale[0]) | (col >= full_scale[1])
        else:
            hit = np.zeros(len(col), bool)
            for ext in (col.min(), col.max()):
                eq = (col == ext).astype(int)
                edges = np.diff(np.r_[0, eq, 0])
                for a, b in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]):
                    if b - a >= min_run:
                        hit[a:b] = True
        if hit.any():
            report.append({"axis": "xyz"[j], "count": int(hit.sum()), "first_row": int(np.argmax(hit))})
        bad |= hit
    return bad, report



def stuck_channels(ms):
    """Refuse a column that holds one value in every row: no sensor reads that, even at rest."""
    fs = ms.meta.get("full_scale", {})
    for c in ("ax", "ay", "az", "gx", "gy", "gz"):
        v = ms.samples.get(c)
        if v is not None and len(v) > 1 and np.all(v == v[0]):
            rail = fs.get("acc" if c[0] == "a" else "gyro")
            at_rail = (rail is not None and v[0] in rail) or v[0] in (0.0, 65535.0, 32767.0, -32768.0)
            raise CalibrationError(f"{ms.path / 'samples.csv'}: column {c} holds {v[0]:g} in every row: a stuck "
                                   + ("(at the rail) " if at_rail else "") + "or unconnected channel; check the "
                                   "wiring or the column mapping")
