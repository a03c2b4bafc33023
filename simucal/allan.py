"""`simucal noise`: Allan deviation of a static recording and the IEEE 952 noise terms (the
terms the data show).

Overlapping Allan variance of a rate y sampled every dt (IEEE 952-1997, Annex C, eq. C.2, with
overlapping clusters as allantools' oadev computes it): with theta the integrated output
(theta_k = dt * sum_{i<k} y_i) and tau = m dt,

    sigma^2(tau) = sum_k (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2 / (2 tau^2 (N - 2m)).

Several static stretches (the static segments of a raw turntable set) are pooled: their sums of
squares and their counts add. Computed with cumulative sums, one pass per tau (vectorised); the
tests check it against allantools.oadev to 1e-12. Tau runs over about 10 values per decade, up to
a ninth of the longest stretch, where the clusters still number 9 or more.

The terms (IEEE 952 Table C.1): sigma^2(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln 2 / pi) B^2
+ K^2 tau / 3 + R^2 tau^2 / 2, linear in the squares. Q: quantisation, N: angle (velocity) random
walk, B: bias instability (the flat floor's coefficient, 0.664 B), K: rate random walk, R: rate
ramp. Neighbouring overlapping estimates share most of their data: fitted as independent points
every term looked significant (3-18 sigma for terms that were not there). So they are
fitted by generalised least squares with the estimates' covariance, exact for white noise,
random walk and quantisation at the record's length and rate (simucal.fit.allan_cov), and a term
is reported only where the data show it (simucal.fit.allan_fit: why GLS, the test, the bound);
otherwise it is "not seen" with the 95 % upper bound the record allows, or, where the record has
too few taus to test it, "too short" with the length it needs. The 68 % band drawn around the
fitted curve (rel_err in the report) is that covariance's, at the fitted model. A channel that never changes (stuck or
dead) is named, with no terms: its Allan deviation of 0 is not a perfect sensor.

Units: gyro rates in deg/h, accelerometer outputs in g, tau in s; each term also in the units a
data sheet uses (deg/sqrt(h), ug/sqrt(Hz), deg/h, ...), and for Kalibr's imu.yaml in SI.
"""
from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from simucal import io, methods
from simucal.errors import CalibrationError
from simucal.fit import allan_cov, allan_fit, allan_sums
from simucal.fit.noise import TERMS, allan_deviation
from simucal.report.console import skipped_sensors
from simucal.io import MeasurementSetError, columnar
from simucal.report.kalibr import kalibr_missing, kalibr_yaml  # noqa: F401 (allan.kalibr_yaml: the API's)

MIN_CLUSTERS = 9  # the longest tau keeps this many independent clusters (relative error <= 25 %)

# (name, factor from the fitted unit, unit) of each term for a data sheet; the fitted units are
# sigma's (deg/h, g) times s^a: Q [.s], N [.sqrt(s)], B [.], K [./sqrt(s)], R [./s]
SHEET = {"gyro": {"Q": ("quantisation", 1.0, "arcsec"), "N": ("angle random walk", 1 / 60.0, "deg/sqrt(h)"),
                  "B": ("bias instability", 1.0, "deg/h"), "K": ("rate random walk", 60.0, "deg/h/sqrt(h)"),
                  "R": ("rate ramp", 3600.0, "deg/h/h")},
         "acc": {"Q": ("quantisation", 1e6, "ug*s"), "N": ("velocity random walk", 1e6, "ug/sqrt(Hz)"),
                 "B": ("bias instability", 1e6, "ug"), "K": ("acceleration random walk", 1e6, "ug/sqrt(s)"),
                 "R": ("acceleration ramp", 1e6, "ug/s")}}


