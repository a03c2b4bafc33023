"""`simucal.validate` -> Validation (`simucal validate`): a calibration judged on an independent set, before and after.

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
  as an angle in deg, on the stream's clock as the calibration read its own. Both arms take the
  gyro's bias from the session's initial rest (no calibration carries another power-up's turn-on
  bias) and the calibrated accelerometers' directions, so the check is the gyro's T alone; its floor
  is the gyro's white noise, the rest bias's error and the poses' directions with the accelerometer
  calibration's uncertainty (handheld/validation.py).

The floor of each norm error is its whole uncertainty: the noise (a segment's or pose's scatter
over its rows, std of the mean, or the stated noise of one row) and the calibration's own: its
parameters' covariance (a thermal calibration's coefficients', at each segment's temperature)
propagated to the calibrated norm, d|u|/dp = (u/|u|)' (dh/du)^-1 dh/dp, added in quadrature
(fit/validation.py's `calibration_sd`; a file without a covariance adds nothing, and the check says so). A calibration
whose error is above the nominal one's is said to be worse, loudly; rows outside a calibration's
temperature range are named (apply's warning). The checks of each kind of data are its entry's in methods.KINDS
(turntable/validation.py, handheld/validation.py).
"""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Mapping, NamedTuple, Sequence

import numpy as np
from numpy.typing import NDArray

from simucal import io, methods
from simucal.arguments import checked
from simucal.api.calibrating import Data
from simucal.io.calibration import Calibration
from simucal.api.sets import folder_of
from simucal.api.tables import TableOf
from simucal.fit.apply import apply
from simucal.fit.validation import FAR_OFF, ValidationReport
from simucal.errors import CalibrationError
from simucal.io import calibration, units
from simucal.io.details import WARMUP
from simucal.io.timestamps import with_timestamps
from simucal.report.console import skipped_sensors, validation_next

WORSE = 1.05  # after/before above this: the calibration makes the unit worse on these data
AT_FLOOR = 2.0  # after below this many floors: the noise, nothing left to gain

FORMAT = "simucal.validation/1"  # the report validate writes (the certificate reads it)


def _verdict(check: Mapping[str, Any]) -> str:
    b, a, fl = check["before_rms"], check["after_rms"], check["floor_rms"]
    if a is None or b is None:
        return "not measured"
    if a > WORSE * b and (fl is None or a > AT_FLOOR * fl):
        return "WORSE THAN NOMINAL"
    if fl is not None and a <= AT_FLOOR * fl:
        return "at the noise floor"
    return "better" if a * WORSE < b else "no better than nominal"


TABLE_LIMITED = ("the gravity direction against the commanded angles is above its floor, which lacks the table's "
                 "angle errors the set does not state (table_accuracy_arcsec, table_tilt_arcsec): the table, not the "
                 "calibration")


def _sensor_verdict(rows: Sequence[Mapping[str, Any]], nominal: bool) -> str:
    """A sensor's verdict from its checks. A check limited by the table (the gravity direction against commanded
    angles whose errors the set does not state: its floor lacks them) does not pull a verdict below the floor
    that the calibration's own checks reach (the report's verdict_notes say so); it still counts when it is
    worse than nominal."""
    if nominal:
        return "not calibrated: kept at its nominal scale factors"
    if any(c["verdict"] == "WORSE THAN NOMINAL" for c in rows):
        return "WORSE THAN NOMINAL"
    own = [c for c in rows if not c.get("limited_by_table")] or rows
    if all(c["verdict"] == "at the noise floor" for c in own):
        return "at the noise floor"
    return "better" if all(c["verdict"] in ("better", "at the noise floor") for c in rows) else "no better than nominal"


REGISTER_BITS = (8, 10, 12, 14, 16, 18, 20, 24, 32)


