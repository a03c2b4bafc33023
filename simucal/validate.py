"""`simucal validate`: a calibration judged on an independent set, before and after.

The promise of the loop is that the user watches the error fall; on the fit's own rows
it always does. Here a calibration is applied (fit/apply.py) to a set it was not made
from, and the error against what physics says the unit felt is compared with the same
error at the nominal scale factors only (the raw outputs divided by meta.json's scales,
no bias, no misalignment), and with the noise floor of that error:

- every static segment or pose: |f| = 1 g (dong2018 eq. 2, the norm observation) and,
  for gyros, |w| = the Earth rate;
- turntable rate runs: |w| = |w_T + w_e sin L| (eq. 9's input norm);
- a turntable set with commanded angles: the calibrated gravity directions against the
  commanded table vertical, after the one rotation between unit and table that fits best
  (Wahba): the direction error (rad). It carries the table's own angle errors;
- a stream: each move's gravity direction after the move predicted by the integrated gyro
  against the one the calibrated accelerometers measure (Tedaldi's cost; handheld/moves.py),
  as an angle in deg. At nominal the gyro's bias is taken from the initial rest, as any user
  would; both use the calibrated accelerometers' directions, so the check is the gyro's alone.

The floor of each norm error is its whole uncertainty: the noise (a segment's or pose's scatter
over its rows, std of the mean, or the stated noise of one row) and the calibration's own: its
parameters' covariance (a thermal calibration's coefficients', at each segment's temperature)
propagated to the calibrated norm, d|u|/dp = (u/|u|)' (dh/du)^-1 dh/dp, added in quadrature
(`calibration_sd`; a file without a covariance adds nothing, and the check says so). For moves,
the same residual at the rests' noise is not known a priori, so moves have no floor. A calibration
whose error is above the nominal one's is said to be worse, loudly; rows outside a calibration's
temperature range are named (apply's warning).
"""
from __future__ import annotations

import numpy as np

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit.apply import apply
from simucal.fit.rotations import wahba
from simucal.io import calibration, units
from simucal.report.console import validation_next
from simucal.turntable.observations import mean_and_sigma, outer_angle_rad, table_accuracy_rad
from simucal.turntable.plan_design import directions_k

WORSE = 1.05  # after/before above this: the calibration makes the unit worse on these data
AT_FLOOR = 2.0  # after below this many floors: the noise, nothing left to gain
FAR_OFF = 10.0  # a row this many floors (and medians) off is named


def _rms(x):
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x ** 2))) if x.size else None


def _segment_means(data, groups, stated, angles=None):
    """Mean of each group of rows (n, 3) and the std of each mean (n,) along the norm, the rms over
    the axes of observations.mean_and_sigma's: a rate run's (angles: each row's outer angle) as the
    calibration takes it, the constant of its outer angle's harmonics and their residuals' scatter
    (first differences would count the turning Earth rate as noise: at 20 Hz 3x it, a floor 3-5x too
    high), a static group's from first differences (blind to a slow drift); the stated noise of one
    row where a group has fewer than three."""
    out = [mean_and_sigma(data[rows], stated, varying=True, angle_rad=None if angles is None else a)
           for rows, a in zip(groups, angles or [None] * len(groups))]
    return np.array([m for m, _ in out]), np.array([np.sqrt(np.mean(sd ** 2)) for _, sd in out], float)


def _norm_block(unit, before, after, floor_sd, what, labels):
    """Errors of a norm against its known value, before and after, with the floor; labels name
    the rows (segments or poses) for the ones far off (_far_off)."""
    ok = np.isfinite(floor_sd)
    return {"what": what, "unit": unit, "n": int(len(after)), "before_rms": _rms(before), "after_rms": _rms(after),
            "floor_rms": _rms(floor_sd[ok]) if ok.all() and ok.any() else None,
            "far_off": _far_off(after, floor_sd, labels)}


