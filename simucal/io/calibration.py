"""The calibration file: one versioned format, written by every method, read back by `apply`.

Format `simucal.calibration/2` (JSON). Units everywhere: accelerometer in g,
gyro in deg/h, after dividing the raw outputs by the nominal scale factors of
the data's meta.json (so for `counts` a raw ADC offset shows in `bias` as
offset / counts_per_g, in g). Top level:

    format, method, input, input_sha256,
    layout      the data's units and nominal scale factors; apply refuses data
                with another layout (another sensor or unit)
    formula     how an output relates to its input (below), per sensor
    acc, gyro   one block each (absent when the data had none)
    unification C_b^d and how it was found (turntable gyro)
    t_ref_c, temperature_range_c   where the data have temp_c: the reference
                temperature T_ref of temperature terms (they read temp_c - T_ref,
                so bias and M are the unit's at T_ref) and the range calibrated

Each sensor block:

    model        the generated model of the forward function h ("affine" for
                 y = M u + bias), model_source "built-in" or the user's file
    effects      {id: {value, std, unit, meaning}}: candidate effects added
    params, std, param_units   every parameter of h (std inflated by the misfit
                 when the model fails; std_raw then holds the unscaled ones)
    M, bias      the linear part in frame b: output = M u_b + bias + nonlinear terms
    C_b_model    the rotation from b to the model's own frame (gyro: C_b^d), so
                 output = h(C_b_model u_b, p)
    residual_rms, residual_unit, chi2, dof, p_value, test, verdict

Direction: the calibration maps input to output (the sensor model). `apply`
inverts it: u_b = C_b_model^T h^-1(output), Newton per sample for nonlinear terms.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from simucal.errors import CalibrationError
from simucal.io import outputs, units

FORMAT = "simucal.calibration/2"
FORMULA = {
    "acc": "a_g = a_raw / nominal scale (meta.json); a_g = h_acc(f_b, p) = M f_b + bias + effects; "
           "f_b: specific force in the accelerometer frame b, g",
    "gyro": "w_out = w_raw / nominal scale; w_out = h_gyro(C_b_model w_b, p) = M w_b + bias + effects; "
            "w_b: angular rate in b, deg/h; g-sensitivity terms take the specific force in the model's frame, g",
}
LAYOUT_KEYS = ("acc_unit", "gyro_unit", "acc_pulses_per_g", "gyro_pulses_per_arcsec", "acc_counts_per_g",
               "gyro_counts_per_dps")


class CalibrationFileError(ValueError):
    """A calibration file that cannot be read, or that does not fit the data."""


def input_sha256(folder) -> str:
    h = hashlib.sha256()
    for name in ("meta.json", "segments.csv", "samples.csv"):
        p = Path(folder) / name
        if p.is_file():
            h.update(name.encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


SERIAL = "unit_serial"  # meta.json's optional serial number of the unit (README: the spec's extension)


def layout(ms) -> dict:
    out = {k: ms.meta[k] for k in LAYOUT_KEYS + (SERIAL,) if k in ms.meta}
    out["sensors"] = [s for s, has in (("acc", ms.has_acc), ("gyro", ms.has_gyro)) if has]
    return out


def header(method: str, ms) -> dict:
    out = {"format": FORMAT, "method": method, "input": str(ms.path), "input_sha256": input_sha256(ms.path),
           "layout": layout(ms), "formula": {s: FORMULA[s] for s in layout(ms)["sensors"]},
           "units": {"acc": "g", "gyro": "deg/h", "angles": "rad"}}
    if ms.t_ref_c is not None:  # temperature terms read dtemp_c = temp_c - t_ref_c; apply takes it from here
        temp = ms.samples["temp_c"]
        out.update(t_ref_c=ms.t_ref_c, temperature_range_c=[float(np.min(temp)), float(np.max(temp))])
    return out


def effect_entry(value, std, unit, meaning, term_of=None) -> dict:
    """One added effect in a sensor block's `effects`: a library effect (by its id), or a term of a
    user's model file beyond the baseline (by its parameter name, term_of the model's name)."""
    return {"value": float(value), "std": float(std), "unit": unit, "meaning": meaning,
            **({"term_of": term_of} if term_of else {})}


def library_effects(block) -> tuple[str, ...]:
    """The library effect ids a block's model adds (its `effects` less a model file's own terms)."""
    return tuple(e for e, v in block["effects"].items() if not (isinstance(v, dict) and v.get("term_of")))


def _user_terms(model, fit) -> dict:
    """A user's model file's terms beyond its sensor's baseline, as effect entries."""
    return {n: effect_entry(fit.params[n], fit.std[n], u, m, model.base.name)
            for n, u, m in zip(model.base.params, model.base.param_units, model.base.meanings)
            if n in model.model_file_terms}