def taus(n_longest: int, per_decade=10, m_max=None) -> np.ndarray:
    """Cluster sizes m (log-spaced, distinct) from 1 to n_longest / MIN_CLUSTERS, or to m_max."""
    top = max(n_longest // MIN_CLUSTERS if m_max is None else int(m_max), 1)
    return np.unique(np.floor(np.logspace(0, np.log10(top), max(int(per_decade * np.log10(top)) + 1, 1))).astype(int))


def allan_variance(stretches, dt: float, m_values) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan variance (module doc) of one channel pooled over stretches (a list of 1-D
    arrays of the rate, one per still stretch): (avar (len(m_values),), terms pooled per m)."""
    sums = np.zeros(len(m_values))
    counts = np.zeros(len(m_values))
    for y in stretches:
        theta = np.r_[0.0, np.cumsum(y)] * dt
        for i, m in enumerate(m_values):
            if len(theta) > 2 * m:
                d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
                sums[i] += float(d @ d)
                counts[i] += len(d)
    tau = np.asarray(m_values) * dt
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums / (2 * tau ** 2 * counts), counts


def still_stretches(ms, sensor) -> tuple[list[np.ndarray], float, str]:
    """(stretches (rows, 3), dt, where): the whole stream, or each static segment of a raw
    turntable set (three rows or more), in deg/h or g."""
    data = ms.gyro_dph() if sensor == "gyro" else ms.acc_g()
    t = ms.samples["t_s"]
    pieces, where = methods.kind_of(ms).still_rows(ms)
    dt = sample_step(np.concatenate([np.diff(t[p]) for p in pieces]), ms.path / "samples.csv")
    return [data[p] for p in pieces], dt, where


def sample_step(dts, path) -> float:
    """The sample clock (s): the median step of t_s; refused where a step is a gap (lost samples)."""
    lo, hi = float(dts.min()), float(dts.max())
    dt = float(np.median(dts, overwrite_input=True))  # dts reordered in place: no copy of a long record's steps
    # a logger's timestamps jitter around the sample clock (taken as the median step); a gap is lost samples
    if dt <= 0 or max(hi - dt, dt - lo) > 0.5 * dt:
        raise CalibrationError(f"{path}: t_s has gaps within the still stretches (steps "
                               f"{lo:.4g} to {hi:.4g} s, median {dt:.4g}): the Allan deviation needs "
                               "every sample of a constant rate; cut the recording at the gaps")
    return dt


def second_rows(dt) -> int:
    """Rows in one second: the means check_still compares."""
    return max(int(round(1.0 / dt)), 1)


# A still unit's 1-s means wander by its noise and drift only, far below these; a hand-placed move passes them
# (0.05 g of specific force; 1 deg/s of rate, where a set has no accelerometers to tell)
MOVING = {"acc": (0.05, "g", "specific force"), "gyro": (3600.0, "deg/h", "rate")}


def check_still(ms, dt):
    """Refuse a stream that moves: its 1-s mean specific force (or, without accelerometers, rate) may wander by
    noise, not move by MOVING's amount (the difference of two means: a raw register's zero cancels, where an
    angle would need it)."""
    if not methods.kind_of(ms).still_whole:
        return
    sensor = "acc" if ms.has_acc else "gyro"
    x = ms.acc_g() if sensor == "acc" else ms.gyro_dph()
    k = second_rows(dt)
    refuse_moving(x[: len(x) // k * k].reshape(-1, k, 3).mean(1), x.mean(0), ms.path, sensor)


def refuse_moving(x_1s, x_mean, where, sensor="acc"):
    """check_still on a sensor's 1-s means (rows, 3) and its mean over the record (g or deg/h)."""
    limit, unit, what = MOVING[sensor]
    off = np.linalg.norm(x_1s - x_mean, axis=1)
    if len(off) > 1 and np.max(off) > limit:
        raise CalibrationError(f"{where}: the unit moves during the recording (its 1-s mean {what} differs "
                               f"from the record's mean by up to {np.max(off):.2g} {unit}, where a still unit's "
                               "wanders by the noise only): the Allan deviation needs a still unit; record it at rest")


def _seconds_for(n_taus: int, dt: float) -> float:
    """The shortest still stretch (s) whose default grid holds n_taus taus."""
    top = n_taus
    while len(taus(MIN_CLUSTERS * top)) < n_taus:
        top += 1
    return MIN_CLUSTERS * top * dt


