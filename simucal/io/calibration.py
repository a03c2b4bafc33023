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


def layout(ms) -> dict:
    out = {k: ms.meta[k] for k in LAYOUT_KEYS if k in ms.meta}
    out["sensors"] = [s for s, has in (("acc", ms.has_acc), ("gyro", ms.has_gyro)) if has]
    return out


def header(method: str, ms) -> dict:
    return {"format": FORMAT, "method": method, "input": str(ms.path), "input_sha256": input_sha256(ms.path),
            "layout": layout(ms), "formula": {s: FORMULA[s] for s in layout(ms)["sensors"]},
            "units": {"acc": "g", "gyro": "deg/h", "angles": "rad"}}


def sensor_block(model, fit, M, bias, base: dict | None = None, C_b_model=None) -> dict:
    """The block of one sensor from a norm fit of `model` (an AugmentedModel)."""
    effects = {e: {"value": fit.params[e], "std": fit.std[e], "unit": u, "meaning": m}
               for e, u, m in zip(model.effects, model.param_units[len(model.base.params):],
                                  model.meanings[len(model.base.params):])}
    block = {"model": model.base.name, "model_source": model.base.source, "effects": effects,
             "M": np.asarray(M).tolist(), "bias": np.asarray(bias).tolist(),
             "bias_unit": model.unit, "params": dict(fit.params), "std": dict(fit.std),
             "param_units": dict(zip(model.params, model.param_units)),
             "residual_rms": fit.residual_rms, "residual_unit": model.unit,
             "chi2": fit.chi2, "dof": fit.dof, "p_value": fit.p_value}
    if C_b_model is not None:
        block["C_b_model"] = np.asarray(C_b_model).tolist()
    if base is not None:
        block.update(p_value=base["p_value"], test=base["test"], noise=base["noise"],
                     lack_of_fit=base["lack_of_fit"])
    return block


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


def write(path, cal: dict) -> None:
    path = Path(path)
    if not path.parent.is_dir():
        raise CalibrationFileError(f"{path}: the folder {path.parent} does not exist")
    path.write_text(json.dumps(cal, indent=2, default=float) + "\n")


def read(path) -> dict:
    path = Path(path)
    try:
        cal = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CalibrationFileError(f"{path}: not a readable calibration file ({e})") from None
    fmt = cal.get("format") if isinstance(cal, dict) else None
    if fmt != FORMAT:
        raise CalibrationFileError(f"{path}: format {fmt!r}, expected {FORMAT!r}"
                                   + ("; calibrate the data again with this version" if fmt else ""))
    for s in cal["layout"]["sensors"]:
        for k in ("model", "M", "bias", "effects"):
            if k not in cal.get(s, {}):
                raise CalibrationFileError(f"{path}: the {s} block lacks {k!r}")
    return cal


def check_layout(cal: dict, ms, where) -> None:
    """Refuse data of another unit, nominal scale or sensor set than the calibration's."""
    mine, theirs = cal["layout"], layout(ms)
    for s in theirs["sensors"]:
        if s not in mine["sensors"] or s not in cal:
            raise CalibrationFileError(f"{ms.path}: has {s} data, but {where} calibrates no {s}")
    for k in LAYOUT_KEYS:
        sensor = k.split("_")[0]
        if sensor in theirs["sensors"] and mine.get(k) != theirs.get(k):
            raise CalibrationFileError(f"{ms.path}: {k} is {theirs.get(k)!r}, but {where} was made for "
                                       f"{mine.get(k)!r}: another sensor or unit; calibrate this sensor's own data")