def sensor_block(model, fit, M, bias, base: dict | None = None, C_b_model=None) -> dict:
    """The block of one sensor from a norm fit of `model` (an AugmentedModel)."""
    effects = {e: effect_entry(fit.params[e], fit.std[e], u, m)
               for e, u, m in zip(model.effects, model.param_units[len(model.base.params):],
                                  model.meanings[len(model.base.params):])}
    effects.update(_user_terms(model, fit))
    block = {"model": model.base.name, "model_source": model.base.source, "effects": effects,
             "M": np.asarray(M).tolist(), "bias": np.asarray(bias).tolist(),
             "bias_unit": model.unit, "params": dict(fit.params), "std": dict(fit.std),
             "param_units": dict(zip(model.params, model.param_units)),
             "residual_rms": fit.residual_rms, "residual_unit": model.unit,
             "chi2": fit.chi2, "dof": fit.dof, "p_value": fit.p_value}
    poor = poorly_determined(model.params, fit)
    if poor:
        block["poorly_determined"] = poor
    if C_b_model is not None:
        block["C_b_model"] = np.asarray(C_b_model).tolist()
    if base is not None:
        block.update(p_value=base["p_value"], test=base["test"], noise=base["noise"],
                     lack_of_fit=base["lack_of_fit"], cross_validation=base.get("cross_validation"),
                     **{k: base[k] for k in ("rows", "noise_warning", "noise_too_small") if base.get(k)})
    return block


POOR_INFLATION = 10.0  # good plans give 1-2 (Table 1, fibonacci48, a hand-placed session)


def poorly_determined(names, fit) -> dict:
    """Parameters whose std the plan inflates more than POOR_INFLATION times by their correlation with
    the others: sqrt of the variance inflation factor, VIF_j = (R^-1)_jj for the correlation matrix R
    of the fit's covariance (1 for a parameter the plan separates from all others). A near-singular
    plan (gravity directions on one great circle) gives thousands. Parameters held by a prior are
    listed as undetermined instead."""
    cov = np.asarray(fit.cov, float)
    d = np.sqrt(np.diag(cov))
    if cov.shape != (len(names), len(names)) or not np.all(d > 0):
        return {}
    lam, V = np.linalg.eigh(cov / np.outer(d, d))
    inflation = np.sqrt((V ** 2 / np.maximum(lam, 1e-300)).sum(axis=1))
    return {n: {"std": float(fit.std[n]), "inflation": float(k)} for n, k in zip(names, inflation)
            if k > POOR_INFLATION and n not in fit.undetermined}


def affine_block(sensor: str, M, bias, std: dict, residual_rms: float, model: str, **extra) -> dict:
    """The block of a method without a generated model: output = M u_b + bias."""
    unit = "g" if sensor == "acc" else "deg/h"
    return {"model": "affine", "description": model, "model_source": "built-in", "effects": {},
            "M": np.asarray(M).tolist(), "bias": np.asarray(bias).tolist(), "bias_unit": unit,
            "std": std, "residual_rms": residual_rms, "residual_unit": extra.pop("residual_unit", unit), **extra}


def inflate_if_failing(block: dict, alpha: float = 1e-3) -> bool:
    """When the model fails (p < alpha), scale every std by sqrt(chi2/dof), the misfit the
    noise does not explain, and keep the unscaled ones as std_raw. Returns whether it failed."""
    p, chi2, dof = block.get("p_value"), block.get("chi2"), block.get("dof")
    if p is None or p >= alpha:
        return False
    if chi2 is not None and dof:
        k = float(np.sqrt(chi2 / dof))
        if k > 1:
            block["std_raw"] = block["std"]
            block["std"] = {n: v * k for n, v in block["std"].items()}
            block["std_note"] = (f"the model fails (p = {p:.2g}); std = std_raw * sqrt(chi2/dof) = std_raw * {k:.3g}, "
                                 "so it includes the misfit; std_raw assumes the model is right")
    return True


def save(path, cal: dict) -> None:
    path = Path(path)
    if not path.parent.is_dir():
        raise CalibrationFileError(f"{path}: the folder {path.parent} does not exist")
    outputs.write_text(path, json.dumps(cal, indent=2, default=float) + "\n")


