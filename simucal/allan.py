"""`simucal noise`: Allan deviation of a static recording and the IEEE 952 noise terms (issue 26, item 3).

Overlapping Allan variance of a rate y sampled every dt (IEEE 952-1997, Annex C, eq. C.2, with
overlapping clusters as allantools' oadev computes it): with theta the integrated output
(theta_k = dt * sum_{i<k} y_i) and tau = m dt,

    sigma^2(tau) = sum_k (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2 / (2 tau^2 (N - 2m)).

Several static stretches (the static segments of a raw turntable set) are pooled: their sums of
squares and their counts add. Computed with cumulative sums, one pass per tau (vectorised); the
tests check it against allantools.oadev to 1e-12. Tau runs over about 10 values per decade, up to
a ninth of the longest stretch, where the clusters still number 9 or more.

Confidence: the relative error of sigma(tau) is 1 / sqrt(2 (K - 1)), K = N / m independent
clusters (IEEE 952 eq. C.5); sigma +- that fraction is the 68 % interval drawn and used as weight.

The terms (IEEE 952 Table C.1): sigma^2(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln 2 / pi) B^2
+ K^2 tau / 3 + R^2 tau^2 / 2, linear in the squares, fitted by weighted non-negative least squares
(scipy.optimize.nnls; weight 1 / (2 rel. error sigma^2)). Q: quantisation, N: angle (velocity)
random walk, B: bias instability (the flat floor's coefficient, 0.664 B), K: rate random walk, R:
rate ramp. A term the curve does not show is 0; its std comes from the weighted fit's covariance
of the terms that are not zero (the std of N from that of N^2: N^2 +- s gives N +- s / (2 N)).

Units: gyro rates in deg/h, accelerometer outputs in g, tau in s; each term also in the units a
data sheet uses (deg/sqrt(h), ug/sqrt(Hz), deg/h, ...), and for Kalibr's imu.yaml in SI.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from simucal.errors import CalibrationError
from simucal.fit.noise import COLUMNS, TERMS, allan_deviation
from simucal.io import units

MIN_CLUSTERS = 9  # the longest tau keeps this many independent clusters (relative error <= 25 %)
G0 = units.DEFAULT_GRAVITY  # m/s^2 per g: Kalibr's SI, not the site's gravity
RAD_PER_DEG = np.pi / 180.0

# (name, factor from the fitted unit, unit) of each term for a data sheet; the fitted units are
# sigma's (deg/h, g) times s^a: Q [.s], N [.sqrt(s)], B [.], K [./sqrt(s)], R [./s]
SHEET = {"gyro": {"Q": ("quantisation", 1.0, "arcsec"), "N": ("angle random walk", 1 / 60.0, "deg/sqrt(h)"),
                  "B": ("bias instability", 1.0, "deg/h"), "K": ("rate random walk", 60.0, "deg/h/sqrt(h)"),
                  "R": ("rate ramp", 3600.0, "deg/h/h")},
         "acc": {"Q": ("quantisation", G0, "m/s"), "N": ("velocity random walk", 1e6, "ug/sqrt(Hz)"),
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


def fit_terms(tau, adev, rel_err) -> dict:
    """The IEEE 952 terms (module doc) fitted to one Allan deviation curve: {term: (value, std)}
    in sigma's unit times s^a."""
    A = np.column_stack([COLUMNS[k](tau) for k in TERMS])
    w = 1.0 / (2 * rel_err * adev ** 2)  # sigma^2's relative error is twice sigma's
    coef, _ = nnls(A * w[:, None], adev ** 2 * w)
    on = coef > 0
    cov = np.zeros((len(TERMS), len(TERMS)))
    if on.any():
        Aw = A[:, on] * w[:, None]
        resid = (A @ coef - adev ** 2) * w
        dof = max(len(tau) - int(on.sum()), 1)
        scale = max(float(resid @ resid) / dof, 1.0)  # the curve's points are correlated: never below 1
        cov[np.ix_(on, on)] = np.linalg.pinv(Aw.T @ Aw) * scale
    out = {}
    for j, k in enumerate(TERMS):
        value = float(np.sqrt(coef[j]))
        out[k] = (value, float(np.sqrt(cov[j, j]) / (2 * value)) if value > 0 else None)
    return out


