"""`simucal calibrate`: one measurement set in, one calibration file out.

The method comes from the registry (methods.py): the one named, or by default the
first that takes the set's data (a turntable test: dong2018's exact method; a
stream: the hand-placed session; a field set: ruan2019). Every method returns the
calibration file's dict (io/calibration.py). `calibrate_thermal` calibrates one unit at
several temperature plateaus, each by its method, and fits every parameter as a
polynomial in temperature (fit/thermal.py).
"""
from __future__ import annotations

import numpy as np

from simucal import io, methods
from simucal.errors import CalibrationError, SimucalError
from simucal.fit.thermal import SPREAD_C, check_temp_c
from simucal.io import calibration, records, units
from simucal.io.calibration import Calibration, SensorBlock, SensorDetails
from simucal.io.calibration_checks import check_layout, scale_notes
from simucal.io.sensor_checks import stuck_channels
from simucal.io.timestamps import with_timestamps


def calibrate(folder, method="auto", acc_model="acc_baseline", gyro_model="gyro_baseline", detect=None,
              add=(), acc_noise_g=None, gyro_noise_dph=None, heading_accuracy_deg=None, t_ref_c=None,
              noise=None, rank=True, timestamps="auto") -> Calibration:
    """Calibrate a measurement set. method: a name of methods.METHODS, or "auto" (the default for
    the set's data). add: effect ids and model files (augmented.resolve_add), and "auto": the
    library effects a failing model needs, chosen one at a time (each sensor's block lists them
    under `auto`); acc_noise_g / gyro_noise_dph: the noise of one row where the data cannot give
    it; detect: a stream's static detection settings; heading_accuracy_deg: a field set's north
    reference (None: methods.DEFAULTS' 5 deg); t_ref_c: T_ref of temperature terms (default the mean of temp_c); noise: a noise.json of
    `simucal noise`, whose Allan curve gives each segment's noise at its length; rank: a failing model's
    candidates ranked (turntable; a thermal calibration's plateau needs none); timestamps: a
    stream's time stamps as recorded, evenly spaced at their mean step (nominal: the sensor's clock
    behind a logger's arrival times), or auto (io/timestamps.py). Options a method does not take are
    refused when set."""
    ms = io.read_set(folder) if not isinstance(folder, io.MeasurementSet) else folder
    try:
        ms, stamps = with_timestamps(ms, timestamps)
    except CalibrationError as e:
        raise e.naming(ms.path) from None
    if t_ref_c is not None and "temp_c" not in ms.samples:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: --t-ref-c {t_ref_c:g}, but there is no temp_c column for "
                               "temperature terms to take it from: leave --t-ref-c out")
    ms = ms.copy(temperature_ref_c=t_ref_c)  # the caller's set keeps its own T_ref
    curves = None
    if noise is not None:  # the file checked before any work, its refusal naming it alone
        from simucal.fit.noise import load_curves
        curves = load_curves(noise)
    try:
        m = methods.choose(method, ms)
        stuck_channels(ms)
        ids = tuple(a for a in add if a != "auto")
        if "ids" in m.options:  # models and effects: imported only by the methods that fit them
            from simucal.fit.augmented import resolve_add
            acc_model, gyro_model, ids = resolve_add(ids, acc_model, gyro_model)
        for sensor, stated, flag in (("acc", acc_noise_g, "--acc-noise-g"), ("gyro", gyro_noise_dph, "--gyro-noise-dph")):
            if stated is not None and curves and curves.get(sensor) is not None:
                raise CalibrationError(f"--noise {noise} gives the {sensor} noise of every segment, and {flag} "
                                       f"{stated:g} one row's: give one of them")
        given = dict(acc_model=acc_model, gyro_model=gyro_model, ids=ids, auto="auto" in add, detect=detect,
                     acc_noise_g=acc_noise_g, gyro_noise_dph=gyro_noise_dph, heading_accuracy_deg=heading_accuracy_deg,
                     noise_curves=curves, rank=rank)
        unused = [k for k in ("ids", "auto", "acc_noise_g", "gyro_noise_dph", "noise_curves", "detect",
                              "heading_accuracy_deg") if given[k] not in (None, False, ()) and k not in m.options]
        if unused:
            flag = {"ids": "--add", "auto": "--add auto", "noise_curves": "--noise",
                    "detect": "--init-rest-s, --threshold-factor, --window-s, --min-static-s and --gyro-limit-dps "
                              "(a stream's)"}.get(
                unused[0], "--" + unused[0].replace("_", "-"))
            takes = [x.name for x in methods.METHODS.values() if unused[0] in x.options]
            raise CalibrationError(f"{flag} does not apply to method {m.name} ({m.summary}); it applies to method "
                                   f"{' or '.join(takes)} ({' or '.join(sorted({methods.DATA[methods.METHODS[t].data] for t in takes}))}).")
        from threadpoolctl import threadpool_limits
        with threadpool_limits(1, "blas"):  # the fits' QRs and pseudo-inverses (up to 522 x 357) are small: on two
            result = m.call(ms, **given)    # OpenBLAS threads each ran 1.1-60x slower here (raw41, both ways measured)
        result.warnings += scale_notes(result, ms.meta)
        result.warnings += [f"{noise}: holds no {s} curve, so the {s} noise is the data's own (--noise covers the "
                            f"{' and '.join(curves)} only)" for s, _ in result.blocks() if curves and s not in curves]
        if stamps:
            result.details["timestamps"] = stamps
    except CalibrationError as e:
        raise e.naming(ms.path) from None
    return result


