"""What a person reads, in the unit system asked (`--units si`, ``units="si"``): a calibration, a validation
report, a noise report and printed lines, converted once here by io/units.py's conversions (each value with its
label; a scale factor or an angle unchanged), so that every printer and page prints what it is given. The files
simucal writes keep the spec's units."""
from __future__ import annotations

import copy
import os
from dataclasses import replace
from pathlib import Path
from typing import Any, Iterable, Mapping, TypeVar, cast

import numpy as np

from simucal.io import units
from simucal.io.results import PlanScore
from simucal.io.calibration import Calibration, EffectValue, SensorBlock
from simucal.fit.results import SensorDiagnosis
from simucal.io.details import SensorDetails
from simucal.report.lot_figures import LotReport

C = TypeVar("C", bound=Calibration)
Report = TypeVar("Report", bound="Mapping[str, Any]")  # a JSON report, returned converted in the type it was given


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
    if details.get("static_rows"):
        details["static_rows"] = _static_rows_in(details["static_rows"], system, g)
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


def validation_in(report: Report, system: str, gravity_mps2: float | None = None) -> Report:
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
    return cast(Report, out)


def noise_in(report: Report, system: str, gravity_mps2: float | None = None) -> Report:
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


def diagnosis_in(report: Report, system: str, gravity_mps2: float | None = None) -> Report:
    """A copy of a diagnosis with each sensor's residuals, noise floor, candidates' estimates, added effects'
    parameters and the plots' points in the system asked, each with its label, and its verdicts written anew
    from those numbers (a sentence without numbers behind it converted as printed)."""
    from simucal.report.verdicts import sensor_verdict
    units.check_unit_system(system)
    if system == "spec":
        return report
    g = gravity_of(report.get("input")) if gravity_mps2 is None else gravity_mps2
    out: Any = copy.deepcopy(report)  # its blocks are free-form documents
    done: set[int] = set()  # done: the dicts converted, one object may sit in two places

    def conv(d, labels):  # labels: {key: its unit label}
        if id(d) not in done:
            done.add(id(d))
            d.update({k: units.in_units(d[k], u, system, g)[0]
                      for k, u in labels.items() if u and d.get(k) is not None})

    def candidate(c, residual_unit):
        if id(c) not in done:
            conv(c, {"residual_rms_after": residual_unit, "estimate": c.get("unit"), "std": c.get("unit")})
            c["unit"] = units.in_units(1.0, c["unit"], system, g)[1] if c.get("unit") else c.get("unit")
    for s in ("acc", "gyro"):
        if s not in out:
            continue
        b = out[s]
        unit = residual_unit = (b.get("model_test") or {}).get("residual_unit")  # a row's residual's too
        for test in (b.get("model_test"), b.get("baseline")):
            _test_in(test, conv, system, g)
        for c in b.get("candidates", []):
            candidate(c, residual_unit)
        for row in b.get("residuals", []) + b.get("added", {}).get("residuals_before", []):
            conv(row, {"residual": unit, "sigma": unit})
        for step in (b.get("misfit_shares") or {}).get("steps", []):  # the effects chosen over a stream's moves
            conv(step, {"residual_rms_after": residual_unit})
        if b.get("shape"):
            conv(b["shape"], {"residual_rms_after": residual_unit})
            conv(b["shape"]["points"], {"residual": unit, "term_visible": unit})
            b["shape"]["text"] = units.text_in_units(b["shape"]["text"], system, g)
        if b.get("added"):
            _added_in(b, conv, system, g)
        if unit and units.si_unit(unit, g) is not None:  # not a whitened or a direction's residual
            b["unit"] = units.in_units(1.0, unit, system, g)[1]
        b["verdict"] = sensor_verdict(b, s)
    if out.get("stream"):
        conv(out["stream"], {"acc_norm_g": "g"})
        out["stream"]["one_g"], out["stream"]["acc_norm_unit"] = units.in_units(1.0, "g", system, g)
    for c in out.get("candidates", []):  # the sensors' merged (the same rows, apart where read from a file)
        candidate(c, (report.get(c["id"].split(".")[0], {}).get("model_test") or {}).get("residual_unit"))
    out["verdict"] = " | ".join(out[s]["verdict"] for s in ("acc", "gyro") if s in out)
    out["notes"] = lines_in(out.get("notes", []), system, g)
    return out


def param_units_of(block: SensorDiagnosis) -> dict[str, str]:
    """Each parameter's unit label of a diagnosis block (the spec's): its model's, an added effect's from the
    effect library."""
    from simucal.generated.effects import EFFECTS
    names = block["added"]["params"] if "added" in block else {}
    return {**{e: EFFECTS[e].unit for e in names if e in EFFECTS}, **block.get("param_units", {})}