def nominal(ms: io.MeasurementSet, sensor: str) -> tuple[NDArray[np.float64], str]:
    """A sensor's outputs at the nominal scale factors (acc in g, gyro in deg/h) as a user reads them
    without a calibration, and what was subtracted, said ('' where nothing). Raw counts carry the
    register's zero (the spec's `counts`: an unsigned 16-bit ADC rests near 32768, 8 g at 4096
    counts/g), which the calibration's bias absorbs but a nominal reading must not keep: meta.json's
    {sensor}_offset_counts (x y z) where stated, else an unsigned register's mid-scale 2^(b-1) where
    every row lies in [0, 2^b) and every axis's median within 2^(b-2) of it (b the narrowest of
    REGISTER_BITS); a signed register's rows lie near 0 and keep no offset."""
    out = ms.acc_g() if sensor == "acc" else ms.gyro_dph()
    if ms.meta.get(f"{sensor}_unit") != "counts":
        return out, ""
    meta: Mapping[str, Any] = ms.meta  # read by a key made of the sensor's name
    raw, key = ms.raw(sensor), f"{sensor}_offset_counts"
    if key in meta:
        try:
            off = np.asarray(meta[key], float).reshape(-1)
        except (TypeError, ValueError):
            off = np.zeros(0)
        if off.size not in (1, 3) or not np.all(np.isfinite(off)):
            raise CalibrationError(f"{ms.path / 'meta.json'}: {key} {meta[key]!r}: give the register's value at "
                                   "zero input, one number or x y z, e.g. 32768")
        how = f"meta.json's {key}"
    else:
        b = next((b for b in REGISTER_BITS if raw.max() < 2.0 ** b), None)
        half = 2.0 ** (b - 1) if b else np.nan
        if b is None or raw.min() < 0 or np.any(np.abs(np.median(raw, axis=0) - half) > half / 2):
            return out, ""
        off, how = np.array([half]), f"inferred: an unsigned {b}-bit register's mid-scale; state {key} in meta.json"
    off = np.broadcast_to(off, (3,))
    to_unit = units.acc_to_g if sensor == "acc" else units.gyro_to_dph
    return out - to_unit(off[None], ms.meta)[0], f"{sensor}: the counts less {', '.join(f'{x:g}' for x in off)} ({how})"


class Check(NamedTuple):
    """One row of `Validation.checks`: an error of the calibrated outputs against physics."""
    sensor: str
    what: str
    unit: str
    n: int
    nominal_rms: float | None     # at the nominal scale factors only
    calibrated_rms: float | None  # after the calibration
    floor_rms: float | None       # the noise and the calibration's own uncertainty (None: not known)
    verdict: str


@dataclass
class Validation:
    """A calibration judged on a set (ideally one it was not made from).

    Attributes
    ----------
    verdict : dict
        Per sensor: "at the noise floor", "better", "no better than nominal", "WORSE THAN NOMINAL".
    checks : DataFrame or list of Check
        Each check's error at nominal, after the calibration and its floor (a table).
    check_rows : list of Check
        The same rows as a list.
    independent : bool
        False where the data are the calibration's own (a model always looks better there).
    warnings : list of str
    report : dict
        What `simucal validate -o` writes (``simucal.validation/1``).
    """
    verdict: dict[str, str]
    check_rows: list[Check]
    independent: bool
    warnings: list[str]
    report: ValidationReport  # validation.json as written
    checks = TableOf("check_rows", Check._fields)

    def __repr__(self) -> str:  # the report's arrays are in .report
        return ("<simucal.Validation: " + "; ".join(f"{s} {v}" for s, v in self.verdict.items())
                + ("" if self.independent else " (on the calibration's own data)") + ">")

    def _repr_html_(self) -> str:
        from simucal.notebook import html_card
        return html_card("simucal.Validation", [*self.verdict.items(), ("independent data", self.independent),
                                                *[("warning", w) for w in self.warnings]])


@checked
def validate(cal: Calibration | str | os.PathLike[str], data: Data, *, acc_noise_g: float | None = None,
             gyro_noise_dph: float | None = None, timestamps: str | None = None, units: str = "spec") -> Validation:
    """Apply a calibration to an independent set and compare with nominal and the noise floor.

    Parameters
    ----------
    cal : Calibration or a calibration file's path
    data : str, os.PathLike or MeasurementSet
    acc_noise_g, gyro_noise_dph : float, optional
        The noise of one row (g, deg/h) where the data cannot give it (averaged rows), as `calibrate` takes it:
        the floor of those rows' checks stands on it (without it, such rows have no floor).
    timestamps : {"auto", "recorded", "nominal"}, optional
        A stream's time stamps, as `calibrate` takes them; default: as the calibration read its own.
    units : {"spec", "si"}
        The unit system of ``.checks`` (si: m/s^2 and rad/s, as `simucal validate --units si` prints them);
        ``.report``, the file, is always in the spec's.

    Returns
    -------
    Validation

    Examples
    --------
    >>> v = simucal.validate(cal, "other_set")  # doctest: +SKIP
    >>> v.verdict  # doctest: +SKIP
    {'acc': 'at the noise floor', 'gyro': 'at the noise floor'}
    """
    from simucal.report.units import validation_in
    io.units.check_unit_system(units)
    report = validation_report(cal, data if isinstance(data, io.MeasurementSet) else folder_of(data), acc_noise_g,
                              gyro_noise_dph, timestamps)
    checks = [Check(s, c["what"], c["unit"], c["n"], c["before_rms"], c["after_rms"], c["floor_rms"], c["verdict"])
              for s, rows in validation_in(report, units)["checks"].items() for c in rows]
    return Validation(dict(report["verdict"]), checks, bool(report["independent"]),
                      list(report["warnings"]), report)