def calibrate_to_file(folder, output, kwargs: dict):
    """calibrate() one set and write its file; (result, None), or (None, the refusal's message).
    One task of a batch (`simucal calibrate DIR1 DIR2 ... --scheduler`): a refusal loses no other set."""
    try:
        result = calibrate(folder, **kwargs)
        calibration.save(output, result)
        return result, None
    except SimucalError as e:  # a refusal of this set; anything else is a bug, which stops the batch
        return None, str(e)


PLATEAU_SPREAD_C = SPREAD_C  # temperatures within this are one (a plateau's wander); plateaus or a ramp must span more


def _refuse_repeated(sets):
    """One plateau given twice (the same folder, or a copy of its samples) would count its rows twice and
    fake the plateaus' agreement: refused, naming both paths."""
    seen = {}
    for ms in sets:
        key = tuple(ms.sample_digests())
        if key in seen:
            raise CalibrationError(f"{seen[key]} and {ms.path}: the same samples (sha256 of the sensor outputs) given "
                                   "twice as plateaus: give each temperature plateau once")
        seen[key] = ms.path


def _plateau(folder):
    """A plateau's set and its temperature (the mean of temp_c), refused without a plausible temp_c."""
    ms = folder if isinstance(folder, io.MeasurementSet) else io.read_set(folder)
    if "temp_c" not in ms.samples:
        other = {c: units.temperature_unit_in_name(c) for c in ms.samples}
        named = [f"{c} (named as {u})" for c, u in other.items() if u]
        raise CalibrationError(f"{ms.path / 'samples.csv'}: no temp_c column, so no plateau temperature: a thermal "
                               "calibration needs the unit's temperature on every row" + (
                                   f"; it has {', '.join(named)}: convert it to degC as column temp_c" if named else ""))
    return ms, float(check_temp_c(ms).mean())


def _same_model(blocks, sensor, plateaus) -> None:
    """Refuse plateaus whose blocks cannot be followed over temperature: no model parameters (nominal,
    or an affine method), or another model than the first plateau's."""
    first = blocks[0]
    for b, p in zip(blocks, plateaus):
        if b.nominal or not b.params:
            raise CalibrationError(f"{p}: its {sensor} block has no model parameters to follow over temperature ("
                                   + (f"left at nominal: {b.description}" if b.nominal
                                      else f"method {b.description or b.model}; use --method exact or handheld")
                                   + ")")
        if (b.model, list(b.effects), list(b.params)) != (first.model, list(first.effects), list(first.params)):
            raise CalibrationError(f"{p}: the {sensor} model ({b.model} + {list(b.effects)}) differs from the "
                                   f"first plateau's ({first.model} + {list(first.effects)}): a thermal "
                                   "calibration needs one model at every plateau (name its effects with --add)")


