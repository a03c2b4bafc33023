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
from simucal.errors import CalibrationError
from simucal.io import calibration
from simucal.io.calibration import Calibration, SensorBlock
from simucal.io.calibration_checks import check_layout, scale_notes
from simucal.io.sensor_checks import stuck_channels


def calibrate(folder, method="auto", acc_model="acc_baseline", gyro_model="gyro_baseline", detect=None,
              add=(), acc_noise_g=None, gyro_noise_dph=None, heading_accuracy_deg=5.0, t_ref_c=None,
              noise=None) -> Calibration:
    """Calibrate a measurement set. method: a name of methods.METHODS, or "auto" (the default for
    the set's data). add: effect ids and model files (augmented.resolve_add), and "auto": the
    library effects a failing model needs, chosen one at a time (each sensor's block lists them
    under `auto`); acc_noise_g / gyro_noise_dph: the noise of one row where the data cannot give
    it; detect: a stream's static detection settings; heading_accuracy_deg: a field set's north
    reference; t_ref_c: T_ref of temperature terms (default the mean of temp_c); noise: a noise.json of
    `simucal noise`, whose Allan curve gives each segment's noise at its length. Options a method does
    not take are refused when set."""
    ms = io.read_set(folder) if not isinstance(folder, io.MeasurementSet) else folder
    if t_ref_c is not None and "temp_c" not in ms.samples:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: --t-ref-c {t_ref_c:g}, but there is no temp_c column for "
                               "temperature terms to take it from: leave --t-ref-c out")
    ms.temperature_ref_c = t_ref_c
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
        given = dict(acc_model=acc_model, gyro_model=gyro_model, ids=ids, auto="auto" in add, detect=detect,
                     acc_noise_g=acc_noise_g, gyro_noise_dph=gyro_noise_dph, heading_accuracy_deg=heading_accuracy_deg,
                     noise_curves=curves)
        unused = [k for k in ("ids", "auto", "acc_noise_g", "gyro_noise_dph", "noise_curves")
                  if given[k] and k not in m.options]
        if unused:
            flag = {"ids": "--add", "auto": "--add auto", "noise_curves": "--noise"}.get(
                unused[0], "--" + unused[0].replace("_", "-"))
            raise CalibrationError(f"{flag} does not apply to method {m.name} ({m.summary}).")
        result = m.call(ms, **given)
        result.warnings += scale_notes(result, ms.meta)
        result.warnings += [f"{noise}: holds no {s} curve, so the {s} noise is the data's own (--noise covers the "
                            f"{' and '.join(curves)} only)" for s, _ in result.blocks() if curves and s not in curves]
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
    except (io.MeasurementSetError, CalibrationError, KeyError, FileNotFoundError, ValueError) as e:
        return None, str(e.args[0] if isinstance(e, KeyError) and e.args else e)


PLAUSIBLE_C = (-60.0, 150.0)  # beyond any unit's operating range: a column in another unit (K, degF) or broken
PLATEAU_SPREAD_C = 2.0  # a plateau's temp_c wider than this (peak to peak) is a sweep, not a plateau


def _plateau(folder):
    """A plateau's set and its temperature (the mean of temp_c), refused without a plausible temp_c."""
    ms = io.read_set(folder)
    if "temp_c" not in ms.samples:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: no temp_c column, so no plateau temperature: a thermal "
                               "calibration needs the unit's temperature on every row")
    T = ms.samples["temp_c"]
    if T.min() < PLAUSIBLE_C[0] or T.max() > PLAUSIBLE_C[1]:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: temp_c runs {T.min():.4g} to {T.max():.4g}, outside any "
                               f"unit's range {PLAUSIBLE_C} degC: is the column in kelvin or degF?")
    return ms, float(T.mean())


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
        f.update(per_plateau=[b.params[n] for b in blocks], per_plateau_std=[b.std[n] for b in blocks])
    p0 = np.array([fits[n]["coefficients"][0] for n in names])
    nearest = blocks[int(np.argmin(np.abs(np.asarray(T_k) - t_ref_c)))]
    M, bias = AugmentedModel(first.model, first.library_effects()).matrix_and_bias(p0)
    details = {"plateaus": [{"input": p, "temp_c": t, "p_value": b.p_value, "residual_rms": b.residual_rms,
                             "residual_unit": b.residual_unit} for p, t, b in zip(plateaus, T_k, blocks)]}
    if first.C_b_model is not None:
        details["M_in_d"] = M.tolist()
    return replace(first, effects={e: replace(v, value=fits[e]["coefficients"][0], std=fits[e]["std"][0])
                                   for e, v in first.effects.items()},
                   params={n: fits[n]["coefficients"][0] for n in names}, std={n: fits[n]["std"][0] for n in names},
                   M=M @ nearest.C, bias=bias, C_b_model=None if first.C_b_model is None else nearest.C,
                   residual_rms=None, chi2=None, dof=None, p_value=None,
                   thermal={"t_ref_c": t_ref_c, "plateaus_c": list(T_k), "parameters": fits}, details=details)