def load(path) -> dict:
    """A calibration file, checked before any of it is used (check_file)."""
    path = Path(path)
    try:
        cal = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CalibrationFileError(f"{path}: not a readable calibration file ({e})") from None
    fmt = cal.get("format") if isinstance(cal, dict) else None
    if fmt != FORMAT:
        raise CalibrationFileError(f"{path}: format {fmt!r}, expected {FORMAT!r}"
                                   + ("; calibrate the data again with this version" if fmt else ""))
    check_file(path, cal)
    return cal


# Beyond these no sensor block is physics: a hand-edited or corrupted file, refused naming the entry.
SCALE_RANGE = (0.5, 2.0)      # M's diagonal after the nominal scale factors
SMALL_UNITS = ("1", "rad")    # scale-factor errors and misalignments: |p| <= 0.5
PARAM_LIMIT = 1e6             # any other parameter, in its unit
BIAS_LIMIT = {"acc": 16.0, "gyro": 7.2e6}  # 16 g; 2000 deg/s in deg/h


def bias_limit(layout, sensor) -> float:
    """BIAS_LIMIT, or for raw counts the span of an unsigned 16-bit register at the nominal scale
    (the bias then holds the register's zero offset too)."""
    per = layout.get(f"{sensor}_counts_per_{'g' if sensor == 'acc' else 'dps'}")
    if layout.get(f"{sensor}_unit") != "counts" or not per:
        return BIAS_LIMIT[sensor]
    span = 2.0 ** 16 / min(per) * (1.0 if sensor == "acc" else units.DPH_PER_DPS)
    return max(BIAS_LIMIT[sensor], span)


def _matrix(path, where, value, shape):
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise CalibrationFileError(f"{path}: {where} is not a {shape[0]}x{shape[1] if len(shape) > 1 else ''} "
                                   "array of numbers".replace("x ", " ")) from None
    if a.shape != shape:
        raise CalibrationFileError(f"{path}: {where} has shape {list(a.shape)}, expected {list(shape)}")
    if not np.all(np.isfinite(a)):
        raise CalibrationFileError(f"{path}: {where} holds NaN or infinite entries")
    return a


def check_file(path, cal: dict) -> None:
    """Refuse a calibration that cannot be physics before it is applied: missing keys, shapes,
    NaN, a C_b_model that is not a proper rotation, scale factors outside SCALE_RANGE, a
    reversed axis, implausible parameters, unknown effects. Each refusal names the entry."""
    from simucal.generated.effects import EFFECTS
    lay = cal.get("layout")
    if not isinstance(lay, dict) or not isinstance(lay.get("sensors"), list):
        raise CalibrationFileError(f"{path}: lacks 'layout' (the data's units and sensors, written by simucal "
                                   "calibrate): it was not written by this version, or was edited; calibrate again")
    for s in lay["sensors"]:
        block = cal.get(s)
        if s not in ("acc", "gyro") or not isinstance(block, dict):
            raise CalibrationFileError(f"{path}: layout names sensor {s!r}, but the file has no {s} block")
        for k in ("model", "M", "bias", "effects"):
            if k not in block:
                raise CalibrationFileError(f"{path}: the {s} block lacks {k!r}")
        M = _matrix(path, f"{s}.M", block["M"], (3, 3))
        bias = _matrix(path, f"{s}.bias", block["bias"], (3,))
        diag = np.diag(M)
        if np.any(diag <= 0):
            raise CalibrationFileError(f"{path}: {s}.M has diagonal {np.round(diag, 4).tolist()}: a reversed axis; "
                                       "no calibration of a unit at its nominal signs has one")
        if np.any(diag < SCALE_RANGE[0]) or np.any(diag > SCALE_RANGE[1]) or np.linalg.det(M) <= 0:
            raise CalibrationFileError(f"{path}: {s}.M has diagonal {np.round(diag, 4).tolist()} (det "
                                       f"{np.linalg.det(M):.3g}): scale factors outside {SCALE_RANGE} of nominal "
                                       "are not a calibration of this unit")
        limit = bias_limit(lay, s)
        if np.any(np.abs(bias) > limit):
            raise CalibrationFileError(f"{path}: {s}.bias {bias.tolist()} is beyond any sensor's range "
                                       f"(|bias| <= {limit:.3g} {'g' if s == 'acc' else 'deg/h'})")
        if "C_b_model" in block:
            C = _matrix(path, f"{s}.C_b_model", block["C_b_model"], (3, 3))
            if np.abs(C.T @ C - np.eye(3)).max() > 1e-6 or np.linalg.det(C) < 0:
                raise CalibrationFileError(f"{path}: {s}.C_b_model is not a proper rotation (C^T C - I up to "
                                           f"{np.abs(C.T @ C - np.eye(3)).max():.2g}, det {np.linalg.det(C):.4g})")
        params = block.get("params", {})
        units = block.get("param_units", {})
        if not isinstance(params, dict):
            raise CalibrationFileError(f"{path}: {s}.params must be an object {{name: value}}")
        for name, v in params.items():
            unit = units.get(name, "1")
            limit = 0.5 if unit in SMALL_UNITS else PARAM_LIMIT
            if not isinstance(v, (int, float)) or not np.isfinite(v) or abs(v) > limit:
                raise CalibrationFileError(f"{path}: {s}.params.{name} = {v!r} is not a plausible value (finite, "
                                           f"|value| <= {limit:g}{'' if unit == '1' else ' ' + unit})")
        if not isinstance(block["effects"], dict):
            raise CalibrationFileError(f"{path}: {s}.effects must be an object {{id: {{value, ...}}}}")
        for e, entry in block["effects"].items():
            if e not in EFFECTS and not (isinstance(entry, dict) and entry.get("term_of") == block["model"]):
                raise CalibrationFileError(f"{path}: {s}.effects names {e!r}, which is no library effect "
                                           "(simucal diagnose lists them)")
            v = entry.get("value") if isinstance(entry, dict) else None
            if not isinstance(v, (int, float)) or not np.isfinite(v) or abs(v) > PARAM_LIMIT:
                raise CalibrationFileError(f"{path}: {s}.effects.{e}.value = {v!r} is not a plausible value")


