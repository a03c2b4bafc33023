"""What a person reads, in the unit system asked (`--units si`, ``units="si"``): a calibration, a validation
report, a noise report and printed lines, converted once here by io/units.py's conversions (each value with its
label; a scale factor or an angle unchanged), so that every printer and page prints what it is given. The files
simucal writes keep the spec's units."""
from __future__ import annotations

import copy
import os
from dataclasses import replace
from pathlib import Path
from typing import Any, Iterable, TypeVar, cast

import numpy as np

from simucal.io import units
from simucal.io.calibration import Calibration, EffectValue, SensorBlock, SensorDetails

C = TypeVar("C", bound=Calibration)


def gravity_of(where: Any) -> float:
    """g in m/s^2 for a result made from `where` (a set's folder, or a list of them): the first set's meta.json
    gravity_mps2 where it is at hand, else the standard 9.80665 (units.gravity's default)."""
    first = where[0] if isinstance(where, list) and where else where
    path = Path(first) / "meta.json" if isinstance(first, (str, os.PathLike)) else None
    if path is None or not path.is_file():
        return units.DEFAULT_GRAVITY
    from simucal import io
    from simucal.errors import SimucalError
    try:
        return units.gravity(io.read_meta(path.parent))
    except (SimucalError, OSError):  # a set unreadable now: the standard, as for one not at hand
        return units.DEFAULT_GRAVITY


def lines_in(lines: Iterable[str], system: str, gravity_mps2: float) -> list[str]:
    """Printed lines with each quantity that carries its unit in the system asked (units.text_in_units)."""
    return [units.text_in_units(line, system, gravity_mps2) for line in lines]


def calibration_in(cal: C, system: str, gravity_mps2: float | None = None) -> C:
    """A copy of cal with every block's numbers in the system asked (itself for the spec's): bias, parameters,
    stds, effects, residual, thermal coefficients and the held-out errors, each with its label."""
    units.check_unit_system(system)
    if system == "spec":
        return cal
    g = gravity_of(cal.input) if gravity_mps2 is None else gravity_mps2
    return replace(cal, acc=None if cal.acc is None else _block_in(cal.acc, system, g),
                   gyro=None if cal.gyro is None else _block_in(cal.gyro, system, g))


def _block_in(b: SensorBlock, system: str, g: float) -> SensorBlock:
    def conv(value, label):
        return units.in_units(value, label, system, g)

    def factor(name):  # a parameter's (a polynomial's coefficient b_x.T1, per degC^k: its parameter's)
        return conv(1.0, b.param_units.get(name.split(".")[0], "1"))[0]
    bias, bias_unit = conv(b.bias, b.bias_unit)
    per_bias = conv(1.0, b.bias_unit)[0]
    std: dict[str, Any] = {n: v if v is None else np.asarray(v, float) * (per_bias if n == "bias" else factor(n))
                           for n, v in b.std.items()}  # M's and T's: dimensionless; a null std stays null
    effects = {e: EffectValue(conv(v.value, v.unit)[0], conv(v.std, v.unit)[0], conv(1.0, v.unit)[1], v.meaning,
                              v.term_of) for e, v in b.effects.items()}
    residual_rms, residual_unit = conv(b.residual_rms, b.residual_unit) if b.residual_unit else (b.residual_rms, None)
    details: dict[str, Any] = dict(b.details)
    cv = details.get("cross_validation")
    if cv and cv.get("unit"):
        details["cross_validation"] = {**cv, **{k: conv(cv[k], cv["unit"])[0] for k in ("in_sample_rms", "held_out_rms")
                                                if k in cv}, "unit": conv(1.0, cv["unit"])[1]}
    if details.get("covariance"):  # the common vocabulary's stds are drawn from it
        details["covariance"] = _covariance_in(details["covariance"], factor)
    if details.get("poorly_determined"):
        details["poorly_determined"] = {n: {**v, "std": v["std"] * factor(n)}
                                        for n, v in details["poorly_determined"].items()}
    return replace(b, bias=bias, bias_unit=bias_unit, params={n: v * factor(n) for n, v in b.params.items()}, std=std,
                   param_units={n: conv(1.0, u)[1] for n, u in b.param_units.items()}, effects=effects,
                   residual_rms=residual_rms, residual_unit=residual_unit, thermal=_thermal_in(b.thermal, factor),
                   details=cast(SensorDetails, details))


def _thermal_in(thermal, factor):
    """A copy of a block's temperature model with each polynomial's coefficients, stds, plateau estimates and
    their covariance by their parameter's factor."""
    if thermal is None:
        return None
    out = copy.deepcopy(thermal)
    for n, poly in out.get("parameters", {}).items():
        for key in ("coefficients", "std", "per_plateau", "per_plateau_std"):
            if poly.get(key) is not None:
                poly[key] = [None if v is None else v * factor(n) for v in poly[key]]
    if out.get("covariance"):
        out["covariance"] = _covariance_in(out["covariance"], factor)
    return out


def _covariance_in(cov, factor):
    """A covariance {names, matrix} with each entry by both its parameters' factors."""
    f = np.array([factor(n) for n in cov["names"]])
    return {**cov, "matrix": (np.asarray(cov["matrix"], float) * np.outer(f, f)).tolist()}


def validation_in(report: dict, system: str, gravity_mps2: float | None = None) -> dict:
    """A copy of a validation report with each check's errors and floor in the system asked, its texts too."""
    units.check_unit_system(system)
    if system == "spec":
        return report
    g = gravity_of(report.get("data")) if gravity_mps2 is None else gravity_mps2
    out = dict(report)
    out["checks"] = {s: [{**c, **{k: units.in_units(c[k], c["unit"], system, g)[0]
                                  for k in ("before_rms", "after_rms", "floor_rms")},
                          "unit": units.in_units(1.0, c["unit"], system, g)[1],
                          "what": units.text_in_units(c["what"], system, g)} for c in rows]
                     for s, rows in report["checks"].items()}
    return out


def noise_in(report: dict, system: str, gravity_mps2: float | None = None) -> dict:
    """A copy of a noise report with each axis's Allan deviation and every term (value, std, bound) in the
    system asked, each with its label."""
    units.check_unit_system(system)
    if system == "spec":
        return report
    g = gravity_of(report.get("data")) if gravity_mps2 is None else gravity_mps2
    out = copy.deepcopy(report)
    for s in ("acc", "gyro"):
        if s not in out:
            continue
        unit = out[s]["unit"]
        for ax in out[s]["axes"].values():
            if "adev" in ax:
                ax["adev"] = units.in_units(list(ax["adev"]), unit, system, g)[0]
            for t in ax.get("sheet", {}).values():
                t.update({k: units.in_units(t[k], t["unit"], system, g)[0] for k in ("value", "std", "bound_95")
                          if t.get(k) is not None}, unit=units.in_units(1.0, t["unit"], system, g)[1])
        out[s]["unit"] = units.in_units(1.0, unit, system, g)[1]
    return out