def _far_off(after, floor_sd, labels, k=FAR_OFF):
    """The rows whose calibrated error is k floors and k times the median error or more: a few
    rows far off, where the rest agree, are mislabelled or disturbed, not a model's failing."""
    e = np.abs(np.asarray(after, float))
    fl = np.broadcast_to(np.asarray(floor_sd, float), e.shape)
    if len(e) < 4 or not np.all(np.isfinite(fl)):
        return []
    far = (e > k * fl) & (e > k * np.median(e))
    return [labels[i] for i in np.nonzero(far)[0]] if far.sum() <= len(e) // 4 else []


def _block_model(block, t_ref_c):
    """(model, p, covariance) of a block for the propagation, or None without a covariance."""
    from simucal.fit.augmented import AugmentedModel
    if block.model == "affine":
        return None
    model = AugmentedModel(block.model, block.library_effects())
    th = block.thermal
    cov = th.get("covariance") if th else block.details.get("covariance")
    if not cov:
        return None
    if th:
        from simucal.fit.thermal import ThermalModel
        model = ThermalModel(model, [th["parameters"][n]["degree"] for n in model.params])
        p = np.array([th["parameters"][n.split(".T")[0]]["coefficients"][int(n.split(".T")[1]) if ".T" in n else 0]
                      for n in model.params])
    else:
        p = np.array([block.params[n] for n in model.params])
    if list(cov["names"]) != list(model.params):
        return None
    raw = block.details.get("std_raw")  # a failing model's stds inflated by its misfit: the covariance too
    k2 = (block.std[model.params[0]] / raw[model.params[0]]) ** 2 if raw and raw.get(model.params[0]) else 1.0
    return model, p, np.asarray(cov["matrix"], float) * k2


def calibration_sd(cal, sensor, u_b, aux_values: dict) -> np.ndarray | None:
    """The std of the calibrated norm |u| at each row (segment means u_b (n, 3) in b, with their
    auxiliary inputs: temp_c, f_x..) from the calibration's covariance (module doc); None where the
    file holds none."""
    from simucal.fit.aux_inputs import T_REF, AuxInputs
    block = getattr(cal, sensor)
    found = _block_model(block, cal.t_ref_c)
    if found is None:
        return None
    model, p, cov = found
    t_ref = block.thermal["t_ref_c"] if block.thermal else cal.t_ref_c
    values = dict(aux_values)
    if "temp_c" in values:
        values[T_REF] = 0.0 if t_ref is None else t_ref
    u = u_b @ block.C.T
    _, Ju, Jp = model.jacobians(u, p, AuxInputs(values))
    du = -np.linalg.solve(Ju, Jp)  # (n, 3, m): the calibrated input's change per parameter
    g = np.einsum("ni,nim->nm", u / np.linalg.norm(u, axis=1, keepdims=True), du)
    return np.sqrt(np.maximum(np.einsum("nm,mk,nk->n", g, cov, g), 0.0))


def _with_calibration(floor_sd, cal, sensor, means, groups, ms, f_means=None):
    """The noise floor per row and the calibration's std added in quadrature (None: the noise alone)."""
    aux = {}
    if "temp_c" in ms.samples:
        aux["temp_c"] = np.array([np.mean(ms.samples["temp_c"][g]) for g in groups])
    if f_means is not None:
        from simucal.fit.aux_inputs import specific_force
        aux.update(specific_force(f_means @ getattr(cal, sensor).C.T))
    sd = calibration_sd(cal, sensor, means, aux)
    return floor_sd if sd is None else np.hypot(floor_sd, sd), sd is not None


