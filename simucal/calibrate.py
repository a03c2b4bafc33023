"""Calibrate a turntable measurement set (dong2018), writing calibration.json.

Methods:
- exact (default): maximum-likelihood norm fits (norm_fit.fit_exact) of both
  triads, then the gyro frame d tied to b by pairing each rate run's rotation
  axis (seen by the gyros, in d) with the gravity direction of the static
  position at the same middle/inner angles (seen by the accelerometers, in b):
  Wahba's problem, solved by SVD. It needs no accurate table angles, unlike
  eq. 25-27.
- linear: the paper as printed: eq. 8 / 12 with the back-substitution, and
  frame unification by the (derived) eq. 25-27 at the Table 2 positions.
- multiposition: the traditional method: outputs regressed on the inputs
  computed from the commanded angles of an ideal table, b = k assumed.
Outputs follow output = M f + bias with f in b (g, deg/h).
"""
from __future__ import annotations

import numpy as np

from . import calibration, io, units
from .augmented import AugmentedModel
from .candidates import ALPHA, rank_candidates, shape_if_unexplained, test_model, verdict
from .generated import table, unify
from .handheld import saturated_rows
from .noise import white_noise_var
from .norm_fit import CalibrationError, Observations, fit_linear, initial_directions
from .user_models import resolve_add

METHODS = ("exact", "linear", "multiposition")


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