def calibrate_thermal(folders, degree=None, t_ref_c=None, **kwargs) -> Calibration:
    """One unit at two or more temperature plateaus (one set each, its temperature the mean of its
    temp_c): each plateau calibrated alone by calibrate(**kwargs), then every parameter of the
    model a polynomial in (T - T_ref) (fit/thermal.py; degree None: chosen by the data).
    T_ref: t_ref_c, else the mean of the plateaus' temperatures. The file holds the unit at
    T_ref and, per sensor, `thermal` (the polynomials) that apply evaluates at each row's temp_c."""
    if len(folders) < 2:
        raise CalibrationError("--thermal needs two or more plateaus (one set each): one plateau shows no "
                               "temperature dependence; calibrate it without --thermal")
    if degree is not None and not 0 <= degree <= min(3, len(folders) - 1):
        raise CalibrationError(f"--thermal-degree {degree}: between 0 and {min(3, len(folders) - 1)} "
                               f"({len(folders)} plateaus fit at most degree {len(folders) - 1})")
    from simucal.fit.augmented import follows_temperature
    from simucal.generated.effects import EFFECTS
    temperature = [e for e in kwargs.get("add", ()) if e in EFFECTS and follows_temperature(e)]
    if temperature:
        raise CalibrationError(f"--thermal with --add {temperature[0]}: every parameter already follows temperature "
                               "as a polynomial over the plateaus; a temperature effect within each plateau would "
                               "count it twice: leave it out")
    sets = [_plateau(f) for f in folders]
    T_k = [t for _, t in sets]
    if max(T_k) - min(T_k) < PLATEAU_SPREAD_C:
        raise CalibrationError(f"the plateaus' temperatures {[round(t, 2) for t in T_k]} degC span "
                               f"{max(T_k) - min(T_k):.2g} degC: too little to see a temperature dependence (the "
                               f"plateaus should differ by more than {PLATEAU_SPREAD_C:g} degC)")
    t_ref = float(np.mean(T_k)) if t_ref_c is None else float(t_ref_c)
    cals = []
    for ms, t in sets:
        cals.append(calibrate(ms, t_ref_c=t, **kwargs))  # each plateau at its own temperature
        check_layout(cals[0], ms, f"the first plateau ({sets[0][0].path})")
    plateaus = [str(ms.path) for ms, _ in sets]
    first = cals[0]
    result = Calibration(f"thermal ({first.method} per plateau)", plateaus, [c.input_sha256 for c in cals],
                         first.layout, t_ref_c=t_ref, temperature_range_c=[min(T_k), max(T_k)],
                         unification=first.unification, not_calibrated=first.not_calibrated,
                         details=dict(first.details),  # the first plateau's checks (consistency, ...)
                         samples_sha256=[d for c in cals for d in c.samples_sha256 or []])
    for s in first.sensors:
        setattr(result, s, _thermal_block([getattr(c, s) for c in cals], T_k, t_ref, degree, s, plateaus))
    result.warnings = [f"{ms.path}: temp_c spans {np.ptp(ms.samples['temp_c']):.3g} degC, more than a plateau's "
                       f"{PLATEAU_SPREAD_C:g} degC (its parameters are taken at its mean {t:.4g} degC)"
                       for ms, t in sets if np.ptp(ms.samples["temp_c"]) > PLATEAU_SPREAD_C]
    result.warnings += [w for c in cals for w in c.warnings]
    return result