SCALE_NOTE = 0.1  # a scale factor this far from 1 after the nominal ones: the nominal is likely wrong


def scale_notes(cal: dict, meta: dict) -> list[str]:
    """Lines naming implausible scale factors of a fresh calibration (M's diagonal, after dividing by
    the nominal scale factors of meta.json); a reversed axis (diagonal <= 0) is refused instead."""
    lines = []
    for s in cal["layout"]["sensors"]:
        if s not in cal:
            continue
        diag = np.diag(np.asarray(cal[s]["M"], float))
        nominal = ", ".join(f"{k} = {meta[k]}" for k in LAYOUT_KEYS if k.startswith(s) and k in meta)
        if np.any(diag <= 0):
            axes = ", ".join("xyz"[i] for i in np.nonzero(diag <= 0)[0])
            raise CalibrationError(
                f"{s}: scale factors {np.round(diag, 3).tolist()}, negative on {axes}, which no unit at its nominal "
                "signs has: one axis of the accelerometer or gyro triad has its sign flipped (a column written as "
                "65536 - value, an axis wired reversed, or a left-handed frame); the norm cannot tell which triad: "
                "check the sign of every column in samples.csv against the unit's axes and calibrate again")
        far = np.abs(diag - 1) > SCALE_NOTE
        if np.any(far):
            lines.append(f"{s}: scale factors {np.round(diag, 4).tolist()} after dividing by the nominal ones "
                         f"({nominal or 'the unit in meta.json'}): "
                         f"{', '.join('xyz'[i] for i in np.nonzero(far)[0])} more than {SCALE_NOTE:.0%} from 1; "
                         "the nominal scale factor or the unit is likely wrong (the calibration corrects it, but "
                         "check meta.json)")
    return lines


def check_layout(cal: dict, ms, where) -> None:
    """Refuse data of another unit, nominal scale or sensor set than the calibration's."""
    mine, theirs = cal["layout"], layout(ms)
    if SERIAL in mine and SERIAL in theirs and str(mine[SERIAL]) != str(theirs[SERIAL]):
        raise CalibrationFileError(f"{ms.path}: unit_serial is {theirs[SERIAL]!r}, but {where} was made for unit "
                                   f"{mine[SERIAL]!r}: calibrate this unit's own data")
    for s in theirs["sensors"]:
        if s not in mine["sensors"] or s not in cal:
            raise CalibrationFileError(f"{ms.path}: has {s} data, but {where} calibrates no {s}")
    for k in LAYOUT_KEYS:
        sensor = k.split("_")[0]
        if sensor in theirs["sensors"] and mine.get(k) != theirs.get(k):
            raise CalibrationFileError(f"{ms.path}: {k} is {theirs.get(k)!r}, but {where} was made for "
                                       f"{mine.get(k)!r}: another sensor or unit; calibrate this sensor's own data")