def cluster_sizes(lengths, dt, tau_max_s, where) -> np.ndarray:
    """taus(), up to tau_max_s where asked, for still stretches of these lengths (rows); refused where
    the longest is too short for it, or where the grid would hold fewer taus than the white noise's fit needs."""
    n = max(lengths)
    need = allan_fit.TERMS_NEEDING["N"]
    if len(taus(n)) < need:
        raise CalibrationError(f"{where}: the longest still stretch is {n * dt:.4g} s ({n} rows), too short for an "
                               f"Allan fit: its {need} taus need {_seconds_for(need, dt):.4g} s; record longer")
    if tau_max_s is None:
        return taus(n)
    if n < MIN_CLUSTERS * tau_max_s / dt:
        raise CalibrationError(f"{where}: the longest still stretch is {n * dt:.4g} s; a tau of {tau_max_s:g} s needs "
                               f"{MIN_CLUSTERS} clusters of it ({MIN_CLUSTERS * tau_max_s:.4g} s): record longer, or ask "
                               f"for --tau-max-s {n * dt / MIN_CLUSTERS:.3g} at most")
    if len(taus(n, m_max=tau_max_s / dt)) < need:
        lowest = next(m for m in range(need, n) if len(taus(n, m_max=m)) >= need) * dt
        raise CalibrationError(f"{where}: --tau-max-s {tau_max_s:g} leaves fewer than the {need} taus (multiples of "
                               f"the {dt:.4g} s sample step) the fit needs: ask for --tau-max-s {lowest:.4g} at least")
    return taus(n, m_max=tau_max_s / dt)


def stuck(lo, hi, first, rows, unit) -> str | None:
    """Why a channel has no noise to characterise: its value (from lo to hi, the first one `first`, over
    `rows` rows) never changes (to 1e-12 of itself)."""
    if hi - lo <= 1e-12 * max(abs(lo), abs(hi)):
        return (f"stuck or dead: constant at {first:.6g} {unit} over all {rows} rows (a real sensor's "
                "output always has noise); no noise terms")
    return None


def axis_report(sensor, y, dt, m, mats, unit) -> dict:
    """One axis of the report: its Allan deviation, the model's 68 % interval, the terms seen and
    the bounds of those not seen (module doc); "fit": the final model's chi2, dof and its terms'
    squares (x, std) in the fitted units (Q^2, N^2, ... of `terms`), below zero where noise puts them."""
    values = np.concatenate(y)
    return axis_from_avar(sensor, allan_variance(y, dt, m)[0], stuck(values.min(), values.max(), values[0],
                                                                      len(values), unit), dt, m, mats)


def axis_from_avar(sensor, avar, stuck_why, dt, m, mats) -> dict:
    """axis_report from the Allan variance at the cluster sizes m (a stream read chunk by chunk: characterise_folder)."""
    tau = m * dt
    if stuck_why:
        return {"stuck": stuck_why, "adev": np.sqrt(avar).tolist(), "tau_s": tau.tolist()}
    fit = allan_fit.select(tau, avar, mats)
    terms = {k: (v[0] if v else 0.0) for k, v in fit["terms"].items()}
    model = allan_deviation(terms, tau) ** 2
    sheet = {}
    for k in TERMS:
        name, factor, unit_k = SHEET[sensor][k]
        entry = {"name": name, "unit": unit_k, "value": terms[k] * factor, "std": None}
        if fit["terms"][k]:
            entry.update(status="seen", std=fit["terms"][k][1] * factor)
        elif k in fit["bounds"]:
            entry.update(status="not seen", bound_95=fit["bounds"][k] * factor)
        else:
            entry.update(status="too short", needs_s=_seconds_for(fit["needs_taus"], dt))
        sheet[k] = entry
    return {"adev": np.sqrt(avar).tolist(), "rel_err": (np.sqrt(np.diag(fit["cov"])) / (2 * model)).tolist(),
            "tau_s": tau.tolist(), "terms": terms, "bounds": fit["bounds"], "sheet": sheet,
            "fit": {"chi2": fit["chi2"], "dof": fit["dof"], "squares": fit["squares"]}}