def validation_report(cal_path: str | os.PathLike[str] | calibration.Calibration,
                      data_dir: str | os.PathLike[str] | io.MeasurementSet,
                      acc_noise_g: float | None = None, gyro_noise_dph: float | None = None,
                      timestamps: str | None = None) -> ValidationReport:
    """The report (module doc) of calibration file cal_path (or a Calibration) applied to the set data_dir
    (or a MeasurementSet). acc_noise_g, gyro_noise_dph: the noise of one row where the data cannot give it
    (averaged rows), as calibrate takes it: the floors of those rows' checks stand on it. timestamps: a
    stream's stamps (io/timestamps.py: auto, recorded, nominal); None: as the calibration read its own
    (the calibration file's timestamps choice, else auto's rule)."""
    given = isinstance(cal_path, calibration.Calibration)
    cal = cal_path if isinstance(cal_path, calibration.Calibration) else calibration.load(cal_path)
    ms = data_dir if isinstance(data_dir, io.MeasurementSet) else io.read_set(data_dir)
    stamps = None
    if methods.data_kind(ms) == methods.STREAM:  # a stream's clock: as the calibration was told, else auto's rule
        ms, stamps = with_timestamps(ms, timestamps or (cal.details.get("timestamps") or {}).get("choice", "auto"))
    stated = {k: v for k, v in (("acc_noise_g", acc_noise_g), ("gyro_noise_dph", gyro_noise_dph)) if v is not None}
    if stated:
        units.check_meta({**ms.meta, **stated}, ms.path, lambda p, line, rule: CalibrationError(f"{p}: {rule}"))
        ms = ms.copy(meta={**ms.meta, **stated})
    where = f"the calibration of {cal.input}" if given else cal_path
    meta, samples, _ = apply(cal, ms, where)  # checks the layout
    (f_before, said_a), (w_before, said_g) = (nominal(ms, s) if has else (None, "") for s, has in
                                              (("acc", ms.has_acc), ("gyro", ms.has_gyro)))
    f_after = np.column_stack([samples[c] for c in ("ax", "ay", "az")]) if ms.has_acc else None
    w_after = np.column_stack([samples[c] for c in ("gx", "gy", "gz")]) if ms.has_gyro else None
    if cal.method.startswith(WARMUP):
        from simucal.handheld.warmup import warmup_checks
        checks = warmup_checks(ms, f_before, f_after, w_before, w_after, cal)
    else:
        checks = methods.kind_of(ms).validation_checks(ms, f_before, f_after, w_before, w_after, cal)
    for rows in checks.values():
        for c in rows:
            c["ratio_after_before"] = c["after_rms"] / c["before_rms"] if c["before_rms"] else None
            c["verdict"] = _verdict(c)
    verdicts = {s: _sensor_verdict(rows, getattr(cal, s).nominal) for s, rows in checks.items() if rows}
    notes = {s: TABLE_LIMITED for s, rows in checks.items() if verdicts.get(s) == "at the noise floor" and any(
        c.get("limited_by_table") and c["verdict"] != "at the noise floor" for c in rows)}
    for s, rows in checks.items():
        far = sorted({x for c in rows for x in c.get("far_off") or []})
        if far and s in verdicts:
            verdicts[s] += f"; but {', '.join(far)} FAR OFF where the rest agree (mislabelled or disturbed)"
    own = own_rows(cal, ms)
    cal_sha = (None if isinstance(cal_path, calibration.Calibration)  # the bytes the certificate matches
               else hashlib.sha256(Path(cal_path).read_bytes()).hexdigest())
    return {"format": FORMAT, "calibration": str(where), "calibration_sha256": cal_sha, "data": str(ms.path),
            "independent": not own, "checks": checks, "verdict": verdicts, "verdict_notes": notes,
            "warnings": list(meta.get("warnings", [])),  # apply's: rows outside the calibrated temperature range
            "note": own or None, "nominal": [x for x in (said_a, said_g) if x], "skipped": skipped_sensors(ms.sensors),
            **({"timestamps": stamps} if stamps else {})}


