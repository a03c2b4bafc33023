"""White-noise level from the data itself, and the noise of a mean from an Allan curve."""
from typing import Any

import numpy as np

from simucal.errors import CalibrationError
from simucal.io import records

TERMS = ("Q", "N", "B", "K", "R")
# each IEEE 952 term's column in sigma^2(tau) (Table C.1): quantisation, angle/velocity random walk,
# bias instability, rate random walk, rate ramp
COLUMNS = {"Q": lambda t: 3.0 / t ** 2, "N": lambda t: 1.0 / t, "B": lambda t: np.full_like(t, 2 * np.log(2) / np.pi),
           "K": lambda t: t / 3.0, "R": lambda t: t ** 2 / 2.0}


def white_noise_var(x, ddof=0):
    """Per-axis variance of the white noise in rows x (n, k), from first differences:
    var(x[i+1] - x[i]) / 2. Blind to slowly varying signals (motion, a turning Earth rate)."""
    return np.var(np.diff(x, axis=0), axis=0, ddof=ddof) / 2


def mean_and_sigma(x, stated, varying=False, angle_rad=None):
    """Mean of a segment's rows and the std of that mean.

    Several rows: from their scatter, with the lag-1 autocorrelation taken into account
    (effective sample count). A rate run (varying=True) holds a deterministic signal, its
    inputs turning in the body at the outer angle: given each row's outer angle (angle_rad),
    the rows are fitted by a constant and the angle's first HARMONICS (turning_mean), whose
    constant is the mean over whole revolutions whatever the rows span and whose residuals
    are the noise; without the angles, first differences, which remove a signal that
    changes little from row to row. One row: the stated noise, if any, else NaN
    (lack_of_fit.fit_with_noise then estimates a variance component for such rows).
    """
    n = len(x)
    if varying and angle_rad is not None and n > 2 * (2 * HARMONICS + 1):
        return turning_mean(x, angle_rad)
    if n >= 3 and varying:
        return x.mean(0), np.sqrt(white_noise_var(x, ddof=1) / n)
    if n >= 3:
        rows = axis_rows(x)
        mean = rows.sum(1) / n
        d = rows - mean[:, None]
        ss = row_dots(d, d)
        return mean, np.sqrt(ss / (n - 1) / _effective_count(d, ss))
    return x.mean(0), np.full(3, np.nan if stated is None else stated / np.sqrt(n))


def axis_rows(x) -> np.ndarray:
    """x (n, k) as k contiguous rows (k, n): a segment's sums along its rows are 5-15x faster than numpy's
    reductions down a few columns (9,040 rows x 3: the mean 7 against 123 us, a sum of squares 8 against
    45 us; 172 segments a sensor in the 400 Hz set), for a copy of 9 us. The same sums to round-off."""
    return np.ascontiguousarray(np.asarray(x, float).T)


def row_dots(a, b) -> np.ndarray:
    """Per row, the dot product of a and b (k, n)."""
    return np.einsum("ij,ij->i", a, b)


HARMONICS = 3  # of the outer angle in a rate run: the turning inputs, and their squares and cubes in a model


def turning_mean(x, angle_rad):
    """(mean over whole revolutions, its std) of a rate run's rows x (n, 3) at outer angles angle_rad
    (n,): least squares on [1, cos k a, sin k a] (k = 1..HARMONICS). Every input of the run turns
    with the outer angle, so a model's output there is a sum of these harmonics, and the constant is
    its average over a revolution (what the norm fit takes) even where the rows span a revolution
    only in part (a sample count that is not a whole number per revolution); its variance is the
    residuals' (n - 2 HARMONICS - 1 dof) times (X^T X)^-1_00, for correlated noise times
    (1 + r1) / (1 - r1) (lag-1 autocorrelation r1 of the residuals)."""
    a = np.asarray(angle_rad, float)
    rows = axis_rows(x)
    Xt = np.empty((2 * HARMONICS + 1, len(a)))  # the basis as rows: each harmonic written contiguously
    Xt[0] = 1.0
    cos, sin = Xt[1:HARMONICS + 1], Xt[HARMONICS + 1:]
    np.cos(a, out=cos[0])
    np.sin(a, out=sin[0])
    two_cos = 2 * cos[0]
    for k in range(1, HARMONICS):  # cos (k+1)a = 2 cos a cos ka - cos (k-1)a, and the same for sin: 2 trig passes
        np.multiply(two_cos, cos[k - 1], out=cos[k])
        cos[k] -= cos[k - 2] if k > 1 else Xt[0]
        np.multiply(two_cos, sin[k - 1], out=sin[k])
        if k > 1:
            sin[k] -= sin[k - 2]
    G_inv = np.linalg.inv(Xt @ Xt.T)  # 7 x 7 and well conditioned (harmonics over most of a revolution or more):
    coef = G_inv @ (Xt @ rows.T)      # the normal equations, a tenth of lstsq's SVD of the n x 7 rows
    res = rows - coef.T @ Xt          # (3, n)
    ss = row_dots(res, res)
    return coef[0], np.sqrt(ss / (len(a) - len(Xt)) * G_inv[0, 0] * len(a) / _effective_count(res, ss))


