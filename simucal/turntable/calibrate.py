"""Calibrate a turntable measurement set (dong2018), writing calibration.json.

Methods:
- exact (default): maximum-likelihood norm fits (norm_fit.fit_exact) of both
  triads, then the gyro frame d tied to b by each rate run's mean specific force
  (in b) and mean rate (in d), both along the outer axis (simucal/unification.py):
  no accurate table angles needed, unlike eq. 25-27; C_b^d and the gyro M in b
  come with their stds.
- linear: the paper as printed: eq. 8 / 12 with the back-substitution, and
  frame unification by the (derived) eq. 25-27 at the Table 2 positions.
- multiposition: the traditional method: outputs regressed on the inputs
  computed from the commanded angles of an ideal table, b = k assumed.
Outputs follow output = M f + bias with f in b (g, deg/h).
"""
from __future__ import annotations

import numpy as np

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit import aux_inputs
from simucal.fit.augmented import AugmentedModel, for_sensor
from simucal.fit.aux_inputs import AuxInputs, column_means
from simucal.fit.candidates import forward_selection, verdict
from simucal.fit.lack_of_fit import noise_dof, with_estimated_sigma
from simucal.fit.noise import white_noise_var
from simucal.fit.norm_fit import Observations, fit_linear
from simucal.generated import table
from simucal.io import calibration, units
from simucal.io.sensor_checks import saturated_rows
from simucal.turntable.consistency import latitude, mirror_error, mirror_test
from simucal.turntable.model_test import ROWS, fails, rank, test_and_rank
from simucal.turntable.unification import Unifier, unify, unify_paper



def _mean_and_sigma(x, stated, varying=False):
    """Mean of a segment's rows and the std of that mean.

    Several rows: from their scatter, with the lag-1 autocorrelation taken
    into account (effective sample count). For a rate run (varying=True) the
    rows hold a deterministic signal, the horizontal Earth rate turning in
    the body, so the noise comes from first differences, which remove it.
    One row: the stated noise, if any, else NaN (lack_of_fit.fit_with_noise then
    estimates a variance component for such rows).
    """
    n = len(x)
    if n >= 3 and varying:
        return x.mean(0), np.sqrt(white_noise_var(x, ddof=1) / n)
    if n >= 3:
        d = x - x.mean(0)
        var = d.var(0, ddof=1)
        r1 = np.clip(np.sum(d[1:] * d[:-1], 0) / np.maximum(np.sum(d * d, 0), 1e-300), -0.9, 0.99)
        n_eff = n * (1 - r1) / (1 + r1)
        return x.mean(0), np.sqrt(var / np.maximum(n_eff, 1.0))
    return x.mean(0), np.full(3, np.nan if stated is None else stated / np.sqrt(n))


def segment_duration_s(ms, rows, where) -> float:
    """The seconds a segment's mean covers: its rows' span and one step; an averaged row's meta
    average_s (the spec's optional key), which the Allan curve needs."""
    t = ms.samples["t_s"][rows]
    if len(t) >= 2:
        return float(t[-1] - t[0] + np.median(np.diff(t)))
    if "average_s" not in ms.meta:
        raise CalibrationError(f"{ms.path / 'meta.json'}: --noise takes each row's noise from the Allan curve at the "
                               f"seconds it averages, but segment {where} is one averaged row and meta.json states no "
                               "average_s: add \"average_s\": SECONDS (or leave --noise out)")
    return float(ms.meta["average_s"])