def _thermal_block(blocks: list[SensorBlock], T_k, t_ref_c, degree, sensor, plateaus) -> SensorBlock:
    """One sensor's block: every parameter's polynomial, the block at T_ref (params = c_0)."""
    from dataclasses import replace

    from simucal.fit.augmented import AugmentedModel
    from simucal.fit.thermal import fit_polynomial
    _same_model(blocks, sensor, plateaus)
    first = blocks[0]
    names = list(first.params)
    fits = {n: fit_polynomial(T_k, [b.params[n] for b in blocks], [b.std[n] for b in blocks], t_ref_c, degree)
            for n in names}
    for n, f in fits.items():
        f.update({"per_plateau": [b.params[n] for b in blocks], "per_plateau_std": np.array([b.std[n] for b in blocks], float).tolist()})
    p0 = np.array([fits[n]["coefficients"][0] for n in names])
    nearest = blocks[int(np.argmin(np.abs(np.asarray(T_k) - t_ref_c)))]
    M, bias = AugmentedModel(first.model, first.library_effects()).matrix_and_bias(p0)
    details: SensorDetails = {"plateaus": [{"input": p, "temp_c": t, "p_value": b.p_value,
                                            "residual_rms": b.residual_rms, "residual_unit": b.residual_unit}
                                           for p, t, b in zip(plateaus, T_k, blocks)]}
    if first.C_b_model is not None:
        details["M_in_d"] = M.tolist()
    return replace(first, effects={e: replace(v, value=fits[e]["coefficients"][0], std=fits[e]["std"][0])
                                   for e, v in first.effects.items()},
                   params={n: fits[n]["coefficients"][0] for n in names}, std={n: fits[n]["std"][0] for n in names},
                   M=M @ nearest.C, bias=bias, C_b_model=None if first.C_b_model is None else nearest.C,
                   residual_rms=None, chi2=None, dof=None, p_value=None,
                   thermal=records.Thermal(t_ref_c=t_ref_c, plateaus_c=list(T_k), parameters=fits), details=details)


def _own_fits(base, obs, groups) -> list:
    """Each plateau fitted alone by the model without temperature terms: the evidence beside the joint
    fit (its test, and its parameters at the plateau's temperature)."""
    from simucal.fit.lack_of_fit import fit_with_noise
    return [fit_with_noise(base, obs.take(np.nonzero(groups == g)[0]))[0] for g in np.unique(groups)]


