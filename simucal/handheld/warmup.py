"""A still board warming up (what PX4's Tools/process_sensor_caldata.py and ArduPilot's
Tools/scripts/tempcal_IMU.py take): one orientation, the temperature rising; `calibrate SET --thermal`
on a still stream. Each axis's reading against temperature is its bias b_i(T) = sum_k c_ik (T - T_ref)^k,
degree 0 to 3 chosen by the data.

What such data give, and what they cannot:
- the gyro's bias over temperature (with the Earth rate's share along each axis, at most 15 deg/h: the
  autopilots' tools keep it too);
- the accelerometer's change over temperature, not its bias: gravity is in every reading, along an
  axis the data do not know. Its constant is the fit at T_ref less the log's median reading, as PX4's
  tool writes X0 (ArduPilot's drops the constant altogether);
- no scale factor or misalignment (one orientation, no rate): those stay nominal, and the file says so.

The fit (per sensor, per axis): the stream averaged over blocks of equal rows (400 at most), and the
block means regressed on the powers of (T - T_ref) by generalised least squares under white noise plus
a random walk in time, their ratio by maximum likelihood. A warm-up's bias wanders (bias instability,
random walk) while the temperature rises with time, so the wander and the temperature's effect are
confounded: ordinary least squares (or a HAC covariance, which assumes a stationary residual) reads the
wander as temperature and gives stds several times too small; the random walk's covariance carries it
into the stds. The degree falls from 3 (both autopilots' cubic) while the top power's Wald chi2 is under 2
(Akaike's criterion: a bias curve is judged by its error over the range; a test at ALPHA drops real terms
where the bias wanders). The wander's size is poorly seen (its slow
part is the polynomial's), so the stds take it at the upper end of its 68 % likelihood interval (REML). The model test: the two powers beyond the chosen degree, jointly (2 dof);
where they are significant the bias follows temperature in a way the polynomial misses.
T_ref: the middle of the temperatures reached, as PX4's tool takes it (--t-ref-c to choose).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

from simucal.errors import CalibrationError
from simucal.fit.augmented import AugmentedModel
from simucal.fit.distributions import chi2_sf
from simucal.fit.thermal import check_temp_c, clusters
from simucal.io import calibration, records, timestamps
from simucal.io.calibration import SensorBlock

METHOD = "warm-up (a still board over temperature)"  # validate.WARMUP starts it
MAX_DEGREE = 3
MAX_BLOCKS = 300  # the generalised least squares' n x n factorisations: 300 blocks, 1 ms each
AIC_KEEP = 2.0  # Akaike: a coefficient is worth its degree of freedom where its chi2 exceeds 2
DROP = 0.5  # the restricted likelihood's fall at the upper end of lam's 68 % interval
LAMBDAS = np.r_[0.0, np.logspace(-8, 2, 41)]  # the random walk's variance rate against the blocks' noise, per s
MIN_SPAN_C = 5.0  # a warm-up over less shows too little of the bias's temperature dependence


def block_means(blocks, *columns):
    """Each column averaged over blocks of equal rows, at most `blocks` of them (the last rows left over dropped)."""
    per = max(len(columns[0]) // blocks, 1)
    n = len(columns[0]) // per * per
    return [c[:n].reshape(-1, per, *c.shape[1:]).mean(axis=1) for c in columns]


class Whitened:
    """The block means and the powers of (T - T_ref) whitened under noise r (I + lam K) for each lam of a grid,
    K_ij = min(t_i, t_j) (a random walk's covariance; lam 0: white noise alone): one Cholesky factor a lam for
    every axis and degree."""

    def __init__(self, Y, x, t_s, lambdas=LAMBDAS):
        n = len(x)
        self.X = _powers(x, MAX_DEGREE + 2)
        walk = np.minimum.outer(t_s, t_s)
        self.grid = []
        for lam in lambdas:
            L = np.linalg.cholesky(np.eye(n) + lam * walk)
            self.grid.append((lam, solve_triangular(L, self.X, lower=True), solve_triangular(L, Y, lower=True),
                              2 * float(np.sum(np.log(np.diag(L))))))

    def fit(self, axis: int, degree: int):
        """Generalised least squares of one axis on the powers 0..degree, lam by restricted maximum likelihood
        over the grid: (coefficients, their covariance at the wide lam, that lam, r there, the covariance at the
        best lam)."""
        n, k, fits = len(self.X), degree + 1, []
        for lam, Xw, Yw, logdet in self.grid:
            c, *_ = np.linalg.lstsq(Xw[:, :k], Yw[:, axis], rcond=None)
            rss = float(np.sum((Yw[:, axis] - Xw[:, :k] @ c) ** 2))
            # restricted likelihood (REML): the powers absorb the wander's slow part, so ordinary ML reads the
            # rest as white noise (lam 0) and the coefficients' stds miss what was absorbed
            loglik = -0.5 * ((n - k) * np.log(max(rss, 1e-300) / (n - k)) + logdet
                             + np.linalg.slogdet(Xw[:, :k].T @ Xw[:, :k])[1])
            fits.append((loglik, lam, c, rss / max(n - k, 1), Xw[:, :k]))
        top = max(f[0] for f in fits)
        best = max(fits, key=lambda f: f[0])
        # the wander is barely seen beside the temperature's effect (its slow part is the polynomial's), so its
        # best lam is often 0 where a wander is there: the stds take the largest lam within DROP of the restricted
        # likelihood's top (over simulated warm-ups with a wander, error/std 0.87-1.02; without one, the stds
        # are conservative, up to 2x: a wander the data cannot exclude is counted)
        wide = max((f for f in fits if f[0] >= top - DROP), key=lambda f: f[1])
        cov_best = best[3] * np.linalg.inv(best[4].T @ best[4])
        return best[2], wide[3] * np.linalg.inv(wide[4].T @ wide[4]), wide[1], wide[3], cov_best


def _powers(x, degree):
    return np.vander(x, degree + 1, increasing=True)


def _wald(c, cov, rows):
    """chi2 of the coefficients `rows` against 0 under their covariance, and its dof."""
    s = np.asarray(rows)
    v = c[s]
    return float(v @ np.linalg.solve(cov[np.ix_(s, s)], v)), len(s)


def axis_polynomial(w: Whitened, axis: int, scale_c: float, temperatures: int = MAX_DEGREE + 3):
    """One axis: {degree, coefficients, std (per degC^k), chi2, dof, p_value (the model test), the noise}.
    The degree falls from 3 (or from the distinct temperatures seen less one: two holds give a line) while its
    top coefficient's Wald chi2 is under AIC_KEEP (at the best lam); the model test is the two powers beyond it
    (fewer where the temperatures seen allow fewer; none: no test), jointly, at ALPHA (at the wide lam)."""
    top = min(MAX_DEGREE, temperatures - 1)
    degree = top
    c, cov, lam, r, cov_best = w.fit(axis, degree)
    # Akaike's rule (a term stays where its Wald chi2 exceeds 2: it lowers the curve's expected error), at the
    # best lam: a test at ALPHA, or the wide lam's covariance, drops real terms where the bias wanders
    while degree > 0 and _wald(c, cov_best, [degree])[0] <= AIC_KEEP:
        degree -= 1
        c, cov, lam, r, cov_best = w.fit(axis, degree)
    extra = min(2, temperatures - 1 - degree)
    chi2, dof = 0.0, 0
    if extra > 0:
        c2, cov2, _, _, _ = w.fit(axis, degree + extra)
        chi2, dof = _wald(c2, cov2, list(range(degree + 1, degree + extra + 1)))
    per = scale_c ** -np.arange(degree + 1)
    e = w.grid[0][2][:, axis] - w.X[:, :degree + 1] @ c  # lam 0's whitening is none: the block means themselves
    return {"degree": degree, "degree_from": "the data" if top == MAX_DEGREE else
            f"the data, at most {top} for the {temperatures} temperatures seen", "coefficients": (c * per).tolist(),
            "std": (np.sqrt(np.diag(cov)) * per).tolist(), "chi2": chi2, "dof": dof,
            "p_value": float(chi2_sf(chi2, dof)) if dof else None, "residual_rms": float(np.sqrt(np.mean(e ** 2))),
            "noise": {"block_mean_std": float(np.sqrt(r)), "random_walk_per_sqrt_s": float(np.sqrt(r * lam))}}


def calibrate_warmup(ms, t_ref_c=None) -> calibration.Calibration:
    """The calibration of a still stream whose temperature rises (module doc)."""
    if "temp_c" not in ms.samples:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: no temp_c column: a still recording gives the bias over "
                               "temperature only where each row's temperature is logged")
    T = check_temp_c(ms)
    lo, hi = float(T.min()), float(T.max())
    if hi - lo < MIN_SPAN_C:
        raise CalibrationError(f"{ms.path}: still throughout, and its temperature spans {hi - lo:.2g} degC "
                               f"({lo:.4g} to {hi:.4g}): a warm-up of under {MIN_SPAN_C:g} degC shows too little of the "
                               "bias's temperature dependence; cold-soak the board and log its warm-up, or run "
                               "simucal noise on these data for their noise terms")
    t_ref = (lo + hi) / 2 if t_ref_c is None else float(t_ref_c)
    cal = calibration.header(METHOD, ms)
    cal.t_ref_c, cal.temperature_range_c = t_ref, [lo, hi]
    for sensor, raw in (("acc", ms.acc_g() if ms.has_acc else None), ("gyro", ms.gyro_dph() if ms.has_gyro else None)):
        if raw is not None:
            setattr(cal, sensor, _block(sensor, raw, T, np.asarray(ms.samples["t_s"], float), t_ref, (hi - lo) / 2))
    found = timestamps.gaps(ms.samples["t_s"])
    if found:  # the block means still average rows; a gap shifts a block's time, which the random walk reads
        cal.warnings.append(f"{timestamps.gap_text(found)}: no rows there, so the curve has no data in the temperatures "
                            "those gaps crossed")
    cal.warnings.append("a still board over temperature: the bias's change with temperature only; scale factors and "
                        "misalignments stay nominal (one orientation), and the accelerometer's constant bias is not seen "
                        "(gravity): calibrate them by a six-pose or turntable session")
    return cal


def _block(sensor, raw, T, t_s, t_ref, scale_c) -> SensorBlock:
    model = AugmentedModel(f"{sensor}_baseline")
    y, T_b, t_b = block_means(MAX_BLOCKS, raw, T, t_s - t_s[0])
    w = Whitened(y, (T_b - t_ref) / scale_c, t_b)  # powers of order 1 for the solves; coefficients scaled back
    temperatures = int(clusters(T_b).max()) + 1  # holds (within SPREAD_C) count once: they fix the degree's limit
    axes = [axis_polynomial(w, i, scale_c, temperatures) for i in range(3)]
    if sensor == "acc":  # the constant less the median reading, as PX4's tool writes X0 (module doc)
        median = np.median(raw, axis=0)
        for i, a in enumerate(axes):
            a["coefficients"][0] -= float(median[i])
            a["constant"] = "the fit at T_ref less the log's median reading (gravity is in the readings)"
    bias = np.array([a["coefficients"][0] for a in axes])
    names = model.params
    fixed = {n: 0.0 for n in names if not n.startswith("b_")}
    params = {**fixed, **{f"b_{'xyz'[i]}": float(bias[i]) for i in range(3)}}
    parameters: dict[str, records.ThermalPolynomial] = {n: {"degree": 0, "coefficients": [0.0], "std": [0.0], "degree_from": "not seen: nominal"}
                  for n in fixed}
    parameters.update({f"b_{'xyz'[i]}": axes[i] for i in range(3)})
    chi2 = float(sum(a["chi2"] for a in axes))
    dof = int(sum(a["dof"] for a in axes))
    thermal: records.Thermal = {"t_ref_c": t_ref, "temperature_range_c": [float(T.min()), float(T.max())], "parameters": parameters,
               "warmup": f"{len(T_b)} block means of {len(T) // len(T_b)} rows"}
    unit = model.unit
    return SensorBlock(model.base.name, np.eye(3), bias, unit, {}, "built-in", params,
                       {f"b_{'xyz'[i]}": axes[i]["std"][0] for i in range(3)}, dict(zip(names, model.param_units)),
                       None, float(np.sqrt(np.mean([a["residual_rms"] ** 2 for a in axes]))), f"{unit} (block means)",
                       chi2, dof, float(chi2_sf(chi2, dof)) if dof else None,
                       description=f"bias over temperature, each axis a polynomial of degree {[a['degree'] for a in axes]}"
                                   " chosen by the data (Newey-West stds); scale factors and misalignments nominal",
                       thermal=thermal,
                       details={"test": "the powers beyond each axis's degree, jointly (Wald, under the random "
                                        f"walk's covariance; {'/'.join(str(a['dof']) for a in axes)} dof on x/y/z)",
                                "note": "still data: " + ("the change over temperature only (gravity hides the "
                                                          "constant)" if sensor == "acc" else
                                                          "the bias with the Earth rate's share along each axis")})


def warmup_checks(ms, f_before, f_after, w_before, w_after, cal) -> dict:
    """`simucal validate` of a warm-up calibration on another warm-up (the same unit, a still stream over
    temperature): per sensor, each axis's change over the warm-up (its block means less their median) at
    nominal and calibrated, with the block means' white noise as the floor (first differences); for the
    gyro also its rest output, whose floor is the Earth rate (its share along the axes stays in the
    calibrated output, as in the autopilots'). The data must be still throughout."""
    from simucal.fit.validation import rms
    from simucal.handheld.static_detect import still_throughout
    t = np.asarray(ms.samples["t_s"], float)
    if not ms.has_acc or not still_throughout(ms.acc_g(), t):
        raise CalibrationError(f"{ms.path}: a warm-up calibration is validated on another still warm-up of the unit "
                               "(a stream that never moves, with temp_c); these data are not one")
    out = {}
    for sensor, before, after, unit in (("acc", f_before, f_after, "g"), ("gyro", w_before, w_after, "deg/h")):
        if before is None or getattr(cal, sensor, None) is None:
            continue
        b, a = block_means(MAX_BLOCKS, before, after)
        floor = float(np.sqrt(np.mean(np.diff(a, axis=0) ** 2) / 2))
        out[sensor] = [{"what": "each axis's change over the warm-up (block means less their median)", "unit": unit,
                        "n": int(a.size), "before_rms": rms(b - np.median(b, axis=0)),
                        "after_rms": rms(a - np.median(a, axis=0)), "floor_rms": floor}]
        if sensor == "gyro":
            earth = float(ms.meta.get("earth_rate_dph", 15.04107))
            out[sensor].append({"what": "the rest output (the bias; the Earth rate's share stays)", "unit": unit,
                                "n": int(a.size), "before_rms": rms(b), "after_rms": rms(a),
                                "floor_rms": float(np.hypot(earth / np.sqrt(3), floor))})
    return out