def segment_observations(ms: io.MeasurementSet, sensor: str, kinds=None, stated=None, curve=None):
    """(Observations, segments) for 'acc' (by default the static segments; with kinds
    {"static", "rate"} the rate runs too, whose centripetal scale w2 lets lever arms show)
    or 'gyro' (rate segments). stated: the noise of one row (g or deg/h) where the data
    cannot give it; default meta's acc_noise_g / gyro_noise_dph. curve: the std of a mean
    over tau seconds (allan.load_curves, `calibrate --noise`), which then gives every
    segment's noise at its length: with bias instability a long mean is noisier than its
    rows' scatter over sqrt(n) says."""
    if ms.segments is None:
        raise CalibrationError(f"{ms.path}: no segments.csv: this is a continuous stream (use calibrate, "
                               "which detects its static poses)")
    kinds = kinds or ({"static"} if sensor == "acc" else {"rate"})
    segs = [s for s in ms.segments if s.kind in kinds]
    data = ms.acc_g() if sensor == "acc" else ms.gyro_dph()
    if stated is None:
        stated = ms.meta.get("acc_noise_g" if sensor == "acc" else "gyro_noise_dph")
    lat = np.radians(ms.meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(ms.meta)
    N, sig, rho, keep = [], [], [], []
    raw = ms.raw(sensor)
    clipped = saturated_segments(ms, sensor)
    for s in segs:
        rows = ms.samples["segment"] == s.segment
        if not rows.any():
            raise CalibrationError(f"{ms.path / 'samples.csv'}: segment {s.segment} has no samples")
        if s.segment in clipped:  # before the glitch test: a clipped sample is no glitch
            continue
        refuse_outliers(ms, raw, rows, sensor, s.segment)
        m, sd = _mean_and_sigma(data[rows], stated, varying=(s.kind == "rate"))  # the inputs turn in a rate run
        if curve is not None:
            sd = curve(segment_duration_s(ms, rows, s.segment))
        N.append(m)
        sig.append(sd)
        rho.append(1.0 if sensor == "acc" else abs(s.outer_rate_dps * units.DPH_PER_DPS + w_e * np.sin(lat)))  # |input|
        keep.append(s)
    dropped = [s.segment for s in segs if s.segment in clipped]
    need = len(AugmentedModel(f"{sensor}_baseline").params)
    if dropped and len(keep) < need and (keep or sensor == "acc"):  # no gyro at all: not calibrated, said so
        raise CalibrationError(
            f"{ms.path / 'samples.csv'}: {len(dropped)} of {len(segs)} {sensor} segments hold clipped samples (at or "
            f"beyond full_scale, or repeating the rail: segments {dropped[:8]}{' ...' if len(dropped) > 8 else ''}) "
            f"and are left out, leaving {len(keep)}, too few for the {need} parameters of {sensor}_baseline; record "
            "them within the sensor's range, or correct full_scale in meta.json if the rails are wrong")
    aux = column_means(ms.samples, [ms.samples["segment"] == s.segment for s in keep], t_ref_c=ms.t_ref_c)
    aux.update(specific_force(ms, keep) if sensor == "gyro" else {"w2": centripetal_scale(ms, keep)})
    obs = Observations(np.array(N).reshape(-1, 3), np.array(rho), np.array(sig).reshape(-1, 3), AuxInputs(aux),
                       [s.segment for s in keep])
    if curve is not None:
        obs.sigma_source = "the Allan curve of --noise at each segment's length"
    if sensor == "acc":
        check_axes_follow_gravity(ms, obs, keep)
    if keep:
        try:
            units.check_magnitude(sensor, np.linalg.norm(obs.N, axis=1), obs.rho, ms.path / "samples.csv", ms.meta)
        except CalibrationError as e:
            raise CalibrationError(f"{e}{_rates_not_units(ms) if sensor == 'gyro' else ''}") from None
    return obs, keep


def check_axes_follow_gravity(ms, obs, segs, live_g=0.5, dead_ratio=0.05, spread=0.2):
    """Refuse an accelerometer axis whose static means do not follow gravity while the others
    do (they span live_g or more): a dead channel, or a column holding another signal. Only
    where the commanded angles turn gravity out of every plane (its directions in the table
    frame spread by `spread` or more across their flattest direction), so that every axis of the
    unit, however mounted, must see it change."""
    rows = [i for i, s in enumerate(segs) if s.kind == "static" and s.middle_deg is not None
            and s.inner_deg is not None]
    if len(rows) < 4:
        return
    up_k, _ = _commanded_up_k([segs[i] for i in rows])
    if np.sqrt(max(np.linalg.eigvalsh(np.cov(up_k.T))[0], 0.0)) < spread:
        return
    span = np.ptp(obs.N[rows], axis=0)
    for j in range(3):
        others = np.delete(span, j)
        if others.min() > live_g and span[j] < dead_ratio * others.min():
            raise CalibrationError(
                f"{ms.path / 'samples.csv'}: column a{'xyz'[j]} does not follow gravity: its static means span "
                f"{span[j]:.2g} g over the {len(rows)} positions, where the other axes' span {others.min():.2g} g "
                "or more: a dead or unconnected channel, or the column holds another signal; check the wiring and "
                "the column order")


def _rates_not_units(ms) -> str:
    """Where the static segments read the Earth rate in gyro_unit (a gyro that resolves it), the
    unit is right and the commanded rates are what is off: say so."""
    if "Ferraris" in ms.meta.get("description", ""):
        return ("; this set was imported from a Ferraris session, whose commanded rate is the turn angle over the "
                "turn's duration: check the import's --rate-hz (the sample rate) and --turn-deg")
    static = np.isin(ms.samples["segment"], [s.segment for s in ms.segments if s.kind == "static"])
    if not static.any():
        return ""
    w = float(np.median(np.linalg.norm(ms.gyro_dph()[static], axis=1)))
    w_e = units.earth_rate_dph(ms.meta)
    if not 0.5 * w_e < w < 2 * w_e:
        return ""
    return (f"; but the static segments read the Earth rate ({w:.3g} deg/h against {w_e:.4g}) in that unit, so it "
            "is outer_rate_dps in segments.csv that is off: it is deg/s (not rad/s, not deg/h)")


def saturated_segments(ms, sensor) -> dict:
    """{segment: number of its samples clipped} of one sensor (io/sensor_checks.saturated_rows)."""
    bad = saturated_rows(ms, sensor)[0]
    seg, n = np.unique(ms.samples["segment"][bad], return_counts=True)
    return dict(zip(seg.tolist(), n.tolist()))


def refuse_outliers(ms, raw, rows, sensor, segment, k=100.0):
    """Refuse a gross glitch: an isolated sample k robust spreads (1.4826 MAD, floored at 1e-9 of
    the median) from its segment's median, whose neighbours are normal, would carry the segment's
    mean with it. A smooth excursion (a table settling) spans its neighbours and is not a glitch."""
    x = raw[rows]
    if len(x) < 10:
        return
    med = np.median(x, axis=0)
    spread = np.maximum(1.4826 * np.median(np.abs(x - med), axis=0), 1e-9 * np.maximum(np.abs(med), 1.0))
    dev = np.abs(x - med) / spread
    calm = np.pad(dev, ((1, 1), (0, 0)), constant_values=0.0) < k / 10  # the neighbours are normal
    bad = (dev > k) & calm[:-2] & calm[2:]
    if bad.any():
        i, j = np.argwhere(bad)[0]
        line = 2 + int(np.nonzero(rows)[0][i])
        col = ("ax", "ay", "az", "gx", "gy", "gz")[j + (0 if sensor == "acc" else 3)]
        raise CalibrationError(f"{ms.path / 'samples.csv'}, line {line}: {col} = {x[i, j]:g} is a glitch in segment "
                               f"{segment} (its median {med[j]:g}, spread {spread[j]:.3g}): remove or repair that row")


def centripetal_scale(ms, segs):
    """w2 = w_T^2 / g (1/m) of each segment: 0 at rest, the outer-axis rate's under rotation."""
    return np.array([np.radians(s.outer_rate_dps) ** 2 / units.gravity(ms.meta) for s in segs])


def specific_force(ms, segs) -> dict:
    """The specific force (g) each segment's gyro saw, for g-sensitivity terms (f_x, f_y, f_z):
    the accelerometer mean where there is one, else the commanded vertical, else none."""
    if not segs:
        return {}
    if ms.has_acc:
        acc = ms.acc_g()
        return aux_inputs.specific_force([acc[ms.samples["segment"] == s.segment].mean(0) for s in segs])
    if all(s.middle_deg is not None and s.inner_deg is not None for s in segs):
        return aux_inputs.specific_force(_commanded_up_k(segs)[0])
    return {}


def table_accuracy_rad(ms):
    """meta.json's table_accuracy_arcsec (the std of each commanded angle's position error) in rad,
    or None where not stated (the unification then estimates it from the static pairs)."""
    v = ms.meta.get("table_accuracy_arcsec")  # checked when the set is read (units.check_meta)
    return None if v is None else float(v * units.ARCSEC_RAD)


def _find(segs, kind, **want):
    """The index of the first segment of this kind at the angles want, or None."""
    for i, s in enumerate(segs):
        if s.kind == kind and all(getattr(s, k) is not None and abs(getattr(s, k) - v) < 1e-6 for k, v in want.items()):
            return i
    return None


def _rate_run_acc_means(acc_obs, acc_segs, gyro_segs):
    """The rate runs' mean accelerometer outputs (Unifier's acc_means), or None without any, taken
    from the accelerometers' observations as segment_observations gave them (before a fit fills
    their sigma): NaN where neither their scatter nor a statement gives it (the unification then
    estimates it from the rate-run pairs)."""
    if acc_obs is None:
        return None
    at = {s.segment: i for i, s in enumerate(acc_segs) if s.kind == "rate"}
    rows = [j for j, s in enumerate(gyro_segs) if s.segment in at]
    if len(rows) < 2:
        return None
    k = [at[gyro_segs[j].segment] for j in rows]
    return np.array(rows), acc_obs.N[k], acc_obs.sigma[k], acc_obs.aux.take(k)


def handedness(ms, fa, acc_obs, acc_segs, fg, gyro_segs) -> list[str]:
    """Each triad's fitted directions against the commanded table vertical (consistency.py):
    refuses a reflected triad; where both are reflected, the table's angles follow another
    convention than the spec's, which the exact method does not need (a note)."""
    return handedness_verdict(ms, {"accelerometer": mirrored(fa, acc_segs, False), "gyro": mirrored(fg, gyro_segs, True)})


def mirrored(fit, segs, rate_sign: bool):
    """consistency.mirror_test of one triad's fitted directions against the commanded vertical:
    (axis, residual, r) where the triad is a mirror image, else None. rate_sign: the directions
    are rate runs', signed by their commanded rate."""
    if fit is None or fit.directions is None:
        return None
    rows = [i for i, s in enumerate(segs) if s.middle_deg is not None and s.inner_deg is not None
            and (rate_sign or s.kind == "static")]
    if len(rows) < 3:
        return None
    up_k, _ = _commanded_up_k([segs[i] for i in rows])
    u = fit.directions[rows] * (np.sign([segs[i].outer_rate_dps for i in rows])[:, None] if rate_sign else 1.0)
    axis, resid, r = mirror_test(up_k, u)
    return None if axis is None else (axis, resid, r)


def handedness_verdict(ms, found: dict) -> list[str]:
    """found: {triad: mirrored(...)}. One reflected triad is refused; two are a note."""
    found = {k: v for k, v in found.items() if v is not None}
    if len(found) == 1:
        (sensor, (axis, resid, r)), = found.items()
        raise mirror_error(f"{ms.path}: the {sensor} directions against the commanded table vertical",
                           f"the {sensor}'s", axis, resid, r)
    if len(found) == 2:
        return ["handedness: both triads are mirror images of the commanded table geometry, so the table's angles "
                "follow another sign convention than the spec's (segments.csv); the exact method does not use them"]
    return []


def _latitude_check(ms, fa, acc_segs, gm, fg, C_b_d, gyro_noise_dph=None):
    """consistency.latitude at the static positions that have gyro data; their noise from their
    scatter, else the stated one (gyro_noise_dph, else meta's), else estimated by the latitude
    fit itself."""
    rows = [i for i, s in enumerate(acc_segs) if s.kind == "static"]
    if not rows:
        return {"verdict": "not checked: no static positions"}
    gyro = ms.gyro_dph()
    raw = ms.raw("gyro")
    stated = ms.meta.get("gyro_noise_dph") if gyro_noise_dph is None else gyro_noise_dph
    N, sig, groups = [], [], []
    for i in rows:
        r = ms.samples["segment"] == acc_segs[i].segment
        refuse_outliers(ms, raw, r, "gyro", acc_segs[i].segment)
        m, sd = _mean_and_sigma(gyro[r], stated)
        N.append(m)
        sig.append(sd)
        groups.append(r)
    sig = np.array(sig)
    sig = None if np.isnan(sig).all() else np.where(np.isnan(sig), np.nanmax(sig), sig)
    return latitude(ms, gm, fg, C_b_d, fa.directions[rows], (np.array(N), sig, AuxInputs(column_means(ms.samples, groups, t_ref_c=ms.t_ref_c))))


def _commanded_up_k(segs):
    """Unit vertical (outer axis) in k at each segment's commanded middle/inner angles."""
    if any(s.middle_deg is None or s.inner_deg is None for s in segs):
        raise CalibrationError("this method needs commanded middle and inner angles in segments.csv")
    C = table.C_k_n(0.0, np.radians([s.middle_deg for s in segs]), np.radians([s.inner_deg for s in segs]),
                    np.zeros(7))
    return C[:, 2, :], C


def check_rate_sense(ms, gyro_obs, gyro_segs):
    """Refuse rate runs whose gyro output turns opposite to the commanded rate.

    The mean output along the commanded axis, less the static outputs' mean,
    must have the sign of outer_rate_dps; a reversed turn (or a gyro of the
    opposite sign convention) would otherwise be fitted into a matrix near -I.
    """
    if gyro_obs is None or not gyro_segs:
        return
    keep = [i for i, s in enumerate(gyro_segs) if s.middle_deg is not None and s.inner_deg is not None]
    if not keep:
        return  # no commanded axis to compare with
    gyro_segs = [gyro_segs[i] for i in keep]
    gyro_obs = Observations(gyro_obs.N[keep], gyro_obs.rho[keep])
    up, _ = _commanded_up_k(gyro_segs)
    static = ms.samples["segment"] == -1
    for s in ms.segments:
        if s.kind == "static":
            static |= ms.samples["segment"] == s.segment
    rest = np.median(ms.gyro_dph()[static], axis=0) if static.any() else np.zeros(3)  # robust to a glitch
    rate = np.array([s.outer_rate_dps for s in gyro_segs])
    along = np.einsum("ni,ni->n", gyro_obs.N - rest, up) / units.DPH_PER_DPS
    wrong = np.sign(along) != np.sign(rate)
    if not wrong.any():
        return
    for k in range(3):  # some runs reversed, some not: one axis of the triad reversed?
        D = np.diag([-1.0 if j == k else 1.0 for j in range(3)])
        if wrong.sum() < len(rate) and np.all(np.sign(np.einsum("ni,ni->n", (gyro_obs.N - rest) @ D, up)) == np.sign(rate)):
            raise CalibrationError(
                f"{ms.path}: the gyro {'xyz'[k]} output has the wrong sign: {int(wrong.sum())} of {len(rate)} rate runs "
                f"turn opposite to the commanded rate, and all agree once gyro {'xyz'[k]} is reversed (a left-handed "
                f"triad, the axis wired or declared with its sign reversed); fix the sign of g{'xyz'[k]} in samples.csv "
                "(or the wiring) and calibrate again")
    detail = ", ".join([f"segment {s.segment}: commanded {r:+.1f} deg/s, measured {a:+.1f} deg/s"
                        for s, r, a, w in zip(gyro_segs, rate, along, wrong) if w][:4])
    raise CalibrationError(
        f"the gyro turns opposite to the commanded rate in {int(wrong.sum())} of {len(rate)} rate segments "
        f"({detail}{', ...' if wrong.sum() > 4 else ''}): the rotation was made the other way (or the gyro's sign "
        "convention or axes differ); not fitted, since it would give a gyro matrix near -I. Check the protocol's "
        "rotation sense (for imucal's Ferraris: import with --turn-deg 360 if the turns were counter-clockwise)")


def multiposition(ms, acc_obs, acc_segs, gyro_obs, gyro_segs):
    """Traditional method: y = M f + b with f from commanded angles, ideal table, b = k.

    Gyro inputs: rate runs (w_T + w_e sin L) along the commanded vertical, and
    the static positions' Earth rate (its heading taken from outer_deg, 0 where blank).
    """
    lat = np.radians(ms.meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(ms.meta)
    w_ie_n = table.earth_rate_n(w_e, lat)
    out = {}
    if acc_obs is not None:
        up, _ = _commanded_up_k(acc_segs)
        out["acc"] = _affine_fit(up, acc_obs.N, "acc")
    if gyro_obs is not None:
        up, _ = _commanded_up_k(gyro_segs)
        f = up * np.array([s.outer_rate_dps * units.DPH_PER_DPS + w_e * np.sin(lat) for s in gyro_segs])[:, None]
        N = gyro_obs.N
        statics = [s for s in ms.segments if s.kind == "static"]
        if statics:
            C = table.C_k_n(np.radians([s.outer_deg or 0.0 for s in statics]),
                            np.radians([s.middle_deg for s in statics]), np.radians([s.inner_deg for s in statics]),
                            np.zeros(7))
            gyro = ms.gyro_dph()
            Ns = np.array([gyro[ms.samples["segment"] == s.segment].mean(0) for s in statics])
            f = np.vstack([f, np.einsum("nji,j->ni", C, w_ie_n)])
            N = np.vstack([N, Ns])
        out["gyro"] = _affine_fit(f, N, "gyro")
    return out


def _affine_fit(f, N, sensor):
    X = np.column_stack([f, np.ones(len(f))])
    if len(f) < 5 or np.linalg.matrix_rank(X) < 4:
        raise CalibrationError(f"the multi-position {sensor} regression is rank deficient: input directions "
                               "must span three dimensions (and a bias needs a fourth position)")
    coef, *_ = np.linalg.lstsq(X, N, rcond=None)
    r = N - X @ coef
    dof = max(len(f) - 4, 1)
    s2 = np.sum(r ** 2, 0) / dof
    cov = np.linalg.inv(X.T @ X)
    return {"M": coef[:3].T, "bias": coef[3], "residual_rms": float(np.sqrt(np.mean(r ** 2))),
            "std": {"M": np.sqrt(np.outer(s2, np.diag(cov)[:3])).tolist(), "bias": np.sqrt(s2 * cov[3, 3]).tolist()}}


def _exact_sensor(model, obs, segs, method, where):
    """Fit and test one sensor by the one model test (model_test.py). Returns (fit, test block or
    None for the linear method, the effect to add when the model fails or None, the observations
    with the noise used)."""
    if method == "linear":
        if model.effects:
            raise CalibrationError("--add needs --method exact: the paper's linear regression exists for "
                                   "derived models only (or derive a model file with the term and use it)")
        return fit_linear(model, obs), None, None, obs
    fit, obs2, base, cands, shape, _ = test_and_rank(model, obs, segs, only_if_failing=True)
    base["noise"]["text"] = _noise_text(base["noise"], obs2, model.unit)
    base["verdict"] = verdict(model.sensor, base, cands, where, shape, command="calibrate")
    advice = None
    if fails(base):
        sig = [c for c in cands if c.get("significant")]
        generic = shape and not shape.get("catalog_id")  # it beats every library effect: the verdict leads with it
        advice = "a term " + shape["text"] if generic else sig[0]["id"] if sig else None
    return fit, base, advice, with_estimated_sigma(obs2, base["noise"])


def _noise_text(noise, obs, unit):
    """Which noise a fit used and where it came from, in words."""
    if not noise.get("rows_estimated"):
        return f"{np.median(obs.sigma):.2g} {unit} per row (median), from {noise['source']}"
    est = f"{noise['estimated_std']:.2g} {unit} per row estimated from the fit's residuals ({noise['dof']:.3g} dof)"
    n_known = len(obs.N) - noise["rows_estimated"]
    return est + (f" for {noise['rows_estimated']} rows; {n_known} from their scatter or the stated noise" if n_known
                  else ": none in the data or stated")


def calibrate_table(ms, method, acc_model, gyro_model, ids, acc_noise_g=None, gyro_noise_dph=None,
                    auto=False, noise_curves=None) -> dict:
    """Calibrate a turntable set (segments.csv) by `method` (exact, linear or multiposition: methods.py), the models with the effect ids added
    (auto: and the library effects that a failing model needs, candidates.forward_selection); noise_curves:
    {sensor: std of a mean over tau s} (`calibrate --noise`, segment_observations)."""
    curves = noise_curves or {}
    if auto and method != "exact":
        raise CalibrationError("--add auto needs --method exact (the effects are chosen by the exact fit's test)")
    acc_obs = acc_segs = gyro_obs = gyro_segs = None
    # the paper's linear regression (eq. 8) and the multi-position method take static positions only
    rows = ROWS if method == "exact" else {**ROWS, "acc": {"static"}}
    if ms.has_acc:
        acc_obs, acc_segs = segment_observations(ms, "acc", rows["acc"], acc_noise_g, curves.get("acc"))
    if ms.has_gyro:
        gyro_obs, gyro_segs = segment_observations(ms, "gyro", rows["gyro"], gyro_noise_dph, curves.get("gyro"))
        if not gyro_segs:
            gyro_obs = None
    check_rate_sense(ms, gyro_obs, gyro_segs)
    result = calibration.header(method, ms)
    kind = {s.segment: s.kind for s in ms.segments}
    excluded = [{"sensor": sensor, "segment": k, "samples": n, "reason": "saturated samples"}
                for sensor, present in (("acc", ms.has_acc), ("gyro", ms.has_gyro)) if present
                for k, n in saturated_segments(ms, sensor).items() if kind.get(k) in rows[sensor]]
    if excluded:
        result["excluded_segments"] = excluded
    if method == "multiposition":
        if ids or acc_model != "acc_baseline" or gyro_model != "gyro_baseline":
            raise CalibrationError("the multi-position method is the linear y = M f + b; --add and models need "
                                   "--method exact")
        mp = multiposition(ms, acc_obs, acc_segs, gyro_obs, gyro_segs)
        for sensor in ("acc", "gyro"):
            if sensor in mp:
                r = mp[sensor]
                result[sensor] = calibration.affine_block(sensor, r["M"], r["bias"], r["std"], r["residual_rms"],
                                                          "linear y = M f + b on commanded inputs")
        result["residual_rms"] = {s: result[s]["residual_rms"] for s in ("acc", "gyro") if s in result}
        return result

    am = AugmentedModel(acc_model, for_sensor(ids, "acc"))
    gm = AugmentedModel(gyro_model, for_sensor(ids, "gyro"))
    chosen = {}
    if auto:
        if acc_obs is not None:
            am, *chosen["acc"] = forward_selection(am, acc_obs, lambda *a: rank(*a, acc_segs)[:2])
        if gyro_obs is not None:
            gm, *chosen["gyro"] = forward_selection(gm, gyro_obs, lambda *a: rank(*a, gyro_segs)[:2])
    fa = fg = None
    acc_read = acc_obs  # as read: _exact_sensor returns them with each row's sigma filled in
    if acc_obs is not None:
        fa, base_a, advice_a, acc_obs = _exact_sensor(am, acc_obs, acc_segs, method, str(ms.path))
        M, b = am.matrix_and_bias(fa.vector(am.params))
        units.check_scale("acc", M, am.name)
        result["acc"] = calibration.sensor_block(am, fa, M, b, base_a)
        result["acc"]["advice"] = advice_a
    if gyro_obs is not None:
        fg, base_g, advice_g, gyro_obs = _exact_sensor(gm, gyro_obs, gyro_segs, method, str(ms.path))
        M_d, b_g = gm.matrix_and_bias(fg.vector(gm.params))
    if method == "exact":
        result["consistency"] = {"lines": handedness(ms, fa, acc_obs, acc_segs, fg, gyro_segs)}
    if gyro_obs is not None:
        no_angles = any(s.middle_deg is None or s.inner_deg is None for s in (acc_segs or []) + gyro_segs)
        acc_means = _rate_run_acc_means(acc_read, acc_segs, gyro_segs) if fa is not None and method == "exact" else None
        if fa is None or (no_angles and acc_means is None):
            why = ("no accelerometer data" if fa is None else "the rate runs have no accelerometer data and "
                   "segments.csv gives no middle/inner angles to pair them with static positions")
            units.check_scale("gyro", M_d, gm.name)
            result["gyro"] = calibration.sensor_block(gm, fg, M_d, b_g, base_g, np.eye(3))
            result["gyro"].update(frame="d (the gyro parameter frame)",
                                  note=f"M is in the gyro frame d, not in b: {why}, so the frames cannot be tied")
        else:
            std_M = None
            if method == "exact":
                un = Unifier(am, fa, acc_obs, gm, fg, gyro_obs, acc_means, noise_dof(base_a["noise"]),
                             noise_dof(base_g["noise"]))
                C_b_d, M_b, std_M, info = unify(un, acc_segs, gyro_segs, _find, table_accuracy_rad(ms))
                result["consistency"]["latitude"] = _latitude_check(ms, fa, acc_segs, gm, fg, C_b_d, gyro_noise_dph)
                result["consistency"]["lines"].append("latitude: " + result["consistency"]["latitude"]["verdict"])
            else:
                if (am.name, gm.name) != ("acc_baseline", "gyro_baseline"):
                    raise CalibrationError(f"the paper's frame unification (eq. 25-27) is derived for the baseline "
                                           f"models; {am.name} / {gm.name} have other terms it would neglect: use "
                                           "--method exact, whose unification holds for any model")
                C_b_d, info = unify_paper(acc_obs, acc_segs, gyro_obs, gyro_segs,
                                          fa.vector(am.params), fg.vector(gm.params), ms.meta, _find)
                M_b = M_d @ C_b_d
                info = {"method": "dong2018 eq. 25-27 at the Table 2 positions", "C_b_d": C_b_d.tolist(), **info}
            units.check_scale("gyro", M_b, gm.name)
            result["gyro"] = calibration.sensor_block(gm, fg, M_b, b_g, base_g, C_b_d)
            result["gyro"]["M_in_d"] = np.asarray(M_d).tolist()
            if std_M is not None:
                result["gyro"]["std_M"] = std_M.tolist()
            result["unification"] = info
        result["gyro"]["advice"] = advice_g
    for s in ("acc", "gyro"):
        if s in result:
            calibration.inflate_if_failing(result[s])
            if s in chosen:
                result[s]["auto"], result[s]["auto_stopped"] = chosen[s]
    if ms.has_gyro and "gyro" not in result:  # the data hold a gyro, the plan determines none of it
        n_rate = sum(s.kind == "rate" for s in ms.segments)
        result["not_calibrated"] = {"gyro": (
            f"no usable rate runs ({n_rate} in segments.csv, all saturated)" if n_rate else
            "no rate runs in segments.csv") + ": the gyro is not calibrated; the norm needs rate runs "
            "about several axes (the outer axis turning at several middle/inner angles)"}
        result["layout"]["sensors"] = [x for x in result["layout"]["sensors"] if x != "gyro"]
        result["formula"].pop("gyro", None)
    result["residual_rms"] = {s: result[s]["residual_rms"] for s in ("acc", "gyro") if s in result}
    return result
