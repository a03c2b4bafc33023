"""`simucal validate`'s checks on a turntable test (or a field set: its static segments): |f| = 1 g at
every static segment, the gravity directions against the commanded table vertical, |w| against the
rate runs' input norm (dong2018 eq. 9) and the Earth rate at rest (the shared pieces:
fit/validation.py; the registry of kinds of data: methods.py)."""
from __future__ import annotations

import numpy as np

from simucal.fit.rotations import wahba
from simucal.fit.validation import FLOOR, CheckRecord, far_off, norm_block, rms, segment_means, with_calibration
from simucal.io import units
from simucal.turntable.observations import outer_angle_rad, table_accuracy_rad
from simucal.turntable.plan_design import directions_k


def table_checks(ms, f_before, f_after, w_before, w_after, cal) -> dict[str, list[CheckRecord]]:
    """{sensor: [check]} of a calibration cal on the set ms: each sensor's outputs (g, deg/h) at its nominal
    scale factors (before) and calibrated (after; None: no such sensor)."""
    segs = ms.segments
    seg_rows = {s.segment: ms.rows(s.segment) for s in segs}
    lat = np.radians(ms.meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(ms.meta)
    out: dict[str, list[CheckRecord]] = {}
    static = [s for s in segs if s.kind == "static" and seg_rows[s.segment].size]
    if f_after is not None and static:
        groups = [seg_rows[s.segment] for s in static]
        sd = units.stated_noise(ms.meta, "acc")
        (mb, _), (ma, fl) = segment_means(f_before, groups, sd), segment_means(f_after, groups, sd)
        labels = [f"segment {s.segment}" for s in static]
        whole, with_cal = with_calibration(fl, cal, "acc", ma, groups, ms)
        checks = [norm_block("g", np.linalg.norm(mb, axis=1) - 1, np.linalg.norm(ma, axis=1) - 1, whole,
                             "|f| - 1 g at each static segment" + FLOOR[with_cal], labels)]
        angled = [i for i, s in enumerate(static) if s.middle_deg is not None and s.inner_deg is not None]
        if len(angled) >= 3:
            # the navigation vertical (z up) in the table frame k: gravity's reaction
            up_k = directions_k([(s.outer_deg or 0.0, s.middle_deg, s.inner_deg) for s in (static[i] for i in angled)])
            errs = []
            for m in (mb[angled], ma[angled]):
                d = m / np.linalg.norm(m, axis=1, keepdims=True)
                R = wahba(up_k, d, np.ones(len(d)))
                errs.append(np.linalg.norm(d - up_k @ R.T, axis=1))
            # the table's angle errors move the direction too: two angles, each of its stated std, and the outer
            # axis's tilt about two horizontal axes (a constant tilt seen at several outer angles: no one rotation)
            stated = [k for k in ("table_accuracy_arcsec", "table_tilt_arcsec") if ms.meta.get(k) is not None]
            table_sd = np.hypot(table_accuracy_rad(ms) or 0.0,
                                ms.meta.get("table_tilt_arcsec", 0.0) * units.ARCSEC_RAD) * np.sqrt(2)
            floor = np.hypot(fl[angled], table_sd)
            checks.append({"what": "gravity direction against the commanded table vertical, after the best "
                                   "rotation between unit and table" + (
                                       f" (floor: the noise and meta.json's {' and '.join(stated)})" if stated else
                                       " (floor: the noise alone; the table's angle errors add to it: state them "
                                       "as meta.json's table_accuracy_arcsec and table_tilt_arcsec)"),
                           "unit": "rad", "n": len(angled), "before_rms": rms(errs[0]), "after_rms": rms(errs[1]),
                           "floor_rms": rms(floor) if np.all(np.isfinite(floor)) else None,
                           "far_off": far_off(errs[1], floor, [labels[i] for i in angled]),
                           "far_off_hint": "check their commanded angles in segments.csv",
                           "limited_by_table": not stated})
        out["acc"] = checks
    if w_after is not None:
        sd = units.stated_noise(ms.meta, "gyro")
        checks = []
        rate = [s for s in segs if s.kind == "rate" and seg_rows[s.segment].size]
        for kind, chosen, truth in (("rate", rate,
                                     [abs(s.outer_rate_dps * units.DPH_PER_DPS + w_e * np.sin(lat)) for s in rate]),
                                    ("static", static, [w_e] * len(static))):
            if not chosen:
                continue
            groups = [seg_rows[s.segment] for s in chosen]
            angles = [outer_angle_rad(ms, seg_rows[s.segment], s) for s in chosen]
            (mb, _), (ma, fl) = segment_means(w_before, groups, sd, angles), segment_means(w_after, groups, sd, angles)
            f_means = None if f_after is None else np.array([f_after[g].mean(0) for g in groups])
            whole, with_cal = with_calibration(fl, cal, "gyro", ma, groups, ms, f_means)
            what = ("|w| - |w_T + w_e sin L| at each rate run" if kind == "rate" else
                    "|w| - w_e (the Earth rate) at each static segment")
            checks.append(norm_block("deg/h", np.linalg.norm(mb, axis=1) - truth, np.linalg.norm(ma, axis=1) - truth,
                                     whole, what + FLOOR[with_cal], [f"segment {s.segment}" for s in chosen]))
        out["gyro"] = checks
    return out


