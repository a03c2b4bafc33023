"""A thermal calibration's plateaus (one set each, or one set whose temperature ramps): each read and checked
(a plausible temp_c, each plateau given once, one IMU, temperatures that span enough to show a dependence),
and, for a method that fits each plateau alone, every parameter's polynomial over the plateaus' blocks
(fit/thermal.fit_polynomial). The joint fit of a turntable unit's rows is turntable/thermal.py's."""
from __future__ import annotations

import os

import numpy as np

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit.thermal import SPREAD_C, check_temp_c
from simucal.io import records, units
from simucal.io.calibration import SensorBlock
from simucal.io.details import SensorDetails


def refuse_repeated(sets) -> None:
    """One plateau given twice (the same folder, or a copy of its samples) would count its rows twice and
    fake the plateaus' agreement: refused, naming both paths."""
    seen: dict[tuple, object] = {}  # the samples' digests: the path first given them
    for ms in sets:
        key = tuple(ms.sample_digests())
        if key in seen:
            raise CalibrationError(f"{seen[key]} and {ms.path}: the same samples (sha256 of the sensor outputs) given "
                                   "twice as plateaus: give each temperature plateau once")
        seen[key] = ms.path


def plateau(folder: str | os.PathLike[str] | io.MeasurementSet) -> tuple[io.MeasurementSet, float]:
    """A plateau's set and its temperature (the mean of temp_c), refused without a plausible temp_c."""
    ms = folder if isinstance(folder, io.MeasurementSet) else io.read_set(folder)
    if "temp_c" not in ms.samples:
        other = {c: units.temperature_unit_in_name(c) for c in ms.samples}
        named = [f"{c} (named as {u})" for c, u in other.items() if u]
        raise CalibrationError(f"{ms.path / 'samples.csv'}: no temp_c column, so no plateau temperature: a thermal "
                               "calibration needs the unit's temperature on every row" + (
                                   f"; it has {', '.join(named)}: convert it to degC as column temp_c" if named
                                   else ""))
    return ms, float(check_temp_c(ms).mean())


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


def refuse_thermal_options(folders, degree, add) -> None:
    """Sets of several IMUs, a degree outside 0-3, and a temperature effect in add (every parameter already
    follows temperature): refused before any set is read whole."""
    _refuse_several_imus(folders)
    if degree is not None and not 0 <= degree <= 3:
        raise CalibrationError(f"--thermal-degree {degree}: between 0 and 3")
    from simucal.fit.augmented import follows_temperature
    from simucal.generated.effects import EFFECTS
    temperature = [e for e in add if e in EFFECTS and follows_temperature(e)]
    if temperature:
        raise CalibrationError(f"--thermal with --add {temperature[0]}: every parameter already follows temperature "
                               "as a polynomial inside the model; a temperature effect added to it would count it "
                               "twice: leave it out")


def reference_temperature(sets, t_ref_c) -> float:
    """T_ref (t_ref_c, else the plateaus' mean), refused where the plateaus (or one set's ramp) cannot show a
    temperature dependence."""
    T_k = [t for _, t in sets]
    if len(sets) == 1:
        T = sets[0][0].samples["temp_c"]
        if np.ptp(T) < SPREAD_C:
            raise CalibrationError(f"{sets[0][0].path / 'samples.csv'}: one set whose temp_c spans "
                                   f"{np.ptp(T):.2g} degC: a ramp of under {SPREAD_C:g} degC shows no "
                                   "temperature dependence; record a wider ramp, or give two or more plateaus")
    elif max(T_k) - min(T_k) < SPREAD_C:
        raise CalibrationError(f"the plateaus' temperatures {[round(t, 2) for t in T_k]} degC span "
                               f"{max(T_k) - min(T_k):.2g} degC: too little to see a temperature dependence (the "
                               f"plateaus should differ by more than {SPREAD_C:g} degC)")
    return float(np.mean(T_k)) if t_ref_c is None else float(t_ref_c)


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


def plateaus_block(blocks: list[SensorBlock], T_k, t_ref_c, degree, sensor, plateaus) -> SensorBlock:
    """One sensor's block from its blocks at each plateau: every parameter's polynomial, the block at T_ref
    (params = c_0)."""
    from dataclasses import replace

    from simucal.fit.augmented import AugmentedModel
    from simucal.fit.thermal import fit_polynomial
    _same_model(blocks, sensor, plateaus)
    first = blocks[0]
    names = list(first.params)
    fits = {n: fit_polynomial(T_k, [b.params[n] for b in blocks], [b.std[n] for b in blocks], t_ref_c, degree)
            for n in names}
    for n, f in fits.items():
        f.update({"per_plateau": [b.params[n] for b in blocks],
                  "per_plateau_std": np.array([b.std[n] for b in blocks], float).tolist()})
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