def still_stretches(ms, sensor) -> tuple[list[np.ndarray], float, str]:
    """(stretches (rows, 3), dt, where): the whole stream, or each static segment of a raw
    turntable set (three rows or more), in deg/h or g."""
    data = ms.gyro_dph() if sensor == "gyro" else ms.acc_g()
    t = ms.samples["t_s"]
    if ms.segments is None:
        pieces, where = [np.arange(len(t))], "the whole stream"
    else:
        seg = ms.samples["segment"]
        pieces = [np.nonzero(seg == s.segment)[0] for s in ms.segments if s.kind == "static"]
        pieces = [p for p in pieces if len(p) >= 3]
        where = f"{len(pieces)} static segments, pooled"
        if not pieces:
            raise CalibrationError(f"{ms.path}: no static segment holds raw rows (3 or more): the Allan deviation "
                                   "needs the samples, not their averages")
    dts = np.concatenate([np.diff(t[p]) for p in pieces])
    dt = float(np.median(dts))
    # a logger's timestamps jitter around the sample clock (taken as the median step); a gap is lost samples
    if dt <= 0 or np.max(np.abs(dts - dt)) > 0.5 * dt:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: t_s has gaps within the still stretches (steps "
                               f"{dts.min():.4g} to {dts.max():.4g} s, median {dt:.4g}): the Allan deviation needs "
                               "every sample of a constant rate; cut the recording at the gaps")
    return [data[p] for p in pieces], dt, where