def _joint_block(obs, groups, first: SensorBlock, degree, labels, t_ref_c, plateaus: bool, segs,
                 meta=None) -> SensorBlock:
    """One sensor's block from the joint fit of every row at its own temperature (fit/thermal_select.py):
    the block at T_ref (params = c_0), every parameter's polynomial, each group's test under the joint
    model beside its own fit's (plateaus; a ramp's bands have none); segs: the rows' segments; meta: the
    gyro's, for the outer axis's tilt in its stds (turntable/tilt.py)."""
    from dataclasses import replace

    from simucal.fit.thermal_auto import by_every_row, joint_test
    from simucal.fit.thermal_select import group_tests
    from simucal.turntable.model_test import rows_text
    base, model, fit, how, obs, auto = by_every_row(first, obs, groups, degree)
    own = _own_fits(base, obs, groups) if plateaus else None
    fits: dict[str, records.ThermalPolynomial] = {}
    for j, n in enumerate(base.params):
        names = [n] + [f"{n}.T{k}" for k in range(1, model.degrees[j] + 1)]
        fits[n] = {"degree": model.degrees[j], "degree_from": how["from"],
                   "coefficients": [fit.params[x] for x in names], "std": [fit.std[x] for x in names]}
        if own:
            fits[n].update({"per_plateau": [f.params[n] for f in own], "per_plateau_std": [f.std[n] for f in own]})
    M, bias = base.matrix_and_bias(fit.vector(base.params))
    T = obs.aux.column("temp_c", len(obs.N))
    T_g = [float(np.mean(T[groups == g])) for g in np.unique(groups)]
    details: SensorDetails = {
        "groups": [{"input": lab, "temp_c": t, "own_p_value": f.p_value if f else None, **test}
                   for lab, t, f, test in zip(labels, T_g, own or [None] * len(T_g), group_tests(model, obs, fit, groups))],
        "plateaus": plateaus}
    if first.C_b_model is not None:
        details["M_in_d"] = M.tolist()
    thermal: records.Thermal = {"t_ref_c": t_ref_c, "plateaus_c": T_g, "temperature_range_c": [float(T.min()), float(T.max())],
               "fit": "joint: every row at its own temp_c", "rows": rows_text(segs), "parameters": fits, "dropped": how["dropped"],
               "covariance": {"names": list(model.params), "matrix": fit.cov.tolist()}}
    test = joint_test(base, model, obs, fit)
    details.update(calibration.as_details({k: test[k] for k in ("omnibus_p_value", "omnibus_test", "targeted")
                                           if k in test}))
    if "verdict" in test.get("targeted", {}):  # a library effect beyond its test: the one to add
        details["advice"] = test["targeted"]["strongest"]
    if auto is not None:
        details["auto"] = auto
    block = replace(first, effects=calibration.effect_values(base, fit),  # auto may have changed them (thermal_auto)
                    params={n: fit.params[n] for n in base.params}, std={n: fit.std[n] for n in base.params},
                    M=M @ first.C, bias=bias, residual_rms=fit.residual_rms, chi2=fit.chi2, dof=fit.dof,
                    p_value=test["p_value"], thermal=thermal, details=details)
    if meta is not None:
        from simucal.turntable.tilt import add_tilt_thermal
        add_tilt_thermal(block, model, fit, obs, segs, meta)
    if calibration.inflate_if_failing(block) and fit.dof:  # the coefficients' stds too (covariance kept unscaled)
        k = float(np.sqrt(max(fit.chi2 / fit.dof, 1.0)))
        for f in fits.values():
            f["std"] = [e * k for e in f["std"]]
    return block


def _still_warmup(folders, degree, kwargs):
    """The set, where --thermal is given one stream that never moves (a board warming up, handheld/warmup.py);
    else None. Options a warm-up cannot use are refused by name."""
    if len(folders) != 1:
        return None
    from simucal.handheld.static_detect import still_throughout
    ms = folders[0] if isinstance(folders[0], io.MeasurementSet) else io.read_set(folders[0])
    if methods.data_kind(ms) != methods.STREAM or not ms.has_acc or len(ms.samples["t_s"]) < 20:
        return None
    if not still_throughout(ms.acc_g(), ms.samples["t_s"]):
        _refuse_a_board_that_moved(ms)
        return None
    method = kwargs.get("method")
    given = [o for o, v in (("--thermal-degree", degree),
                            ("--method", method not in (None, "auto") and method),
                            ("--acc-noise-g", kwargs.get("acc_noise_g")), ("--gyro-noise-dph", kwargs.get("gyro_noise_dph")),
                            ("--noise", kwargs.get("noise")),
                            ("--window-s, --threshold-factor, --init-rest-s, --min-static-s, --gyro-limit-dps (a "
                             "hand session's static detection)", kwargs.get("detect")),
                            ("--timestamps", kwargs.get("timestamps") not in (None, "auto"))) if v]
    if given:
        raise CalibrationError(f"{given[0]}: a still warm-up's bias takes its degree from the data (0 to 3), its noise "
                               "from the data, its rows as they are (no poses to find, no moves to time) and no "
                               "other method; leave it out")
    return ms


