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
block means regressed on the powers of (T - T_ref) (and the blocks' dT/dt, where its effect is added) by
generalised least squares under white noise plus a random walk in time, their ratio by maximum likelihood. A warm-up's
bias wanders (bias instability, random walk) while the temperature rises with time, so the wander and the temperature's
effect are confounded: ordinary least squares (or a HAC covariance, which assumes a stationary residual) reads the
wander as temperature and gives stds several times too small; the random walk's covariance carries it
into the stds. The degree falls from 3 (both autopilots' cubic) while the top power's Wald chi2 is under 2
(Akaike's criterion: a bias curve is judged by its error over the range; a test at ALPHA drops real terms
where the bias wanders). The wander's size is poorly seen (its slow
part is the polynomial's), so the stds take it at the upper end of its 68 % likelihood interval (REML). The model test:
the two powers beyond the chosen degree, jointly (2 dof); where they are significant the bias follows temperature in a
way the polynomial misses. T_ref: the middle of the temperatures reached, as PX4's tool takes it (--t-ref-c to choose).

A random walk absorbs any slow misfit (on benchmarks/bench_temperature_rate.py's warm-ups a die 30 s behind
its thermistor passed that test in 50 seeds of 50, the walk fitted 5x the unit's and the residual 1.8x the other
axes'), so each axis's model test is one family at ALPHA (fit/family.py):
- the omnibus at ALPHA / 2, two tests Bonferroni: the powers beyond the degree, and the walk check: the
  smallest walk the block means allow (the lower end of lam's 68 % interval), with the
  white noise of the record's own samples (first differences, fit/noise.white_noise_var, over a block's
  rows), predicts the block residuals' first differences (the shortest tau the fit sees) a mean square; a
  mean square below it by more than its noise says the walk is not in the record's short-term part: a slow
  misfit the walk absorbed;
- the targeted test of the axis's temperature-rate effect (<sensor>.temperature_rate.<axis>, a bias in
  dT/dt: fit/thermal.temperature_rate over each block), at ALPHA / 2: the nested chi2 of adding it, its
  coefficient's Wald chi2 under the wide lam's covariance as the powers' (chi-square on 1 dof; the likelihood
  ratio maximised over the walk reads the walk low, as ordinary ML does, and gave chi2 means of 2.1 on clean
  warm-ups where the Wald gives 0.94-0.97).
A sensor's p is Bonferroni over its three axes. `--add <sensor>.temperature_rate.<axis>` fits that term
beside the polynomial; `--add auto` adds each axis's where its targeted test fails. No other effect is seen
by still data. Where the temperatures seen leave no power beyond the degree (two holds), no test at all.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.linalg import solve_triangular

from simucal.errors import CalibrationError
from simucal.fit import family
from simucal.fit.augmented import AugmentedModel, check_effect
from simucal.fit.distributions import chi2_sf
from simucal.fit.noise import white_noise_var
from simucal.fit.thermal import RATE_WINDOW_S, check_temp_c, clusters, temperature_rate
from simucal.fit.validation import CheckRecord
from simucal.generated.effects import EFFECTS
from simucal.io import calibration, records, timestamps
from simucal.io.details import WARMUP, as_details
from simucal.io.calibration import EffectValue, SensorBlock

METHOD = f"{WARMUP} (a still board over temperature)"  # validated on another warm-up (api/validating.py)
MAX_DEGREE = 3
MAX_BLOCKS = 300  # the generalised least squares' n x n factorisations: 300 blocks, 1 ms each
AIC_KEEP = 2.0  # Akaike: a coefficient is worth its degree of freedom where its chi2 exceeds 2
DROP = 0.5  # the restricted likelihood's fall at the upper end of lam's 68 % interval
LAMBDAS = np.r_[0.0, np.logspace(-8, 2, 41)]  # the random walk's variance rate against the blocks' noise, per s
MIN_SPAN_C = 5.0  # a warm-up over less shows too little of the bias's temperature dependence
RATE = "temperature_rate"  # the one library family still data see beside the polynomial (derive/models/effects.py)
RATE_COLUMN = MAX_DEGREE + 3  # the rate's column in Whitened.X, after the powers 0..MAX_DEGREE + 2


def rate_id(sensor: str, axis: int) -> str:
    return f"{sensor}.{RATE}.{'xyz'[axis]}"


def block_means(blocks, *columns):
    """Each column averaged over blocks of equal rows, at most `blocks` of them (the last rows left over dropped)."""
    per = max(len(columns[0]) // blocks, 1)
    n = len(columns[0]) // per * per
    return [c[:n].reshape(-1, per, *c.shape[1:]).mean(axis=1) for c in columns]


class AxisFit(NamedTuple):
    """One axis's generalised least squares (Whitened.fit)."""
    c: np.ndarray         # coefficients at the best lam
    cov: np.ndarray       # their covariance at the wide lam (the stds)
    lam: float            # the wide lam
    r: float              # the blocks' white noise there
    cov_best: np.ndarray  # the covariance at the best lam
    walk_low: float       # the walk's variance rate (per s) at the lower end of lam's 68 % interval


class Whitened:
    """The block means and the powers of (T - T_ref) (and the blocks' dT/dt) whitened under noise r (I + lam K)
    for each lam of a grid, K_ij = min(t_i, t_j) (a random walk's covariance; lam 0: white noise alone): one
    Cholesky factor a lam, kept as the whitened columns' cross products (a fit of any axis, degree and columns
    is then a k x k solve a lam, all lams at once). The block means are taken about their mean (the constant
    column gets it back), so that a 1 g level leaves the sums of squares their digits."""

    def __init__(self, Y, x, t_s, rate, lambdas=LAMBDAS):
        n, self.t_b, self.lambdas = len(x), np.asarray(t_s, float), np.asarray(lambdas, float)
        self.X = np.column_stack([_powers(x, MAX_DEGREE + 2), rate])
        self.Y, self.level = np.asarray(Y, float), np.mean(Y, axis=0)
        walk = np.minimum.outer(t_s, t_s)
        G, H, yy, logdet = [], [], [], []
        for lam in self.lambdas:
            L = np.linalg.cholesky(np.eye(n) + lam * walk)
            Xw, Yw = solve_triangular(L, self.X, lower=True), solve_triangular(L, self.Y - self.level, lower=True)
            G.append(Xw.T @ Xw)
            H.append(Xw.T @ Yw)
            yy.append(np.sum(Yw ** 2, axis=0))
            logdet.append(2 * float(np.sum(np.log(np.diag(L)))))
        self.G, self.H, self.yy, self.logdet = np.array(G), np.array(H), np.array(yy), np.array(logdet)

    def columns(self, degree: int, rate: bool) -> list[int]:
        return list(range(degree + 1)) + ([RATE_COLUMN] if rate else [])

    def fit(self, axis: int, degree: int, rate: bool = False) -> AxisFit:
        """Generalised least squares of one axis on the powers 0..degree (and the rate), lam by restricted
        maximum likelihood over the grid (AxisFit)."""
        cols = self.columns(degree, rate)
        n, k = len(self.X), len(cols)
        G, h = self.G[:, cols][:, :, cols], self.H[:, cols, axis]
        c = np.linalg.solve(G, h[..., None])[..., 0]
        rss = np.maximum(self.yy[:, axis] - np.einsum("lk,lk->l", h, c), 1e-300)
        # restricted likelihood (REML): the powers absorb the wander's slow part, so ordinary ML reads the
        # rest as white noise (lam 0) and the coefficients' stds miss what was absorbed
        restricted = -0.5 * ((n - k) * np.log(rss / (n - k)) + self.logdet + np.linalg.slogdet(G)[1])
        r = rss / max(n - k, 1)
        near = np.nonzero(restricted >= restricted.max() - DROP)[0]
        best, wide, low = int(np.argmax(restricted)), near.max(), near.min()  # lams ascend
        # the wander is barely seen beside the temperature's effect (its slow part is the polynomial's), so its
        # best lam is often 0 where a wander is there: the stds take the largest lam within DROP of the restricted
        # likelihood's top (over simulated warm-ups with a wander, error/std 0.87-1.02; without one, the stds
        # are conservative, up to 2x: a wander the data cannot exclude is counted); the walk check the smallest
        coefficients = c[best] + np.eye(k)[0] * self.level[axis]
        return AxisFit(coefficients, r[wide] * np.linalg.inv(G[wide]), float(self.lambdas[wide]), float(r[wide]),
                       r[best] * np.linalg.inv(G[best]), float(self.lambdas[low] * r[low]))

    def residual(self, axis: int, degree: int, rate: bool, c) -> np.ndarray:
        """The block means less the fit."""
        return self.Y[:, axis] - self.X[:, self.columns(degree, rate)] @ c


def _powers(x, degree):
    return np.vander(x, degree + 1, increasing=True)


def _wald(c, cov, rows):
    """chi2 of the coefficients `rows` against 0 under their covariance, and its dof."""
    s = np.asarray(rows)
    v = c[s]
    return float(v @ np.linalg.solve(cov[np.ix_(s, s)], v)), len(s)


def walk_check(e, t_b, white, walk_low) -> records.WalkCheck:
    """The walk the fit takes against the record's short-term part (module doc): the block residuals e's first
    differences have mean square E = 2 white + 2/3 q^2 dt under white noise `white` (the blocks', from the
    samples) and a walk q^2 = walk_low (2/3: the difference of two dt-long means of a walk; with q^2 dt, walks
    of 1.5 per sqrt(s) read z 2 on average on clean warm-ups); their noise (an MA(1) of the white part) is
    sqrt((2 E^2 + 4 white^2) / m) for m of them. One-sided: a mean square below E (a smooth misfit's
    differences are small). Its power is modest: a walk shows beside the white noise at one block only where
    it is large (docs/temperature.md gives its numbers)."""
    d = np.diff(e)
    observed = float(np.mean(d ** 2))
    predicted = 2 * white + 2 / 3 * walk_low * float(np.mean(np.diff(t_b)))
    z = (predicted - observed) / math.sqrt((2 * predicted ** 2 + 4 * white ** 2) / len(d))
    return {"walk_low_per_sqrt_s": math.sqrt(walk_low), "white_block_std": math.sqrt(white),
            "first_differences_ms": observed, "predicted_ms": predicted, "z": z,
            "p_value": 0.5 * math.erfc(z / math.sqrt(2))}


def axis_polynomial(w: Whitened, axis: int, scale_c: float, temperatures: int = MAX_DEGREE + 3, rate: bool = False,
                    white: float | None = None, rate_scale: float = 1.0,
                    eid: str | None = None) -> records.ThermalPolynomial:
    """One axis: {degree, coefficients, std (per degC^k), chi2, dof, p_value (the model test), the noise, and
    where the rate is fitted (rate) its coefficient and std per degC/s}. The degree falls from 3 (or from the
    distinct temperatures seen less one: two holds give a line) while its top coefficient's Wald chi2 is under
    AIC_KEEP (at the best lam); the model test is the module doc's family, where the powers beyond the degree
    have a dof (fewer where the temperatures seen allow fewer; none: no test). white: the block means' white
    noise from the samples (None: no walk check); eid: the axis's temperature-rate effect, tested where not fitted."""
    top = min(MAX_DEGREE, temperatures - 1)
    degree = top
    f = w.fit(axis, degree, rate)
    # Akaike's rule (a term stays where its Wald chi2 exceeds 2: it lowers the curve's expected error), at the
    # best lam: a test at ALPHA, or the wide lam's covariance, drops real terms where the bias wanders
    while degree > 0 and _wald(f.c, f.cov_best, [degree])[0] <= AIC_KEEP:
        degree -= 1
        f = w.fit(axis, degree, rate)
    extra = min(2, temperatures - 1 - degree)
    chi2, dof = 0.0, 0
    if extra > 0:
        f2 = w.fit(axis, degree + extra, rate)
        chi2, dof = _wald(f2.c, f2.cov, list(range(degree + 1, degree + extra + 1)))
    per = scale_c ** -np.arange(degree + 1)
    e = w.residual(axis, degree, rate, f.c)
    std = np.sqrt(np.diag(f.cov))
    out: records.ThermalPolynomial = {
        "degree": degree, "degree_from": "the data" if top == MAX_DEGREE else
        f"the data, at most {top} for the {temperatures} temperatures seen",
        "coefficients": (f.c[:degree + 1] * per).tolist(),
        "std": (std[:degree + 1] * per).tolist(), "chi2": chi2, "dof": dof,
        "p_value": float(chi2_sf(chi2, dof)) if dof else None, "residual_rms": float(np.sqrt(np.mean(e ** 2))),
        "noise": {"block_mean_std": float(np.sqrt(f.r)), "random_walk_per_sqrt_s": float(np.sqrt(f.r * f.lam))}}
    if rate:
        out["rate"] = {"value": float(f.c[-1] / rate_scale), "std": float(std[-1] / rate_scale)}
    if dof and white is not None:
        _model_test(out, w, axis, degree, rate, f, e, white, eid, rate_scale)
    return out


def _model_test(out, w: Whitened, axis, degree, rate, f: AxisFit, e, white, eid, rate_scale) -> None:
    """The axis's family (module doc) folded into out: the omnibus (the powers beyond, the walk check) and the
    temperature-rate effect's nested chi2 where it is not in the model and the blocks' rate is not a polynomial
    in T (its separable share, fit/family.py), with its estimate (per degC/s) were it added."""
    walk = walk_check(e, w.t_b, white, f.walk_low)
    out["walk_check"] = walk
    out["test"] = "the powers beyond the degree (Wald) and the walk check, Bonferroni"
    out["p_value"] = min(1.0, 2 * min(out["p_value"], walk["p_value"]))
    tgt: records.Targeted | None = None
    if not rate and eid is not None:
        Q = np.linalg.qr(w.X[:, w.columns(degree, False)])[0]
        if family.separable(Q, w.X[:, RATE_COLUMN])[1] >= family.COLLINEAR:
            with_rate = w.fit(axis, degree, True)
            stat = _wald(with_rate.c, with_rate.cov, [degree + 1])[0]
            tgt = {"tested": 1, "strongest": eid, "statistic": stat, "p_value": float(chi2_sf(stat, 1)),
                   "level": family.candidate_level(1), "estimate": float(with_rate.c[-1] / rate_scale)}
    family.fold(out, tgt)


def calibrate_warmup(ms, t_ref_c=None, add=()) -> calibration.Calibration:
    """The calibration of a still stream whose temperature rises (module doc). add: temperature-rate effect ids
    (<sensor>.temperature_rate.<axis>) fitted beside the polynomials, and "auto" (each axis's where its test fails)."""
    add = (add,) if isinstance(add, str) else tuple(add)
    ids = _rate_effects(add)
    if "temp_c" not in ms.samples:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: no temp_c column: a still recording gives the bias over "
                               "temperature only where each row's temperature is logged")
    T = check_temp_c(ms)
    lo, hi = float(T.min()), float(T.max())
    if hi - lo < MIN_SPAN_C:
        raise CalibrationError(f"{ms.path}: still throughout, and its temperature spans {hi - lo:.2g} degC "
                               f"({lo:.4g} to {hi:.4g}): a warm-up of under {MIN_SPAN_C:g} degC shows too "
                               "little of the bias's temperature dependence; cold-soak the board and log its "
                               "warm-up, or run simucal noise on these data for their noise terms")
    t_ref = (lo + hi) / 2 if t_ref_c is None else float(t_ref_c)
    cal = calibration.header(METHOD, ms)
    cal.t_ref_c, cal.temperature_range_c = t_ref, [lo, hi]
    t_s = np.asarray(ms.samples["t_s"], float)
    for sensor, raw in (("acc", ms.acc_g() if ms.has_acc else None), ("gyro", ms.gyro_dph() if ms.has_gyro else None)):
        if raw is not None:
            block, said = _block(sensor, raw, T, t_s, t_ref, (hi - lo) / 2,
                                 tuple(e for e in ids if e.startswith(sensor + ".")), "auto" in add)
            setattr(cal, sensor, block)
            cal.warnings += said
    found = timestamps.gaps(ms.samples["t_s"])
    if found:  # the block means still average rows; a gap shifts a block's time, which the random walk reads
        cal.warnings.append(f"{timestamps.gap_text(found)}: no rows there, so the curve has no data in the "
                            "temperatures those gaps crossed")
    cal.warnings.append("a still board over temperature: the bias's change with temperature only; scale factors and "
                        "misalignments stay nominal (one orientation), and the accelerometer's constant bias is "
                        "not seen (gravity): calibrate them by a six-pose or turntable session")
    return cal


def refuse_a_board_that_moved(ms) -> None:
    """A warm-up (temp_c rising over MIN_SPAN_C) that is still in a few long stretches, not throughout: the
    board was turned, and each stretch is another orientation; refused by name (the plateau path would count
    its stretches as poses)."""
    from simucal.handheld.static_detect import detect_static
    T, t = ms.samples.get("temp_c"), np.asarray(ms.samples["t_s"], float)
    if T is None or np.ptp(T) < MIN_SPAN_C:
        return
    try:
        d = detect_static(ms.acc_g(), t)
    except CalibrationError:
        return
    spans = [(float(t[a]), float(t[b - 1])) for a, b in zip(d.starts, d.ends)]
    still_s = sum(b - a for a, b in spans)
    if not 2 <= len(spans) <= 3 or still_s < 0.8 * (t[-1] - t[0]):
        return
    f = ms.acc_g()
    up = [f[a:b].mean(axis=0) / np.linalg.norm(f[a:b].mean(axis=0)) for a, b in zip(d.starts, d.ends)]
    angle = max(np.degrees(np.arccos(np.clip(u @ v, -1, 1))) for i, u in enumerate(up) for v in up[i + 1:])
    raise CalibrationError(
        f"{ms.path}: the board moved during the warm-up: it is still in {len(spans)} stretches ("
        + ", ".join(f"{a:.0f}-{b:.0f} s" for a, b in spans) + f"), up to {angle:.0f} deg apart, while a "
        "still warm-up is one orientation: give each stretch as a set of its own (each is calibrated with --thermal "
        f"where its temperature spans {MIN_SPAN_C:g} degC), or log the warm-up again without touching the board")

def _rate_effects(add) -> tuple[str, ...]:
    """The effect ids of --add, each a temperature-rate effect (the one family still data see), else refused."""
    ids = tuple(e for e in add if e != "auto")
    for e in ids:
        check_effect(e)
        if e.split(".")[1] != RATE:
            raise CalibrationError(f"--add {e}: a still warm-up fits no effects but its bias's temperature rate "
                                   f"(<sensor>.{RATE}.<axis>): one orientation and no motion show no other; leave "
                                   "it out, and calibrate the others by a six-pose or turntable session")
    return ids


def _fit_axes(sensor, raw, T, t_s, t_ref, scale_c, effects, auto):
    """(axes, effects, auto's steps or None, blocks): each axis's polynomial (axis_polynomial), with the temperature
    rate fitted where `effects` name it, and with auto where its targeted test fails."""
    y, T_b, t_b = block_means(MAX_BLOCKS, raw, T, t_s - t_s[0])
    per = len(raw) // len(y)
    span_s = per * float(np.median(np.diff(t_s)))
    rate = temperature_rate(t_s, T, t_s[0] + t_b, max(RATE_WINDOW_S, span_s))  # each block's dT/dt, degC/s
    rate_scale = float(np.sqrt(np.mean(rate ** 2))) or 1.0  # a column of order 1 for the solves
    w = Whitened(y, (T_b - t_ref) / scale_c, t_b, rate / rate_scale)  # powers of order 1; coefficients scaled back
    temperatures = int(clusters(T_b).max()) + 1  # holds (within SPREAD_C) count once: they fix the degree's limit
    white = white_noise_var(raw) / per  # the block means' white noise, from the samples' first differences

    def axis(i, fitted):
        return axis_polynomial(w, i, scale_c, temperatures, fitted, float(white[i]), rate_scale, rate_id(sensor, i))
    axes = [axis(i, rate_id(sensor, i) in effects) for i in range(3)]
    steps: list[dict] | None = [] if auto else None
    for i, a in enumerate(axes):
        if steps is not None and "verdict" in a.get("targeted", {}):
            stat = a["targeted"]["statistic"]
            axes[i] = a = axis(i, True)
            effects += (rate_id(sensor, i),)
            steps.append({"id": rate_id(sensor, i), "estimate": a["rate"]["value"], "std": a["rate"]["std"],
                          "unit": EFFECTS[rate_id(sensor, i)].unit, "p_value_after": a["p_value"],
                          "residual_rms_after": a["residual_rms"],
                          "chosen_by": f"the axis's targeted test (nested chi2 {stat:.1f} on 1 dof)"})
    return axes, tuple(sorted(effects)), steps, len(y)


def _block(sensor, raw, T, t_s, t_ref, scale_c, effects, auto) -> tuple[SensorBlock, list[str]]:
    """One sensor's block, and the warnings of its axes' tests."""
    axes, effects, steps, blocks = _fit_axes(sensor, raw, T, t_s, t_ref, scale_c, effects, auto)
    if sensor == "acc":  # the constant less the median reading, as PX4's tool writes X0 (module doc)
        median = np.median(raw, axis=0)
        for i, a in enumerate(axes):
            a["coefficients"][0] -= float(median[i])
            a["constant"] = "the fit at T_ref less the log's median reading (gravity is in the readings)"
    model = AugmentedModel(f"{sensor}_baseline", effects)
    bias = np.array([a["coefficients"][0] for a in axes])
    values = {rate_id(sensor, i): a["rate"] for i, a in enumerate(axes) if "rate" in a}
    fixed = {n: 0.0 for n in model.base.params if not n.startswith("b_")}
    params = {**fixed, **{f"b_{'xyz'[i]}": float(bias[i]) for i in range(3)},
              **{e: v["value"] for e, v in values.items()}}
    parameters: dict[str, records.ThermalPolynomial] = {
        n: {"degree": 0, "coefficients": [0.0], "std": [0.0], "degree_from": "not seen: nominal"} for n in fixed}
    parameters.update({f"b_{'xyz'[i]}": axes[i] for i in range(3)})
    parameters.update({e: {"degree": 0, "coefficients": [v["value"]], "std": [v["std"]],
                           "degree_from": "constant: an effect added beside the bias's polynomial"}
                       for e, v in values.items()})
    chi2 = float(sum(a["chi2"] for a in axes))
    dof = int(sum(a["dof"] for a in axes))
    tested = [a["p_value"] for a in axes if a["p_value"] is not None]
    thermal: records.Thermal = {"t_ref_c": t_ref, "temperature_range_c": [float(T.min()), float(T.max())],
                                "parameters": parameters,
                                "warmup": f"{blocks} block means of {len(raw) // blocks} rows"}
    unit = model.unit
    details = {"test": "per axis one family at the model test's level: the powers beyond its degree (Wald, under "
                       f"the random walk's covariance; {'/'.join(str(a['dof']) for a in axes)} dof on x/y/z) and the "
                       "walk check at half of it, the temperature-rate effect's nested chi2 at the other half; the "
                       "sensor's p Bonferroni over its axes",
               "note": "still data: " + ("the change over temperature only (gravity hides the constant)"
                                         if sensor == "acc"
                                         else "the bias with the Earth rate's share along each axis")}
    beyond = [a["targeted"] for a in axes if "verdict" in a.get("targeted", {})]
    if beyond:
        details["advice"] = max(beyond, key=lambda t: t["statistic"])["strongest"]
    if steps is not None:
        details["auto"] = steps
    block = SensorBlock(model.base.name, np.eye(3), bias, unit,
                        {e: EffectValue(v["value"], v["std"], EFFECTS[e].unit, EFFECTS[e].meaning)
                         for e, v in values.items()},
                        "built-in", params, {**{f"b_{'xyz'[i]}": axes[i]["std"][0] for i in range(3)},
                                             **{e: v["std"] for e, v in values.items()}},
                        dict(zip(model.params, model.param_units)), None,
                        float(np.sqrt(np.mean([a["residual_rms"] ** 2 for a in axes]))), f"{unit} (block means)",
                        chi2, dof, min(1.0, len(tested) * min(tested)) if tested else None,
                        description="bias over temperature, each axis a polynomial of degree "
                                    f"{[a['degree'] for a in axes]}"
                                    " chosen by the data (stds under the random walk's covariance)"
                                    + "".join(f", {e}" for e in values) + "; scale factors and misalignments nominal",
                        thermal=thermal, details=as_details(details))
    return block, [_said(sensor, i, a) for i, a in enumerate(axes) if _said(sensor, i, a)]


def _said(sensor, i, a) -> str:
    """An axis's warning where a test of its family fails: the temperature rate beyond its test (with the lag
    it implies, -bTr / b'(T_ref)), or the walk beyond what the record's short-term part supports."""
    t, walk, level = a.get("targeted", {}), a.get("walk_check"), family.ALPHA * family.OMNIBUS_SHARE / 2
    if "verdict" in t:
        slope = a["coefficients"][1] if a["degree"] else 0.0
        lag = -t.get("estimate", 0.0) / slope if slope else None
        return (f"{sensor} {'xyz'[i]}: its bias follows the temperature's rate of change ({t['strongest']}: nested "
                f"chi2 {t['statistic']:.1f} on 1 dof, p = {t['p_value']:.2g} < {t['level']:.2g})"
                + (f", as a die lagging its thermistor by about {lag:.0f} s would" if lag and lag > 0 else "")
                + f": calibrate with --add {t['strongest']} (or --add auto); the autopilots' thermal parameters "
                "hold no such term")
    if walk is not None and walk["p_value"] < level:
        return (f"{sensor} {'xyz'[i]}: the bias's random walk the fit takes "
                f"({a['noise']['random_walk_per_sqrt_s']:.3g} per sqrt(s); at least {walk['walk_low_per_sqrt_s']:.3g}) "
                "is more than the record's short-term part holds (the block means' first differences "
                f"{walk['first_differences_ms']:.3g} against {walk['predicted_ms']:.3g} predicted, "
                f"p = {walk['p_value']:.2g}): a slow misfit the polynomial misses, read as a wander")
    return ""


def warmup_checks(ms, f_before, f_after, w_before, w_after, cal) -> dict[str, list[CheckRecord]]:
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
    out: dict[str, list[CheckRecord]] = {}
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