def _test_in(test, conv, system, g):
    """A model test's residual, floor and held-out errors in the system asked, and its label."""
    if test is None or not test.get("residual_unit"):
        return
    label = test["residual_unit"]
    conv(test, dict.fromkeys(("residual_rms", "noise_floor", "noise_std_of_mean"), label))
    cv = test.get("cross_validation")
    if cv and cv.get("unit"):
        conv(cv, dict.fromkeys(("held_out", "in_sample", "held_out_rms", "in_sample_rms"), cv["unit"]))
        cv["unit"] = units.in_units(1.0, cv["unit"], system, g)[1]
    if test.get("static_rows"):
        test["static_rows"] = _static_rows_in(test["static_rows"], system, g)
    test["residual_unit"] = units.in_units(1.0, label, system, g)[1]


def _added_in(b, conv, system, g):
    """diagnose --add's residuals before and after and every parameter before and after, each by its unit."""
    a = b["added"]
    label = a.get("residual_unit")
    conv(a, dict.fromkeys(("residual_rms_before", "residual_rms_after"), label))
    a["residual_unit"] = units.in_units(1.0, label, system, g)[1] if label else label
    spec_units = param_units_of(b)
    for name, row in a["params"].items():
        unit = spec_units.get(name)
        conv(row, dict.fromkeys(("before", "std_before", "after", "std_after", "truth", "error_before", "error_after"),
                                unit))
        row["unit"] = units.in_units(1.0, unit, system, g)[1] if unit else unit
    b["param_units"] = {n: units.in_units(1.0, u, system, g)[1] for n, u in b.get("param_units", {}).items()}


def _static_rows_in(st: dict, system: str, g: float) -> dict:
    """A gyro's static-rows test with its verdict written from its residual and noise in the system asked."""
    if "residual_rms_dph" not in st:
        return st
    from simucal.turntable.model_test import static_rows_verdict
    return {**st, "verdict": static_rows_verdict(st, *units.in_units(1.0, "deg/h", system, g)[::-1])}


def lot_in(report: LotReport, system: str, gravity_mps2: float = units.DEFAULT_GRAVITY) -> LotReport:
    """A copy of a lot report with each parameter's values, stds, centre and spreads and the spec limits in the
    system asked (the units' reasons and the verdict, sentences, from their printed digits)."""
    units.check_unit_system(system)
    if system == "spec":
        return report
    out: Any = copy.deepcopy(report)  # converted in place, each record by its unit
    for grp in out["groups"]:
        for p in grp["parameters"]:
            f, label = units.in_units(1.0, p["unit"], system, gravity_mps2)
            p.update({k: [None if v is None else v * f for v in p[k]] for k in ("values", "stds") if k in p})
            p.update({k: p[k] * f
                      for k in ("centre", "spread", "spread_of_units", "median_std") if p.get(k) is not None},
                     unit=label)
    for lim in out["limits"].values():
        f, label = units.in_units(1.0, lim.get("unit", "1"), system, gravity_mps2)
        lim.update({k: lim[k] * f for k in ("min", "max") if k in lim}, **({"unit": label} if "unit" in lim else {}))
    for u in out["units"]:
        u["why"] = lines_in(u["why"], system, gravity_mps2)
    out["verdict"] = lines_in(out["verdict"], system, gravity_mps2)
    return out


def montecarlo_in(result: Report, system: str, gravity_mps2: float = units.DEFAULT_GRAVITY) -> Report:
    """A copy of a Monte Carlo's result with each parameter's truth, mean, std and CRLB in the system asked."""
    units.check_unit_system(system)
    if system == "spec":
        return result
    shown = {}
    for name, v in result["parameters"].items():
        f, label = units.in_units(1.0, v["unit"], system, gravity_mps2)
        shown[name] = {**v, **{k: v[k] * f for k in ("truth", "mean", "std", "crlb") if v.get(k) is not None},
                       "unit": label}
    return cast(Report, {**result, "parameters": shown})


def plan_in(result: PlanScore, system: str, gravity_mps2: float = units.DEFAULT_GRAVITY) -> PlanScore:
    """A copy of a plan's score with its noise and each parameter's CRLB in the system asked, each with its label."""
    units.check_unit_system(system)
    if system == "spec":
        return result
    crlb = {k: units.in_units(v, result["units"][k], system, gravity_mps2) for k, v in result["crlb"].items()}
    noise, unit = units.in_units(result["noise"], result["unit"], system, gravity_mps2)
    return {**result, "noise": noise, "unit": unit, "crlb": {k: v for k, (v, _) in crlb.items()},
            "units": {k: u for k, (_, u) in crlb.items()}}