def characterise(ms, tau_max_s=None) -> dict:
    """The report of `simucal noise` (module doc): per sensor and axis, the Allan deviation with its
    68 % interval and the terms seen (value, std) or not (95 % bound) in the sensor's units and a
    data sheet's; tau up to tau_max_s (default a ninth of the longest still stretch)."""
    out: dict[str, Any] = {"format": "simucal.noise/1", "data": str(ms.path)}
    for sensor, has in (("acc", ms.has_acc), ("gyro", ms.has_gyro)):
        if not has:
            continue
        stretches, dt, where = still_stretches(ms, sensor)
        check_still(ms, dt)
        lengths = [len(s) for s in stretches]
        m = cluster_sizes(lengths, dt, tau_max_s, ms.path / "samples.csv")
        mats = allan_cov.basis(m, dt, lengths)
        out[sensor] = sensor_report(sensor, dt, m, where, {a: axis_report(
            sensor, [s[:, j] for s in stretches], dt, m, mats, UNIT[sensor]) for j, a in enumerate("xyz")})
    if "acc" not in out and "gyro" not in out:
        raise CalibrationError(f"{ms.path}: no sensor columns to characterise")
    if "temp_c" in ms.samples:
        T = np.asarray(ms.samples["temp_c"], float)
        out.update(temperature_block(float(T.min()), float(T.max()), ms.path))
    return out


TEMP_CHANGE_C = 3.0  # a MEMS bias moves by its instability's size over a few degC


def temperature_block(lo, hi, data) -> dict:
    """{"temperature": its range and, where it changes by over TEMP_CHANGE_C, the warning}: a warming board's
    bias follows its temperature, which the Allan variance reads as rate ramp, random walk and instability."""
    block: dict[str, Any] = {"range_c": [lo, hi]}
    if hi - lo > TEMP_CHANGE_C:
        block["warning"] = (f"the temperature changes by {hi - lo:.3g} degC over the record ({lo:.4g} to {hi:.4g} degC): "
                            "the bias's thermal drift reads as bias instability, random walk and rate ramp, so the "
                            "long-tau terms (and Kalibr's random walks) may be thermal, not noise; record at a steady "
                            f"temperature, or take the thermal model out first: simucal calibrate {data} --thermal -o "
                            f"warm.json, simucal apply warm.json {data} -o {Path(str(data)).name}_flat, simucal noise "
                            f"{Path(str(data)).name}_flat")
    return {"temperature": block}


UNIT = {"gyro": "deg/h", "acc": "g"}


def sensor_report(sensor, dt, m, where, axes) -> dict:
    """One sensor's block of the report, around its axes' (axis_report)."""
    return {"unit": UNIT[sensor], "tau_s": (m * dt).tolist(), "rate_hz": 1.0 / dt, "rows": where, "axes": axes}