def segment_observations(ms: io.MeasurementSet, sensor: str, acc_in_rate_runs=False, stated=None):
    """(Observations, segments) for 'acc' (static segments; with acc_in_rate_runs the
    rate runs too, whose centripetal scale w2 lets lever arms show) or 'gyro' (rate
    segments). stated: the noise of one row (g or deg/h) where the data cannot give it;
    default meta's acc_noise_g / gyro_noise_dph."""
    if ms.segments is None:
        raise CalibrationError(f"{ms.path}: no segments.csv: this is a continuous stream (use calibrate, "
                               "which detects its static poses)")
    kinds = ({"static", "rate"} if acc_in_rate_runs else {"static"}) if sensor == "acc" else {"rate"}
    segs = [s for s in ms.segments if s.kind in kinds]
    data = ms.acc_g() if sensor == "acc" else ms.gyro_dph()
    if stated is None:
        stated = ms.meta.get("acc_noise_g" if sensor == "acc" else "gyro_noise_dph")
    lat = np.radians(ms.meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(ms.meta)
    N, sig, rho, t, temp, keep = [], [], [], [], [], []
    raw = np.column_stack([ms.samples[c] for c in (("ax", "ay", "az") if sensor == "acc" else ("gx", "gy", "gz"))])
    fs = ms.meta.get("full_scale", {}).get(sensor)
    counts = ms.meta.get(f"{sensor}_unit") == "counts"
    saturated = saturated_rows(raw, fs)[0] if (fs is not None or counts) else np.zeros(len(raw), bool)
    for s in segs:
        rows = ms.samples["segment"] == s.segment
        if not rows.any():
            raise CalibrationError(f"{ms.path / 'samples.csv'}: segment {s.segment} has no samples")
        if saturated[rows].any():
            ms.extra.setdefault("saturated_segments", []).append(
                {"sensor": sensor, "segment": s.segment, "samples": int(saturated[rows].sum())})
            continue
        m, sd = _mean_and_sigma(data[rows], stated, varying=(sensor == "gyro"))  # the Earth rate turns in a rate run
        N.append(m)
        sig.append(sd)
        rho.append(1.0 if sensor == "acc" else abs(s.outer_rate_dps * 3600.0 + w_e * np.sin(lat)))  # |input|
        t.append(ms.samples["t_s"][rows].mean())
        temp.append(ms.samples["temp_c"][rows].mean() if "temp_c" in ms.samples else 0.0)
        keep.append(s)
    obs = Observations(np.array(N).reshape(-1, 3), np.array(rho), np.array(sig).reshape(-1, 3), np.array(temp), np.array(t),
                       [s.segment for s in keep],
                       specific_force(ms, keep) if sensor == "gyro" else centripetal_scale(ms, keep))
    if keep:
        units.check_magnitude(sensor, np.linalg.norm(obs.N, axis=1), obs.rho, ms.path / "samples.csv", ms.meta)
    return obs, keep


def centripetal_scale(ms, segs):
    """w2 = w_T^2 / g (1/m) of each segment: 0 at rest, the outer-axis rate's under rotation."""
    return np.array([np.radians(s.outer_rate_dps) ** 2 / units.gravity(ms.meta) for s in segs])


def specific_force(ms, segs):
    """The specific force (g) each segment's gyro saw, for g-sensitivity terms: the
    accelerometer mean where there is one, else the commanded vertical, else none."""
    if not segs:
        return None
    if ms.has_acc:
        acc = ms.acc_g()
        return np.array([acc[ms.samples["segment"] == s.segment].mean(0) for s in segs])
    if all(s.middle_deg is not None and s.inner_deg is not None for s in segs):
        return _commanded_up_k(segs)[0]
    return None


def _find(segs, **want):
    for i, s in enumerate(segs):
        if all(getattr(s, k) is not None and abs(getattr(s, k) - v) < 1e-6 for k, v in want.items()):
            return i
    return None


def unify_paper(acc_obs, acc_segs, gyro_obs, gyro_segs, p_acc, p_gyro, meta):
    """eq. 25-27 (derived, generated/unify.py) at the Table 2 positions."""
    ia = [_find(acc_segs, middle_deg=a, outer_deg=g, inner_deg=0.0) for a, g in ((0, 0), (90, 0), (0, 180), (90, 180))]
    ig = [_find(gyro_segs, middle_deg=a, inner_deg=0.0) for a in (0.0, 90.0)]
    if None in ia or None in ig:
        raise CalibrationError("the paper's frame unification needs the Table 2 static positions "
                               "(alpha, gamma) = (0,0), (90,0), (0,180), (90,180) with beta = 0, and rate runs "
                               "at alpha = 0 and 90 deg, beta = 0; use --method exact, which needs none")
    x = unify.acc_table2(acc_obs.N[ia].reshape(12), p_acc)
    w_T = gyro_segs[ig[0]].outer_rate_dps * 3600.0
    lam = unify.gyro_mounting(gyro_obs.N[ig].reshape(6), p_gyro, w_T, units.earth_rate_dph(meta),
                              np.radians(meta["latitude_deg"]))
    C_b_d = table.mounting(lam).T @ table.mounting(x[:3])
    return C_b_d, {"theta4_rad": x[:3].tolist(), "tilt_rad": x[3:].tolist(), "lambda4_rad": lam.tolist()}


def unify_directions(acc_model, acc_fit, acc_obs, acc_segs, gyro_model, gyro_fit, gyro_obs, gyro_segs):
    """C_b^d from paired directions: rate-run axis in d vs gravity in b (Wahba, SVD)."""
    ua = acc_fit.directions if acc_fit.directions is not None else \
        initial_directions(acc_model, acc_obs, acc_fit.vector(acc_model.params))
    ug = gyro_fit.directions if gyro_fit.directions is not None else \
        initial_directions(gyro_model, gyro_obs, gyro_fit.vector(gyro_model.params))
    pairs_b, pairs_d = [], []
    for j, s in enumerate(gyro_segs):
        i = _find(acc_segs, middle_deg=s.middle_deg, inner_deg=s.inner_deg)
        if i is not None:
            pairs_b.append(ua[i])
            pairs_d.append(ug[j] * np.sign(s.outer_rate_dps))  # axis = +up for a positive rate
    if len(pairs_b) < 2 or np.linalg.matrix_rank(np.array(pairs_b), tol=1e-3) < 2:
        raise CalibrationError("frame unification needs at least two rate runs, at distinct middle/inner "
                               "angles, each with a static position at the same angles")
    B = np.array(pairs_d).T @ np.array(pairs_b)
    U, _, Vt = np.linalg.svd(B)
    C_b_d = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    resid = np.array(pairs_d) - np.array(pairs_b) @ C_b_d.T
    return C_b_d, {"pairs": len(pairs_b), "direction_residual_rms_rad": float(np.sqrt(np.mean(resid ** 2)))}


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
    rest = ms.gyro_dph()[static].mean(0) if static.any() else np.zeros(3)
    along = np.einsum("ni,ni->n", gyro_obs.N - rest, up) / 3600.0
    rate = np.array([s.outer_rate_dps for s in gyro_segs])
    wrong = np.sign(along) != np.sign(rate)
    if wrong.any():
        detail = ", ".join(f"segment {s.segment}: commanded {r:+.1f} deg/s, measured {a:+.1f} deg/s"
                           for s, r, a, w in zip(gyro_segs, rate, along, wrong) if w)
        raise CalibrationError(
            f"the gyro turns opposite to the commanded rate in {int(wrong.sum())} of {len(rate)} rate segments "
            f"({detail}): the rotation was made the other way (or the gyro's sign convention or axes differ); "
            "not fitted, since it would give a gyro matrix near -I. Check the protocol's rotation sense "
            "(for imucal's Ferraris: import with --turn-deg 360 if the turns were counter-clockwise)")


def multiposition(ms, acc_obs, acc_segs, gyro_obs, gyro_segs):
    """Traditional method: y = M f + b with f from commanded angles, ideal table, b = k.

    Gyro inputs: rate runs (w_T + w_e sin L) along the commanded vertical, and
    the static positions' Earth rate (its heading taken from outer_deg, 0 where blank).
    """
    lat = np.radians(ms.meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(ms.meta)
    w_ie_n = np.array([0.0, w_e * np.cos(lat), w_e * np.sin(lat)])
    out = {}
    if acc_obs is not None:
        up, _ = _commanded_up_k(acc_segs)
        out["acc"] = _affine_fit(up, acc_obs.N, "acc")
    if gyro_obs is not None:
        up, _ = _commanded_up_k(gyro_segs)
        f = up * np.array([s.outer_rate_dps * 3600.0 + w_e * np.sin(lat) for s in gyro_segs])[:, None]
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


def _exact_sensor(model, obs, method, where):
    """Fit and test one sensor. Returns (fit, test block or None for the linear method, the
    effect to add when the model fails or None)."""
    if method == "linear":
        if model.effects:
            raise CalibrationError("--add needs --method exact: the paper's linear regression exists for "
                                   "derived models only (or derive a model file with the term and use it)")
        return fit_linear(model, obs), None, None
    fit, obs2, base = test_model(model, obs)
    advice = None
    if base["p_value"] is not None and base["p_value"] < ALPHA:
        cands = rank_candidates(model, obs2, fit, True)
        shape = shape_if_unexplained(model, obs2, fit, base, cands)
        base["verdict"] = verdict(model.sensor, base, cands, where, shape, command="calibrate")
        sig = [c for c in cands if c.get("significant")]
        advice = sig[0]["id"] if sig else ("a term " + shape["text"] if shape else None)
    else:
        base["verdict"] = verdict(model.sensor, base, [], where)
    return fit, base, advice


def calibrate(folder, method="exact", acc_model="acc_baseline", gyro_model="gyro_baseline", detect_kw=None,
              add=(), acc_noise_g=None, gyro_noise_dph=None) -> dict:
    """Calibrate a measurement set. add: effect ids and model files (user_models.resolve_add);
    acc_noise_g / gyro_noise_dph: the noise of one row where the data cannot give it."""
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; one of {METHODS}")
    ms = io.read(folder)
    acc_model, gyro_model, ids = resolve_add(add, acc_model, gyro_model)
    if ms.segments is None:  # one continuous stream: a hand-placed session
        from .handheld import calibrate_handheld
        return calibrate_handheld(ms, AugmentedModel(acc_model, tuple(e for e in ids if e.startswith("acc."))),
                                  detect_kw, gyro_effects=tuple(e for e in ids if e.startswith("gyro.")))
    acc_obs = acc_segs = gyro_obs = gyro_segs = None
    if ms.has_acc:
        lever_arms = any(e.startswith("acc.size_effect.") for e in ids)  # seen only under rotation
        acc_obs, acc_segs = segment_observations(ms, "acc", acc_in_rate_runs=lever_arms, stated=acc_noise_g)
    if ms.has_gyro:
        gyro_obs, gyro_segs = segment_observations(ms, "gyro", stated=gyro_noise_dph)
        if not gyro_segs:
            gyro_obs = None
    check_rate_sense(ms, gyro_obs, gyro_segs)
    result = calibration.header(method, ms)
    if ms.extra.get("saturated_segments"):
        result["excluded_segments"] = [{**e, "reason": "saturated samples"} for e in ms.extra["saturated_segments"]]
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

    am = AugmentedModel(acc_model, tuple(e for e in ids if e.startswith("acc.")))
    gm = AugmentedModel(gyro_model, tuple(e for e in ids if e.startswith("gyro.")))
    fa = fg = None
    if acc_obs is not None:
        fa, base_a, advice_a = _exact_sensor(am, acc_obs, method, str(ms.path))
        M, b = am.matrix_and_bias(fa.vector(am.params))
        units.check_scale("acc", M, am.name)
        result["acc"] = calibration.sensor_block(am, fa, M, b, base_a)
        result["acc"]["advice"] = advice_a
    if gyro_obs is not None:
        fg, base_g, advice_g = _exact_sensor(gm, gyro_obs, method, str(ms.path))
        M_d, b_g = gm.matrix_and_bias(fg.vector(gm.params))
        no_angles = any(s.middle_deg is None or s.inner_deg is None for s in (acc_segs or []) + gyro_segs)
        if fa is None or no_angles:
            why = ("no accelerometer data" if fa is None else
                   "segments.csv gives no middle/inner angles to pair rate runs with static positions")
            units.check_scale("gyro", M_d, gm.name)
            result["gyro"] = calibration.sensor_block(gm, fg, M_d, b_g, base_g, np.eye(3))
            result["gyro"].update(frame="d (the gyro parameter frame)",
                                  note=f"M is in the gyro frame d, not in b: {why}, so the frames cannot be tied")
        else:
            if method == "exact":
                C_b_d, info = unify_directions(am, fa, acc_obs, acc_segs, gm, fg, gyro_obs, gyro_segs)
            else:
                C_b_d, info = unify_paper(acc_obs, acc_segs, gyro_obs, gyro_segs,
                                          fa.vector(am.params), fg.vector(gm.params), ms.meta)
            units.check_scale("gyro", M_d @ C_b_d, gm.name)
            result["gyro"] = calibration.sensor_block(gm, fg, M_d @ C_b_d, b_g, base_g, C_b_d)
            result["gyro"]["M_in_d"] = np.asarray(M_d).tolist()
            result["unification"] = {"C_b_d": C_b_d.tolist(), **info}
        result["gyro"]["advice"] = advice_g
    for s in ("acc", "gyro"):
        if s in result:
            calibration.inflate_if_failing(result[s])
    result["residual_rms"] = {s: result[s]["residual_rms"] for s in ("acc", "gyro") if s in result}
    return result