def check_still(ms, dt):
    """Refuse a stream that moves: its 1-s mean specific force may wander by noise, not turn by 0.05 g."""
    if ms.segments is not None or not ms.has_acc:
        return
    f = ms.acc_g()
    k = max(int(round(1.0 / dt)), 1)
    tilt = np.linalg.norm(f[: len(f) // k * k].reshape(-1, k, 3).mean(1) - f.mean(0), axis=1)
    if len(tilt) > 1 and np.max(tilt) > 0.05:
        raise CalibrationError(f"{ms.path}: the unit moves during the recording (its 1-s mean specific force turns "
                               f"by {np.max(tilt):.2g} g): the Allan deviation needs a still unit; record it at rest")


def _cluster_sizes(stretches, dt, tau_max_s, where) -> np.ndarray:
    """taus(), up to tau_max_s where asked; refused where the longest stretch is too short for it."""
    n = max(len(s) for s in stretches)
    if tau_max_s is None:
        return taus(n)
    if n < MIN_CLUSTERS * tau_max_s / dt:
        raise CalibrationError(f"{where}: the longest still stretch is {n * dt:.4g} s; a tau of {tau_max_s:g} s needs "
                               f"{MIN_CLUSTERS} clusters of it ({MIN_CLUSTERS * tau_max_s:.4g} s): record longer, or ask "
                               f"for --tau-max-s {n * dt / MIN_CLUSTERS:.3g} at most")
    return taus(n, m_max=tau_max_s / dt)


def characterise(ms, tau_max_s=None) -> dict:
    """The report of `simucal noise` (module doc): per sensor and axis, the Allan deviation with its
    68 % interval and the fitted terms in the sensor's units and a data sheet's; tau up to tau_max_s
    (default a ninth of the longest still stretch)."""
    out = {"format": "simucal.noise/1", "data": str(ms.path)}
    for sensor, has in (("acc", ms.has_acc), ("gyro", ms.has_gyro)):
        if not has:
            continue
        stretches, dt, where = still_stretches(ms, sensor)
        check_still(ms, dt)
        m = _cluster_sizes(stretches, dt, tau_max_s, ms.path / "samples.csv")
        tau = m * dt
        block = {"unit": "deg/h" if sensor == "gyro" else "g", "tau_s": tau.tolist(), "rate_hz": 1.0 / dt,
                 "rows": where, "axes": {}}
        for j, a in enumerate("xyz"):
            avar, counts = allan_variance([s[:, j] for s in stretches], dt, m)
            ok = np.isfinite(avar) & (counts > 0)
            adev = np.sqrt(avar[ok])
            rel = 1.0 / np.sqrt(2 * np.maximum(counts[ok] / m[ok] - 1, 1))
            terms = fit_terms(tau[ok], adev, rel)
            sheet = {k: {"name": SHEET[sensor][k][0], "value": v * SHEET[sensor][k][1],
                         "std": None if e is None else e * SHEET[sensor][k][1], "unit": SHEET[sensor][k][2]}
                     for k, (v, e) in terms.items()}
            block["axes"][a] = {"adev": adev.tolist(), "rel_err": rel.tolist(), "tau_s": tau[ok].tolist(),
                                "terms": {k: v for k, (v, _) in terms.items()}, "sheet": sheet}
        out[sensor] = block
    if "acc" not in out and "gyro" not in out:
        raise CalibrationError(f"{ms.path}: no sensor columns to characterise")
    return out


def _random_walk_or_bound(axis) -> float:
    """K, or where the curve shows none (a record too short for it) the largest K it allows:
    K^2 tau / 3 <= sigma^2 at the longest tau. Kalibr needs a random walk above zero."""
    if axis["terms"]["K"] > 0:
        return axis["terms"]["K"]
    t, s = axis["tau_s"][-1], axis["adev"][-1]
    return float(np.sqrt(3 * s ** 2 / t))


def kalibr_yaml(report) -> str:
    """Kalibr's imu.yaml (continuous-time densities in SI, the largest over the three axes)."""
    lines = ["# written by simucal noise from " + report["data"],
             "# white noise N and random walk K of the Allan fit; a random walk the record is too short to",
             "# show is given as the largest value its longest tau allows"]
    rate = None
    for sensor, key, to_si in (("acc", "accelerometer", G0), ("gyro", "gyroscope", RAD_PER_DEG / units.DPH_PER_DPS)):
        if sensor not in report:
            continue
        ax = report[sensor]["axes"].values()
        lines.append(f"{key}_noise_density: {max(a['terms']['N'] for a in ax) * to_si:.6e}")
        lines.append(f"{key}_random_walk: {max(_random_walk_or_bound(a) for a in ax) * to_si:.6e}")
        rate = report[sensor]["rate_hz"]
    lines.append(f"rostopic: /imu0\nupdate_rate: {rate:.6g}")
    return "\n".join(lines) + "\n"


def lines(report):
    """The console: each axis's terms in a data sheet's units."""
    for sensor in ("acc", "gyro"):
        if sensor not in report:
            continue
        b = report[sensor]
        yield (f"{sensor}: Allan deviation over {b['rows']}, {b['rate_hz']:.4g} Hz, tau {b['tau_s'][0]:.3g} to "
               f"{b['tau_s'][-1]:.3g} s")
        for a, ax in b["axes"].items():
            yield f"  {a}: " + ", ".join(
                f"{t['name']} {t['value']:.3g}" + (f" +- {t['std']:.2g}" if t["std"] else "") + f" {t['unit']}"
                for t in ax["sheet"].values() if t["value"] > 0)


def _cell(term) -> str:
    return f"{term['value']:.3g}" + (f" &plusmn; {term['std']:.2g}" if term["std"] else "")


def html_page(report) -> str:
    """A self-contained page: each sensor's Allan deviation with its interval and the fitted terms."""
    import html as _html

    from simucal.report.html import _png, plt
    parts = [f"<!doctype html><meta charset=utf-8><title>simucal noise</title><h1>Noise of "
             f"{_html.escape(report['data'])}</h1>"]
    for sensor in ("acc", "gyro"):
        if sensor not in report:
            continue
        b = report[sensor]
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        for (a, axd), color in zip(b["axes"].items(), ("C0", "C1", "C2")):
            t, s, r = (np.array(axd[k]) for k in ("tau_s", "adev", "rel_err"))
            ax.fill_between(t, s * (1 - r), s * (1 + r), color=color, alpha=0.2)
            ax.loglog(t, s, "o", ms=3, color=color, label=f"{a}")
            fit = allan_deviation(axd["terms"], t)
            ax.loglog(t, fit, "-", color=color, lw=1)
        ax.set(xlabel="tau (s)", ylabel=f"Allan deviation ({b['unit']})",
               title=f"{sensor}: points with their 68 % interval, lines the IEEE 952 fit")
        ax.legend(fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        rows = "".join(f"<tr><td>{a}</td>" + "".join(f"<td>{_cell(t)}</td>" for t in axd["sheet"].values()) + "</tr>"
                       for a, axd in b["axes"].items())
        head = "".join(f"<th>{t['name']} ({_html.escape(t['unit'])})</th>" for t in
                       next(iter(b["axes"].values()))["sheet"].values())
        parts.append(f"<h2>{sensor}</h2>{_png(fig)}<table border=1 cellpadding=4><tr><th>axis</th>{head}</tr>"
                     f"{rows}</table>")
    return "".join(parts)