def _effective_count(d, ss):
    """n (1 - r1) / (1 + r1) of rows d (k, n) about their mean (ss: their sums of squares), per axis:
    the count of independent rows that gives their mean the same variance under lag-1 autocorrelation r1."""
    r1 = np.clip(row_dots(d[:, 1:], d[:, :-1]) / np.maximum(ss, 1e-300), -0.9, 0.99)
    return np.maximum(d.shape[1] * (1 - r1) / (1 + r1), 1.0)


def quantization_step(x, whole=None):
    """Per column, the smallest step between distinct values of x (n, k): the LSB of
    quantised data (tiny for unquantised floats). A column that is constant in x (a
    rest quieter than one LSB) takes it from the same column of `whole` (the stream).
    When the noise is below it, the noise a still sensor shows is not the noise a
    moving one has (q^2/12 per sample), and averaging a still sensor does not shrink
    its error below about q/sqrt(12)."""
    steps = []
    for j, col in enumerate(np.asarray(x, float).T):
        d = np.diff(np.unique(col))
        if not np.any(d > 0) and whole is not None:
            d = np.diff(np.unique(np.asarray(whole, float)[:, j]))
        steps.append(float(d[d > 0].min()) if np.any(d > 0) else 0.0)
    return np.array(steps)


def moving_sample_var(rest, whole=None):
    """Per-axis variance of one sample's noise once the sensor moves, from its still rows rest (n, k): their
    white noise, at least the quantisation's q^2/12 (quantization_step: a rest quieter than one LSB reads
    constant, while a moving sensor's samples round by up to q/2); whole: the stream, for q."""
    return np.maximum(white_noise_var(rest), quantization_step(rest, whole) ** 2 / 12)


UNITS = {"acc": "g", "gyro": "deg/h"}  # the unit of a report's terms, as `simucal noise` writes them
REWRITE = "write it again with simucal noise STILL_RECORDING -o noise.json"


def read_report(path) -> records.JSONObject:
    """A noise.json of `simucal noise`, checked entry by entry before any number is used: per sensor its
    unit (g, deg/h), its tau_s (finite, positive) and per axis x, y, z the five terms Q N B K R, each a
    finite number >= 0, not all zero. Refused in one line naming the file, the entry and the fix."""
    import json
    from pathlib import Path

    from simucal.io.text_files import unique_keys

    def bad(entry, what):
        return CalibrationError(f"{path}: {entry} {what}; {REWRITE}")
    p = Path(path)
    if p.is_dir():
        raise CalibrationError(f"{path}: a folder, where a noise.json of simucal noise is expected")
    try:
        rep = json.loads(p.read_text(), object_pairs_hook=unique_keys)  # a term twice: which one is meant?
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as e:  # ValueError: JSON's, a 5000-digit int
        raise CalibrationError(f"{path}: not a readable noise report ({type(e).__name__}: "
                               f"{str(e)[:120] or 'nested too deep'}); {REWRITE}") from None
    if not isinstance(rep, dict) or rep.get("format") != "simucal.noise/1":
        raise CalibrationError(f"{path}: not a report of simucal noise (format simucal.noise/1); {REWRITE}")
    if not any(s in rep for s in UNITS):
        raise bad("the report", "holds neither acc nor gyro")
    for sensor in (s for s in UNITS if s in rep):
        block = rep[sensor]
        if not isinstance(block, dict):
            raise bad(sensor, f"is a {type(block).__name__}, not an object with unit, tau_s and axes")
        if block.get("unit") != UNITS[sensor]:
            raise bad(f"{sensor}.unit", f"is {block.get('unit')!r}, not {UNITS[sensor]!r} (the terms must be in "
                      f"{UNITS[sensor]}, as simucal noise writes them)")
        tau = block.get("tau_s")
        if not isinstance(tau, list) or not tau or not all(_number(t) and t > 0 for t in tau):
            raise bad(f"{sensor}.tau_s", "is not a list of positive numbers (seconds)")
        axes = block.get("axes")
        for a in "xyz":
            if not isinstance(axes, dict) or not isinstance(axes.get(a), dict):
                raise bad(f"{sensor}.axes.{a}", "is missing (every axis x, y, z needs its terms)")
            if "stuck" in axes[a]:  # a dead channel in the recording: load_curves names it
                continue
            terms = axes[a].get("terms")
            if not isinstance(terms, dict) or set(terms) != set(TERMS):
                raise bad(f"{sensor}.axes.{a}.terms", f"must hold exactly the terms {', '.join(TERMS)}")
            for k in TERMS:
                if not _number(terms[k]) or terms[k] < 0:
                    raise bad(f"{sensor}.axes.{a}.terms.{k}", f"is {terms[k]!r}: a term is a finite number >= 0 "
                              f"(in {UNITS[sensor]} times s^a)")
            if not any(terms.values()):
                raise bad(f"{sensor}.axes.{a}.terms", "are all zero: a sensor without noise is no measurement")
    return rep


