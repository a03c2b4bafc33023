"""White-noise level from the data itself, and the noise of a mean from an Allan curve."""
import numpy as np

from simucal.errors import CalibrationError

TERMS = ("Q", "N", "B", "K", "R")
# each IEEE 952 term's column in sigma^2(tau) (Table C.1): quantisation, angle/velocity random walk,
# bias instability, rate random walk, rate ramp
COLUMNS = {"Q": lambda t: 3.0 / t ** 2, "N": lambda t: 1.0 / t, "B": lambda t: np.full_like(t, 2 * np.log(2) / np.pi),
           "K": lambda t: t / 3.0, "R": lambda t: t ** 2 / 2.0}


def white_noise_var(x, ddof=0):
    """Per-axis variance of the white noise in rows x (n, k), from first differences:
    var(x[i+1] - x[i]) / 2. Blind to slowly varying signals (motion, a turning Earth rate)."""
    return np.var(np.diff(x, axis=0), axis=0, ddof=ddof) / 2


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


def load_curves(path) -> dict:
    """{sensor: curve} from a noise.json of `simucal noise`: curve(tau_s) is the std of a tau-long mean
    per axis (3,), from the fitted IEEE 952 terms, sigma(tau) = sqrt(sum_k term_k^2 column_k(tau)) in
    g or deg/h: what `calibrate --noise` takes as the noise of each segment's mean. Beyond the longest
    tau measured (curve.tau_max_s) a short record's terms of long averages (bias instability, random
    walk, ramp) are fitted from its last few taus, often by chance: there the curve goes on as white
    noise, sigma(tau_max) sqrt(tau_max / tau), but for the long terms measured MEASURED stds from 0,
    which follow their own law; calibrate says so."""
    import json
    from pathlib import Path
    try:
        rep = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CalibrationError(f"{path}: not a readable noise report ({e})") from None
    if not isinstance(rep, dict) or rep.get("format") != "simucal.noise/1":
        raise CalibrationError(f"{path}: not a report of simucal noise (format simucal.noise/1); write one with "
                               "simucal noise STILL_RECORDING -o noise.json")
    out = {}
    for sensor in ("acc", "gyro"):
        if sensor in rep:
            axes = [rep[sensor]["axes"][a] for a in "xyz"]
            stuck = [f"{sensor} {a}" for a, ax in zip("xyz", axes) if "stuck" in ax]
            if stuck:
                raise CalibrationError(f"{path}: {', '.join(stuck)} stuck or dead in the still recording (no noise "
                                       "terms): its noise cannot stand for the unit's; record it again or drop --noise")
            tau_max = float(max(rep[sensor]["tau_s"]))

            def curve(tau_s, axes=axes, tau_max=tau_max):
                t = np.atleast_1d(np.asarray(tau_s, float))
                at = np.minimum(t, tau_max)
                var = []
                for ax in axes:
                    kept = {k: v if k in _measured_long(ax) else 0.0 for k, v in ax["terms"].items()}
                    var.append(allan_deviation(ax["terms"], at) ** 2 * at / t
                               + allan_deviation(kept, t) ** 2 - allan_deviation(kept, at) ** 2 * at / t)
                return np.sqrt(np.array(var).T).squeeze()
            curve.tau_max_s = tau_max
            out[sensor] = curve
    return out


LONG_TERMS = ("B", "K", "R")  # the terms of long averages
MEASURED = 10.0  # a long-average term carried past the last tau only where it is this many stds from 0


def _measured_long(axis: dict) -> set:
    """The long-average terms of one axis of a noise report that stand MEASURED stds from zero."""
    sheet = axis.get("sheet", {})
    return {k for k in LONG_TERMS if sheet.get(k, {}).get("std") and sheet[k]["value"] >= MEASURED * sheet[k]["std"]}


def allan_deviation(terms: dict, tau_s) -> np.ndarray:
    """sigma(tau) of the IEEE 952 terms {Q, N, B, K, R} (in a sensor's unit times s^a), at tau_s."""
    t = np.asarray(tau_s, float)
    return np.sqrt(sum(terms[k] ** 2 * COLUMNS[k](t) for k in TERMS))