def own_rows(cal: calibration.Calibration, ms: io.MeasurementSet) -> str:
    """What of set ms the calibration was made from, said ("" if nothing): its samples' digests against
    the calibration's samples_sha256 (per segment: an edit of meta.json, segments.csv or the number
    format does not hide them, and a few of its segments copied into another set show), else, for a
    file written before them, the files' input_sha256 (one per plateau for a thermal calibration)."""
    made_from = cal.input_sha256 if isinstance(cal.input_sha256, list) else [cal.input_sha256]
    mine = ms.sample_digests()
    shared = sum(d in set(cal.samples_sha256 or ()) for d in mine)
    if (ms.sha256 is not None and ms.sha256 in made_from) or (mine and shared == len(mine)):  # None: in memory
        return ("these are the data the calibration was made from: on its own rows a model always looks better; "
                "validate on another recording")
    if shared:
        return (f"{shared} of the {len(mine)} segments of these data are rows the calibration was made from (the "
                "same samples): on its own rows a model always looks better; validate on another recording")
    return ""


def lines(report: ValidationReport, units: str = "spec") -> list[str]:
    """The console: one table row per check, then the verdict per sensor, in the unit system asked."""
    if units == "spec":
        return list(_lines(report))
    from simucal.report import units as shown
    g = shown.gravity_of(report.get("data"))
    return shown.lines_in(_lines(shown.validation_in(report, units, g)), units, g)


def _lines(report: ValidationReport) -> Iterator[str]:
    if report["note"]:
        yield f"NOTE: {report['note']}"
    for x in report.get("nominal", []):
        yield f"nominal: {x}"
    if report.get("timestamps"):
        yield report["timestamps"]["text"]
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
    yield from report.get("skipped", [])
    for s, v in report["verdict"].items():
        yield f"{s}: {v}" + (": this calibration makes the unit worse on these data than its nominal scale "
                             "factors; do not use it" if v.startswith("WORSE THAN NOMINAL") else "") + (
            f" ({report['verdict_notes'][s]})" if s in report.get("verdict_notes", {}) else "") + _own(report)
    yield "next: " + validation_next(report)[0]


def _own(report: ValidationReport) -> str:
    """What a verdict on the calibration's own rows adds to it: that it proves nothing (the NOTE says why)."""
    return " (NOT INDEPENDENT: the calibration's own rows)" if report["note"] else ""


def html_page(report: ValidationReport) -> str:
    """A self-contained page: the verdicts and the next command (report/console.py's, as the console
    prints them), each check's error at nominal and calibrated on a log scale with its floor, the table."""
    from simucal.report.numbers import eng_html
    from simucal.report.page import log_bars, page, png, table, wrapped
    import matplotlib.pyplot as plt  # after page: its backend and style
    rows = [(s, c) for s, cs in report["checks"].items() for c in cs]
    cols = min(len(rows), 4)
    fig, axs = plt.subplots((len(rows) + cols - 1) // cols, cols,
                            figsize=(3.1 * cols, 3.4 * ((len(rows) + cols - 1) // cols)),
                            squeeze=False, layout="constrained")
    for ax, (s, c) in zip(axs.flat, rows):
        log_bars(ax, ["nominal", "calibrated"], [c["before_rms"], c["after_rms"]], c["floor_rms"], c["unit"])
        ax.set_title(wrapped(f"{s}: {c['what'].split(' (')[0]}: {c['verdict']}", 34), fontsize=8)
    for ax in axs.flat[len(rows):]:
        ax.set_visible(False)
    cmd, notes = validation_next(report)
    verdicts = [(not v.startswith(("WORSE", "no better")) and not report["note"], f"{s}: {v}{_own(report)}")
                for s, v in report["verdict"].items()]  # on its own rows no verdict is shown as passed
    return page("simucal validate", f"Validation of {report['calibration']} on {report['data']}", verdicts, cmd,
                notes + [f"WARNING: {w}" for w in report.get("warnings", [])],
                [png(fig), table(["sensor", "check", "nominal", "calibrated", "floor", "unit", "verdict"],
                                 [[s, c["what"], c["before_rms"], c["after_rms"], eng_html(c["floor_rms"]), c["unit"],
                                   c["verdict"]] for s, c in rows])])
