"""The Allan computation of `simucal noise`: the overlapping Allan variance of still stretches, its tau grid,
and each axis's IEEE 952 noise terms (the terms the data show).

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

from typing import TypedDict, cast

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit import allan_fit
from simucal.fit.noise import TERMS, allan_deviation

MIN_CLUSTERS = 9  # the longest tau keeps this many independent clusters (relative error <= 25 %)


class SheetTerm(TypedDict, total=False):
    """One noise term of an axis in a data sheet's units (axis_from_avar)."""
    name: str                         # the term's name (angle random walk, ...)
    unit: str                         # the data sheet's unit of it
    value: float                      # its value, 0 where not seen
    std: float | None                 # its std where seen
    status: str                       # seen, not seen or too short
    bound_95: float                   # not seen: its 95 % upper bound
    needs_s: float                    # too short: the record's length that would test it, s


class AllanAxisFit(TypedDict):
    """The final model of an axis's Allan variance (allan_fit.select)."""
    chi2: float                       # the GLS fit's, on dof
    dof: int                          # the taus less the terms fitted
    squares: dict[str, tuple[float, float]]  # each term's square and its std (the sensor's unit^2 times s^2a)


class AxisNoise(TypedDict, total=False):
    """One axis of the noise report (axis_report; module doc)."""
    stuck: str                        # a channel that never changes: why it has no terms
    adev: list[float]                 # the Allan deviation at tau_s (the sensor's unit)
    tau_s: list[float]                # the cluster times, s
    rel_err: list[float]              # the model's 68 % band, relative to the deviation
    terms: dict[str, float]           # Q N B K R, 0 where not seen (the sensor's unit times s^a)
    bounds: dict[str, float]          # each term's 95 % upper bound where not seen
    sheet: dict[str, SheetTerm]       # each term in a data sheet's units
    fit: AllanAxisFit                 # the final model of the Allan variance


class SensorNoise(TypedDict):
    """One sensor's block of the noise report (sensor_report)."""
    unit: str                         # g or deg/h
    tau_s: list[float]                # the cluster times, s
    rate_hz: float                    # the samples' rate
    rows: str                         # the rows characterised, in words
    axes: dict[str, AxisNoise]        # x, y, z

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


def seconds_for(n_taus: int, dt: float) -> float:
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
                               f"Allan fit: its {need} taus need {seconds_for(need, dt):.4g} s; record longer")
    if tau_max_s is None:
        return taus(n)
    if n < MIN_CLUSTERS * tau_max_s / dt:
        raise CalibrationError(f"{where}: the longest still stretch is {n * dt:.4g} s; a tau of {tau_max_s:g} s needs "
                               f"{MIN_CLUSTERS} clusters of it ({MIN_CLUSTERS * tau_max_s:.4g} s): "
                               f"record longer, or ask for --tau-max-s {n * dt / MIN_CLUSTERS:.3g} at most")
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


def axis_report(sensor, y, dt, m, mats, unit) -> AxisNoise:
    """One axis of the report: its Allan deviation, the model's 68 % interval, the terms seen and
    the bounds of those not seen (module doc); "fit": the final model's chi2, dof and its terms'
    squares (x, std) in the fitted units (Q^2, N^2, ... of `terms`), below zero where noise puts them."""
    values = np.concatenate(y)
    return axis_from_avar(sensor, allan_variance(y, dt, m)[0], stuck(values.min(), values.max(), values[0],
                                                                      len(values), unit), dt, m, mats)


def axis_from_avar(sensor, avar, stuck_why, dt, m, mats) -> AxisNoise:
    """axis_report from the Allan variance at the cluster sizes m (a stream read chunk by chunk:
    characterise_folder)."""
    tau = m * dt
    if stuck_why:
        return {"stuck": stuck_why, "adev": np.sqrt(avar).tolist(), "tau_s": tau.tolist()}
    fit = allan_fit.select(tau, avar, mats)
    terms = {k: (v[0] if v else 0.0) for k, v in fit["terms"].items()}
    model = allan_deviation(terms, tau) ** 2
    sheet: dict[str, SheetTerm] = {}
    for k in TERMS:
        name, factor, unit_k = SHEET[sensor][k]
        entry = {"name": name, "unit": unit_k, "value": terms[k] * factor, "std": None}
        if fit["terms"][k]:
            entry.update(status="seen", std=cast("tuple[float, float]", fit["terms"][k])[1] * factor)
        elif k in fit["bounds"]:
            entry.update(status="not seen", bound_95=fit["bounds"][k] * factor)
        else:
            entry.update(status="too short", needs_s=seconds_for(fit["needs_taus"], dt))
        sheet[k] = cast(SheetTerm, entry)
    return {"adev": np.sqrt(avar).tolist(), "rel_err": (np.sqrt(np.diag(fit["cov"])) / (2 * model)).tolist(),
            "tau_s": tau.tolist(), "terms": terms, "bounds": fit["bounds"], "sheet": sheet,
            "fit": {"chi2": fit["chi2"], "dof": fit["dof"], "squares": fit["squares"]}}


UNIT = {"gyro": "deg/h", "acc": "g"}


def sensor_report(sensor, dt, m, where, axes) -> SensorNoise:
    """One sensor's block of the report, around its axes' (axis_report)."""
    return {"unit": UNIT[sensor], "tau_s": (m * dt).tolist(), "rate_hz": 1.0 / dt, "rows": where, "axes": axes}