def _number(x) -> bool:
    """A finite JSON number (not a string, a bool, NaN or infinity)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


def load_curves(path) -> "dict[str, Curve]":
    """{sensor: curve} from a noise.json of `simucal noise` (read_report): curve(tau_s) is the std of a
    tau-long mean per axis (3,), from the fitted IEEE 952 terms, sigma(tau) = sqrt(sum_k term_k^2
    column_k(tau)) in g or deg/h: what `calibrate --noise` takes as the noise of each segment's mean.
    Beyond the longest tau measured (curve.tau_max_s) a short record's terms of long averages (bias
    instability, random walk, ramp) are fitted from its last few taus, often by chance: there the curve
    goes on as white noise, sigma(tau_max) sqrt(tau_max / tau), but for the long terms measured MEASURED
    stds from 0, which follow their own law; calibrate says so. curve.source names the file."""
    rep: dict[str, Any] = read_report(path)
    out: dict[str, Curve] = {}
    for sensor in ("acc", "gyro"):
        if sensor in rep:
            axes = [rep[sensor]["axes"][a] for a in "xyz"]
            stuck = [f"{sensor} {a}" for a, ax in zip("xyz", axes) if "stuck" in ax]
            if stuck:
                raise CalibrationError(f"{path}: {', '.join(stuck)} stuck or dead in the still recording (no noise "
                                       "terms): its noise cannot stand for the unit's; record it again or drop --noise")
            out[sensor] = Curve(axes, float(max(rep[sensor]["tau_s"])), str(path))
    return out


class Curve:
    """One sensor's curve of load_curves: curve(tau_s), the std of a tau-long mean per axis; tau_max_s,
    the longest tau measured; source, the noise.json it was read from."""

    def __init__(self, axes: list[dict], tau_max_s: float, source: str):
        self.axes, self.tau_max_s, self.source = axes, tau_max_s, source

    def __call__(self, tau_s) -> np.ndarray:
        t = np.atleast_1d(np.asarray(tau_s, float))
        at = np.minimum(t, self.tau_max_s)
        var = []
        for ax in self.axes:
            kept = {k: v if k in _measured_long(ax) else 0.0 for k, v in ax["terms"].items()}
            var.append(allan_deviation(ax["terms"], at) ** 2 * at / t
                       + allan_deviation(kept, t) ** 2 - allan_deviation(kept, at) ** 2 * at / t)
        return np.sqrt(np.array(var).T).squeeze()


LONG_TERMS = ("B", "K", "R")  # the terms of long averages
MEASURED = 10.0  # a long-average term carried past the last tau only where it is this many stds from 0


def _measured_long(axis: dict) -> set:
    """The long-average terms of one axis of a noise report that stand MEASURED stds from zero."""
    sheet = axis.get("sheet")
    sheet = sheet if isinstance(sheet, dict) else {}
    rows = {k: sheet[k] for k in LONG_TERMS if isinstance(sheet.get(k), dict)}  # a damaged sheet measures nothing
    return {k for k, r in rows.items() if _number(r.get("std")) and _number(r.get("value")) and r["std"] > 0
            and r["value"] >= MEASURED * r["std"]}


def allan_deviation(terms: dict, tau_s) -> np.ndarray:
    """sigma(tau) of the IEEE 952 terms {Q, N, B, K, R} (in a sensor's unit times s^a), at tau_s."""
    t = np.asarray(tau_s, float)
    return np.sqrt(sum(terms[k] ** 2 * COLUMNS[k](t) for k in TERMS))