def _refuse_a_board_that_moved(ms) -> None:
    """A warm-up (temp_c rising over MIN_SPAN_C) that is still in a few long stretches, not throughout: the
    board was turned, and each stretch is another orientation; refused by name (the plateau path would count
    its stretches as poses)."""
    from simucal.handheld.static_detect import detect_static
    from simucal.handheld.warmup import MIN_SPAN_C
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


def _refuse_several_imus(folders) -> None:
    """Sets of different IMUs of a log (meta.json's log: instance, device ids) are not one unit's plateaus:
    refused, naming two of them (simucal.calibrate_instances calibrates each apart)."""
    from simucal.io.meta import log_imu
    metas = [(f.path, f.meta) if isinstance(f, io.MeasurementSet) else (f, io.read_meta(f)) for f in folders]
    imus = {log_imu(m): path for path, m in metas}
    if len(imus) > 1:
        (a, one), (b, other) = list(imus.items())[:2]
        said = lambda k: "a set not from a log" if k is None else f"instance {k[0]}, device ids {k[1]}, {k[2]}"  # noqa: E731
        raise CalibrationError(f"{one} and {other}: two IMUs of a log ({said(a)}; {said(b)}), and one thermal "
                               "calibration is one unit: calibrate each apart (the command line does so with several "
                               "instances' sets; from Python, simucal.calibrate_instances)")


def _refuse_thermal_options(folders, degree, kwargs):
    _refuse_several_imus(folders)
    if degree is not None and not 0 <= degree <= 3:
        raise CalibrationError(f"--thermal-degree {degree}: between 0 and 3")
    from simucal.fit.augmented import follows_temperature
    from simucal.generated.effects import EFFECTS
    temperature = [e for e in kwargs.get("add", ()) if e in EFFECTS and follows_temperature(e)]
    if temperature:
        raise CalibrationError(f"--thermal with --add {temperature[0]}: every parameter already follows temperature "
                               "as a polynomial inside the model; a temperature effect added to it would count it "
                               "twice: leave it out")


def _temperatures(sets, t_ref_c):
    """T_ref and the plateaus' temperatures, refused where they cannot show a temperature dependence."""
    T_k = [t for _, t in sets]
    if len(sets) == 1:
        T = sets[0][0].samples["temp_c"]
        if np.ptp(T) < PLATEAU_SPREAD_C:
            raise CalibrationError(f"{sets[0][0].path / 'samples.csv'}: one set whose temp_c spans "
                                   f"{np.ptp(T):.2g} degC: a ramp of under {PLATEAU_SPREAD_C:g} degC shows no "
                                   "temperature dependence; record a wider ramp, or give two or more plateaus")
    elif max(T_k) - min(T_k) < PLATEAU_SPREAD_C:
        raise CalibrationError(f"the plateaus' temperatures {[round(t, 2) for t in T_k]} degC span "
                               f"{max(T_k) - min(T_k):.2g} degC: too little to see a temperature dependence (the "
                               f"plateaus should differ by more than {PLATEAU_SPREAD_C:g} degC)")
    return float(np.mean(T_k)) if t_ref_c is None else float(t_ref_c)


def calibrate_thermal(folders, degree=None, t_ref_c=None, **kwargs) -> Calibration:
    """One unit at two or more temperature plateaus (one set each), or one set whose temperature
    ramps. A turntable unit (method exact) is fitted once, every row at its own temp_c, with every
    parameter of the model a polynomial in (T - T_ref) inside the model, each parameter's degree
    chosen by the model test and by the groups (plateaus, bands of a ramp) left out
    (fit/thermal_select.py); each plateau is also calibrated alone as evidence. Other methods fit
    each plateau alone and then each parameter's polynomial over the plateaus (fit/thermal.py).
    T_ref: t_ref_c, else the mean of the plateaus' temperatures. The file holds the unit at T_ref
    and, per sensor, `thermal` (the polynomials) that apply evaluates at each row's temp_c."""
    if not folders:
        raise CalibrationError("--thermal needs a set whose temperature ramps, or two or more plateaus")
    _refuse_thermal_options(folders, degree, kwargs)
    from threadpoolctl import threadpool_limits
    # one BLAS thread: the QRs and solves here are small, and OpenBLAS's threads spinning against each other
    # (or against another process) made one run 0.66-7.7 s
    with threadpool_limits(1, "blas"):
        return _calibrate_thermal(folders, degree, t_ref_c, kwargs)