def _check_still_stream(kept, dt, where, sensor) -> None:
    """check_still from a sensor's theta: the 1-s means are its differences."""
    triad = io.SENSOR_COLS[sensor]
    th = [kept.theta[c] for c in triad]
    n, k = th[0].n - 1, second_rows(dt)
    center = np.array([kept.center[c] for c in triad])
    sums = np.column_stack([t.at(np.arange(0, n // k * k + 1, k)) for t in th])
    whole = np.array([t.at(np.array([n]))[0] for t in th])
    refuse_moving(np.diff(sums, axis=0) / k + center, whole / n + center, where, sensor)


def characterise_folder(folder, tau_max_s=None, scheduler=None, size=allan_sums.CHUNK) -> dict:
    """characterise() of the set in `folder`, a still stream read a chunk at a time (simucal.fit.allan_sums:
    theta in parts of `size` values, the rows of one task, here or on Dask with `scheduler`); a
    segmented set (a turntable test's static segments, short) is read whole."""
    folder = Path(folder)
    meta = io.read_meta(folder)
    if io.read_segments(folder) is not None:
        return characterise(io.read_set(folder), tau_max_s)
    path = io.samples_path(folder)
    cols, _ = columnar.columns_of(path, None)
    sensors = [s for s, c in (("acc", "ax"), ("gyro", "gx")) if c in cols]
    if "gyro" in sensors and "latitude_deg" not in meta:
        raise MeasurementSetError(folder / "meta.json", None, "latitude_deg is required when gyro data are present")
    scratch: contextlib.AbstractContextManager[str | None] = contextlib.nullcontext()
    if scheduler not in (None, "local"):  # spilled: theta's parts in files the workers read
        scratch = tempfile.TemporaryDirectory(prefix="simucal-noise-")
    with scratch as spill:
        kept, steps = allan_sums.read_pass(folder, meta, sensors, Path(spill) if spill else None, size,
                                           temperature="temp_c" in cols)
        dt = sample_step(steps, path)
        del steps
        n = kept.theta[next(iter(kept.theta))].n - 1
        _check_still_stream(kept, dt, folder, sensors[0])  # acc where it has them
        out: dict[str, Any] = {"format": "simucal.noise/1", "data": str(folder)}
        for sensor in sensors:
            m = cluster_sizes([n], dt, tau_max_s, path)
            mats = allan_cov.basis(m, dt, [n])
            triad = io.SAMPLE_COLS[:3] if sensor == "acc" else io.SAMPLE_COLS[3:]
            avars = allan_sums.allan_variances([kept.theta[c] for c in triad], m, scheduler)
            out[sensor] = sensor_report(sensor, dt, m, "the whole stream", {a: axis_from_avar(
                sensor, avar, stuck(kept.lo[c], kept.hi[c], kept.first[c], n, UNIT[sensor]), dt, m, mats)
                for a, c, avar in zip("xyz", triad, avars)})
    if "temp_c" in cols:
        out.update(temperature_block(kept.temp_c[0], kept.temp_c[1], folder))
    return out


def _term_text(t, html=False) -> str:
    """One term: value +- std where seen, else "not seen" and its bound, or the length it needs."""
    pm, lt, unit = (" &plusmn; ", "&lt;", "") if html else (" +- ", "<", " " + t["unit"])
    if t["status"] == "seen":
        return f"{t['value']:.3g}{pm}{t['std']:.2g}{unit}"
    if t["status"] == "not seen":
        return f"not seen ({lt} {t['bound_95']:.2g}{unit}, 95 %)"
    return f"record too short (needs {t['needs_s']:.3g} s)"


def lines(report, written=None, units: str = "spec"):
    """The console: each axis's terms in a data sheet's units (or SI), seen or not; written: next_step's."""
    if units == "spec":
        return list(_lines(report, written))
    from simucal.report import units as shown
    g = shown.gravity_of(report.get("data"))
    return shown.lines_in(_lines(shown.noise_in(report, units, g), written), units, g)


def _lines(report, written=None):
    for sensor in ("acc", "gyro"):
        if sensor not in report:
            continue
        b = report[sensor]
        yield (f"{sensor}: Allan deviation over {b['rows']}, {b['rate_hz']:.4g} Hz, tau {b['tau_s'][0]:.3g} to "
               f"{b['tau_s'][-1]:.3g} s; terms fitted with the estimates' covariance, reported where beyond "
               f"{allan_fit.SEEN:g} std")
        for a, ax in b["axes"].items():
            if "stuck" in ax:
                yield f"  {a}: {ax['stuck']}"
                continue
            yield f"  {a}: " + ", ".join(f"{t['name']} {_term_text(t)}" for t in ax["sheet"].values())
    for _, text in verdicts(report):
        yield text
    yield from skipped_sensors([s for s in ("acc", "gyro") if s in report])
    yield "next: " + next_step(report, written)[0]


def _axes_of(axes, status, k) -> list[str]:
    return [a for a, ax in axes.items() if "stuck" not in ax and ax["sheet"][k]["status"] == status]


def verdicts(report) -> list[tuple[bool, str]]:
    """Per sensor (ok, the verdict): an axis stuck, else the white noise, the terms seen beyond it and
    those not seen (each with its 95 % bound in the table) or the record too short to tell."""
    out = []
    for sensor in ("acc", "gyro"):
        if sensor not in report:
            continue
        axes = report[sensor]["axes"]
        stuck = [f"{a} {ax['stuck']}" for a, ax in axes.items() if "stuck" in ax]
        n = [axes[a]["sheet"]["N"] for a in _axes_of(axes, "seen", "N")]
        text = (f"{sensor}: {SHEET[sensor]['N'][0]} " + (f"{min(t['value'] for t in n):.3g} to {max(t['value'] for t in n):.3g} "
                f"{n[0]['unit']}" if n else "not seen") + " on " + ", ".join(_axes_of(axes, "seen", "N") or ["no axis"]))
        for status, say in (("seen", "seen beyond it"), ("not seen", "not seen (95 % bounds below)"),
                            ("too short", "the record too short to tell")):
            terms = [f"{SHEET[sensor][k][0]} ({', '.join(_axes_of(axes, status, k))})" for k in SHEET[sensor]
                     if k != "N" and _axes_of(axes, status, k)]
            text += f"; {say}: {', '.join(terms)}" if terms else ""
        out.append((not stuck and len(n) == len(axes), text + "".join(f"; STUCK: {x}" for x in stuck)))
    if report.get("temperature", {}).get("warning"):
        out.append((False, "WARNING: " + report["temperature"]["warning"]))
    return out


def next_step(report, written=None) -> tuple[str, list[str]]:
    """(the command after `simucal noise`, why): Kalibr's imu.yaml where the record gives it, else what to record;
    written ({"-o": noise.json, "--kalibr": imu.yaml}) once imu.yaml is written: a calibration weighed by the
    noise curves (calibrate --noise), not the command just run."""
    missing = kalibr_missing(report)
    if written and written.get("--kalibr"):
        return (f"simucal calibrate TEST_SET --noise {written['-o']} -o calibration.json",
                [f"{written['--kalibr']} is written: Kalibr reads it as its --imu file"])
    if not missing:
        return f"simucal noise {report['data']} -o noise.json --kalibr imu.yaml", []
    return ("simucal noise LONGER_STILL_RECORDING -o noise.json --html noise.html",
            ["Kalibr's imu.yaml would lack " + "; ".join(missing)])


def html_page(report, units: str = "spec", written=None) -> str:
    """A self-contained page: the verdicts and the next step (as the console prints them), then each
    sensor's Allan deviation with its interval and the fitted terms, in one unit system per table (the
    spec's data-sheet units, or SI); written: as next_step's, so that the page's next step is the console's."""
    import html as _html

    from simucal.io.units import in_units
    from simucal.report import units as shown
    from simucal.report.page import page, plt, png
    parts, g = [], shown.gravity_of(report.get("data"))
    sheets = shown.noise_in(report, units, g)  # the tables' and verdicts' numbers; the plot's scaled below
    for sensor in ("acc", "gyro"):
        if sensor not in report:
            continue
        b = report[sensor]
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        _, scale, adev_unit = SHEET[sensor]["B"]  # the bias instability's unit: the table's (ug, deg/h)
        if units != "spec":
            scale, adev_unit = in_units(1.0, b["unit"], units, g)
        for (a, axd), color in zip(b["axes"].items(), ("C0", "C1", "C2")):
            if "stuck" in axd:
                continue
            t, r = np.array(axd["tau_s"]), np.array(axd["rel_err"])
            s, fit = np.array(axd["adev"]) * scale, allan_deviation(axd["terms"], t) * scale
            ax.fill_between(t, fit * (1 - r), fit * (1 + r), color=color, alpha=0.2)
            ax.loglog(t, s, "o", ms=3, color=color, label=f"{a}")
            ax.loglog(t, fit, "-", color=color, lw=1)
        ax.set(xlabel="tau (s)", ylabel=f"Allan deviation ({adev_unit})",
               title=f"{sensor}: points, the fit of the terms seen and its 68 % band")
        ax.legend(fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        axes = sheets[sensor]["axes"]
        head = "".join(f"<th>{name} ({_html.escape(in_units(1.0, unit, units, g)[1])})</th>"
                       for name, _, unit in SHEET[sensor].values())
        rows = "".join(f"<tr><td>{a}</td>" + (f"<td colspan=5>{_html.escape(axd['stuck'])}</td>" if "stuck" in axd else
                       "".join(f"<td>{_term_text(t, html=True)}</td>" for t in axd["sheet"].values())) + "</tr>"
                       for a, axd in axes.items())
        parts.append(f"<h2>{sensor}</h2>{png(fig)}<table><tr><th>axis</th>{head}</tr>"
                     f"{rows}</table><p>Terms fitted by generalised least squares with the covariance of the "
                     f"overlapping estimates; a term is shown where beyond {allan_fit.SEEN:g} std, otherwise "
                     "with its 95 % upper bound.</p>")
    cmd, notes = next_step(report, written)
    return page("simucal noise", f"Noise of {report['data']}", verdicts(sheets), cmd, notes, parts)