def _turntable(ms, f_before, f_after, w_before, w_after, cal):
    segs = ms.segments
    seg_rows = {s.segment: ms.rows(s.segment) for s in segs}
    lat = np.radians(ms.meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(ms.meta)
    out = {}
    static = [s for s in segs if s.kind == "static" and seg_rows[s.segment].size]
    if f_after is not None and static:
        groups = [seg_rows[s.segment] for s in static]
        sd = units.stated_noise(ms.meta, "acc")
        (mb, _), (ma, fl) = _segment_means(f_before, groups, sd), _segment_means(f_after, groups, sd)
        labels = [f"segment {s.segment}" for s in static]
        whole, with_cal = _with_calibration(fl, cal, "acc", ma, groups, ms)
        checks = [_norm_block("g", np.linalg.norm(mb, axis=1) - 1, np.linalg.norm(ma, axis=1) - 1, whole,
                              "|f| - 1 g at each static segment" + _FLOOR[with_cal], labels)]
        angled = [i for i, s in enumerate(static) if s.middle_deg is not None and s.inner_deg is not None]
        if len(angled) >= 3:
            # the navigation vertical (z up) in the table frame k: gravity's reaction
            up_k = directions_k([(s.outer_deg or 0.0, s.middle_deg, s.inner_deg) for s in (static[i] for i in angled)])
            errs = []
            for m in (mb[angled], ma[angled]):
                d = m / np.linalg.norm(m, axis=1, keepdims=True)
                R = wahba(up_k, d, np.ones(len(d)))
                errs.append(np.linalg.norm(d - up_k @ R.T, axis=1))
            # the table's angle errors move the direction too: two angles, each of its stated std
            table_sd = (table_accuracy_rad(ms) or 0.0) * np.sqrt(2)
            floor = np.hypot(fl[angled], table_sd)
            checks.append({"what": "gravity direction against the commanded table vertical, after the best "
                                   "rotation between unit and table" + (
                                       " (floor: noise and meta's table_accuracy_arcsec)" if table_sd else
                                       " (floor: the noise alone; the table's angle errors add to it)"),
                           "unit": "rad", "n": len(angled), "before_rms": _rms(errs[0]), "after_rms": _rms(errs[1]),
                           "floor_rms": _rms(floor) if np.all(np.isfinite(floor)) else None,
                           "far_off": _far_off(errs[1], floor, [labels[i] for i in angled]),
                           "far_off_hint": "check their commanded angles in segments.csv"})
        out["acc"] = checks
    if w_after is not None:
        sd = units.stated_noise(ms.meta, "gyro")
        checks = []
        rate = [s for s in segs if s.kind == "rate" and seg_rows[s.segment].size]
        for kind, chosen, truth in (("rate", rate, [abs(s.outer_rate_dps * units.DPH_PER_DPS + w_e * np.sin(lat)) for s in rate]),
                                    ("static", static, [w_e] * len(static))):
            if not chosen:
                continue
            groups = [seg_rows[s.segment] for s in chosen]
            angles = [outer_angle_rad(ms, seg_rows[s.segment], s) for s in chosen]
            (mb, _), (ma, fl) = _segment_means(w_before, groups, sd, angles), _segment_means(w_after, groups, sd, angles)
            f_means = None if f_after is None else np.array([f_after[g].mean(0) for g in groups])
            whole, with_cal = _with_calibration(fl, cal, "gyro", ma, groups, ms, f_means)
            what = ("|w| - |w_T + w_e sin L| at each rate run" if kind == "rate" else
                    "|w| - w_e (the Earth rate) at each static segment")
            checks.append(_norm_block("deg/h", np.linalg.norm(mb, axis=1) - truth, np.linalg.norm(ma, axis=1) - truth,
                                      whole, what + _FLOOR[with_cal], [f"segment {s.segment}" for s in chosen]))
        out["gyro"] = checks
    return out


_FLOOR = {True: " (floor: the noise and the calibration's own uncertainty)",
          False: " (floor: the noise alone; the file holds no covariance of its parameters)"}


def _stream(ms, f_before, f_after, w_before, w_after, cal):
    from simucal.handheld.moves import build_moves, move_residuals
    from simucal.handheld.static_detect import detect_static
    from simucal.io.sensor_checks import saturated_rows
    t = ms.samples["t_s"]
    det = detect_static(f_after, t)
    rest = slice(det.starts[0] + det.window // 2, det.ends[0] - det.window // 2)
    groups = [slice(a, b) for a, b in zip(det.starts, det.ends)]
    (mb, _), (ma, fl) = _segment_means(f_before, groups, None), _segment_means(f_after, groups, None)
    whole, with_cal = _with_calibration(fl, cal, "acc", ma, [np.arange(a, b) for a, b in zip(det.starts, det.ends)], ms)
    out = {"acc": [_norm_block("g", np.linalg.norm(mb, axis=1) - 1, np.linalg.norm(ma, axis=1) - 1, whole,
                               f"|f| - 1 g at each of the {len(groups)} static poses" + _FLOOR[with_cal],
                               [f"pose at {t[a]:.1f} s" for a in det.starts])]}
    if w_after is not None:
        bad = saturated_rows(ms, "gyro")[0]
        angles = []
        g_dirs = ma / np.linalg.norm(ma, axis=1, keepdims=True)  # the calibrated accelerometers: the gyro's reference
        for w, nominal in ((w_before, True), (w_after, False)):
            w_dps = w / units.DPH_PER_DPS
            bias = w_dps[rest].mean(0) if nominal else np.zeros(3)  # nominal: the rest's bias, as a user would
            mv, _ = build_moves(w_dps, t, det, bias, bad)
            angles.append(np.degrees(np.linalg.norm(move_residuals(np.eye(3), mv, g_dirs, jac=False)[0], axis=1)))
        out["gyro"] = [{"what": "gravity direction after each move: the integrated gyro against the calibrated "
                                "accelerometers (at nominal, the gyro bias from the initial rest)", "unit": "deg",
                        "n": int(len(angles[1])), "before_rms": _rms(angles[0]), "after_rms": _rms(angles[1]),
                        "floor_rms": None}]
    return out


def _verdict(check) -> str:
    b, a, fl = check["before_rms"], check["after_rms"], check["floor_rms"]
    if a is None or b is None:
        return "not measured"
    if a > WORSE * b and (fl is None or a > AT_FLOOR * fl):
        return "WORSE THAN NOMINAL"
    if fl is not None and a <= AT_FLOOR * fl:
        return "at the noise floor"
    return "better" if a * WORSE < b else "no better than nominal"


def validate(cal_path, data_dir) -> dict:
    """The report (module doc) of calibration file cal_path (or a Calibration) applied to the set data_dir
    (or a MeasurementSet)."""
    given = isinstance(cal_path, calibration.Calibration)
    cal = cal_path if given else calibration.load(cal_path)
    ms = data_dir if isinstance(data_dir, io.MeasurementSet) else io.read_set(data_dir)
    where = f"the calibration of {cal.input}" if given else cal_path
    meta, samples, _ = apply(cal, ms, where)  # checks the layout
    f_before = ms.acc_g() if ms.has_acc else None
    w_before = ms.gyro_dph() if ms.has_gyro else None
    f_after = np.column_stack([samples[c] for c in ("ax", "ay", "az")]) if ms.has_acc else None
    w_after = np.column_stack([samples[c] for c in ("gx", "gy", "gz")]) if ms.has_gyro else None
    if ms.segments is not None:
        checks = _turntable(ms, f_before, f_after, w_before, w_after, cal)
    elif f_after is not None:
        checks = _stream(ms, f_before, f_after, w_before, w_after, cal)
    else:
        raise CalibrationError(f"{ms.path}: a stream without accelerometers has no reference to validate against")
    for rows in checks.values():
        for c in rows:
            c["ratio_after_before"] = c["after_rms"] / c["before_rms"] if c["before_rms"] else None
            c["verdict"] = _verdict(c)
    verdicts = {s: ("not calibrated: kept at its nominal scale factors" if getattr(cal, s).nominal else
                    "WORSE THAN NOMINAL" if any(c["verdict"] == "WORSE THAN NOMINAL" for c in rows) else
                    "at the noise floor" if all(c["verdict"] == "at the noise floor" for c in rows) else "better"
                    if all(c["verdict"] in ("better", "at the noise floor") for c in rows) else "no better than nominal")
                for s, rows in checks.items() if rows}
    for s, rows in checks.items():
        far = sorted({x for c in rows for x in c.get("far_off") or []})
        if far and s in verdicts:
            verdicts[s] += f"; but {', '.join(far)} FAR OFF where the rest agree (mislabelled or disturbed)"
    own = own_rows(cal, ms)
    return {"format": "simucal.validation/1", "calibration": str(where), "data": str(ms.path),
            "independent": not own, "checks": checks, "verdict": verdicts,
            "warnings": list(meta.get("warnings", [])),  # apply's: rows outside the calibrated temperature range
            "note": own or None}


def own_rows(cal, ms) -> str:
    """What of set ms the calibration was made from, said ("" if nothing): its samples' digests against
    the calibration's samples_sha256 (per segment: an edit of meta.json, segments.csv or the number
    format does not hide them, and a few of its segments copied into another set show), else, for a
    file written before them, the files' input_sha256 (one per plateau for a thermal calibration)."""
    made_from = cal.input_sha256 if isinstance(cal.input_sha256, list) else [cal.input_sha256]
    mine = ms.sample_digests()
    shared = sum(d in set(cal.samples_sha256 or ()) for d in mine)
    if ms.sha256 in made_from or (mine and shared == len(mine)):
        return ("these are the data the calibration was made from: on its own rows a model always looks better; "
                "validate on another recording")
    if shared:
        return (f"{shared} of the {len(mine)} segments of these data are rows the calibration was made from (the "
                "same samples): on its own rows a model always looks better; validate on another recording")
    return ""


def lines(report):
    """The console: one table row per check, then the verdict per sensor."""
    if report["note"]:
        yield f"NOTE: {report['note']}"
    yield f"{'sensor':6} {'nominal':>10} {'calibrated':>10} {'floor':>9}  {'unit':8} check: verdict"
    for s, rows in report["checks"].items():
        for c in rows:
            fl = "-" if c["floor_rms"] is None else f"{c['floor_rms']:.3g}"
            yield (f"{s:6} {c['before_rms']:10.3g} {c['after_rms']:10.3g} {fl:>9}  {c['unit']:8} {c['what']} "
                   f"(rms over {c['n']}): {c['verdict']}")
            if c.get("far_off"):
                yield (f"{s}: FAR OFF where the rest agree: {', '.join(c['far_off'])} ({FAR_OFF:g} floors or more); "
                       + c.get("far_off_hint", "check those rows of the recording"))
    for w in report.get("warnings", []):
        yield f"WARNING: {report['data']}: {w}"
    for s, v in report["verdict"].items():
        yield f"{s}: {v}" + (": this calibration makes the unit worse on these data than its nominal scale "
                             "factors; do not use it" if v.startswith("WORSE THAN NOMINAL") else "")
    yield "next: " + validation_next(report)[0]


def html_page(report) -> str:
    """A self-contained page: the verdicts and the next command (report/console.py's, as the console
    prints them), each check's error at nominal and calibrated on a log scale with its floor, the table."""
    import html as _html

    from simucal.report.page import log_bars, page, plt, png, wrapped
    rows = [(s, c) for s, cs in report["checks"].items() for c in cs]
    cols = min(len(rows), 4)
    fig, axs = plt.subplots((len(rows) + cols - 1) // cols, cols, figsize=(3.1 * cols, 3.4 * ((len(rows) + cols - 1) // cols)),
                            squeeze=False, layout="constrained")
    for ax, (s, c) in zip(axs.flat, rows):
        log_bars(ax, ["nominal", "calibrated"], [c["before_rms"], c["after_rms"]], c["floor_rms"], c["unit"])
        ax.set_title(wrapped(f"{s}: {c['what'].split(' (')[0]}: {c['verdict']}", 34), fontsize=8)
    for ax in axs.flat[len(rows):]:
        ax.set_visible(False)
    body = "".join(f"<tr><td>{s}</td><td>{_html.escape(c['what'])}</td><td>{c['before_rms']:.3g}</td>"
                   f"<td>{c['after_rms']:.3g}</td><td>{'-' if c['floor_rms'] is None else format(c['floor_rms'], '.3g')}"
                   f"</td><td>{c['unit']}</td><td>{c['verdict']}</td></tr>" for s, c in rows)
    cmd, notes = validation_next(report)
    verdicts = [(not v.startswith(("WORSE", "no better")), f"{s}: {v}") for s, v in report["verdict"].items()]
    return page("simucal validate", f"Validation of {report['calibration']} on {report['data']}", verdicts, cmd,
                notes + [f"WARNING: {w}" for w in report.get("warnings", [])],
                [png(fig), "<table><tr><th>sensor</th><th>check</th><th>nominal</th><th>calibrated</th>"
                 f"<th>floor</th><th>unit</th><th>verdict</th></tr>{body}</table>"])