def _calibrate_thermal(folders, degree, t_ref_c, kwargs) -> Calibration:
    warmup = _still_warmup(folders, degree, kwargs)
    if warmup is not None:
        from simucal.handheld.warmup import calibrate_warmup
        return calibrate_warmup(warmup, t_ref_c, kwargs.get("add") or ())
    sets = [_plateau(f) for f in folders]
    _refuse_repeated([ms for ms, _ in sets])
    t_ref = _temperatures(sets, t_ref_c)
    T_k = [t for _, t in sets]
    near = int(np.argmin(np.abs(np.asarray(T_k) - t_ref)))
    # the plateau nearest T_ref by its method: the gyro frame (C_b^d), the checks, the model's shape
    cal = calibrate(sets[near][0], t_ref_c=T_k[near], rank=False, **kwargs)
    for ms, _ in sets:
        check_layout(cal, ms, f"the plateau nearest T_ref ({sets[near][0].path})")
    plateaus = [str(ms.path) for ms, _ in sets]
    T_all = np.concatenate([ms.samples["temp_c"] for ms, _ in sets])
    result = Calibration(f"thermal ({cal.method}, every row at its own temperature)", plateaus,
                         [ms.sha256 for ms, _ in sets], cal.layout, t_ref_c=t_ref,
                         temperature_range_c=[float(T_all.min()), float(T_all.max())],
                         unification=cal.unification, not_calibrated=cal.not_calibrated,
                         details=cal.details.copy(),  # that plateau's checks (consistency, ...)
                         samples_sha256=[d for ms, _ in sets for d in ms.sample_digests()])
    if cal.method == "exact":
        _joint(result, sets, cal, degree, t_ref, kwargs)
    else:
        if len(sets) < 2:
            raise CalibrationError(f"--thermal on one set needs a turntable set (method exact, whose rows are fitted "
                                   f"at their own temperature); method {cal.method} fits each plateau alone: give "
                                   "two or more plateaus")
        cals = [cal if k == near else calibrate(ms, t_ref_c=t, **kwargs) for k, (ms, t) in enumerate(sets)]
        for s in cal.sensors:
            setattr(result, s, _thermal_block([getattr(c, s) for c in cals], T_k, t_ref, degree, s, plateaus))
        result.warnings += [w for c in cals for w in c.warnings]
        return result
    result.warnings += cal.warnings
    return result


def _joint(result, sets, cal, degree, t_ref, kwargs):
    """The sensors' blocks of a turntable unit by the joint fit (_joint_block)."""
    from simucal.turntable.thermal import joint_observations, ramp_bands, ramp_warnings
    curves = None
    if kwargs.get("noise") is not None:
        from simucal.fit.noise import load_curves
        curves = load_curves(kwargs["noise"])
    obs = joint_observations([ms for ms, _ in sets], t_ref, kwargs.get("acc_noise_g"), kwargs.get("gyro_noise_dph"),
                             curves)
    for s in cal.sensors:
        if s not in obs:
            continue
        o, groups, segs = obs[s]
        labels = [str(ms.path) for ms, _ in sets]
        if len(sets) == 1:
            groups = ramp_bands(o.aux.column("temp_c", len(o.N)))
            labels = [f"{sets[0][0].path}, band {g + 1}" for g in np.unique(groups)]
            result.warnings += ramp_warnings(s, o, segs)
        setattr(result, s, _joint_block(o, groups, getattr(cal, s), degree, labels, t_ref, len(sets) > 1, segs,
                                        sets[0][0].meta if s == "gyro" else None))
