"""`simucal apply`: a calibration file applied to raw outputs, giving inputs in g and deg/h.

The calibration gives output = h(C u_b, p) (simucal.calibration); apply solves
it for u_b per sample: the linear start u = M^-1 (output - bias), then Newton
steps u <- u - (dh/du)^-1 (h(u) - output) until the step is below 1e-12 of |u|
(nonlinear effect terms converge in 2-4 steps; affine models need none).
Accelerometers first: their calibrated specific force feeds the gyros'
g-sensitivity terms. Written as a measurement set in g and deg/h, in frame b,
with the same segments (and rate runs' centripetal scale for lever arms).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from simucal import io
from simucal.errors import CalibrationError, InputError
from simucal.fit.augmented import AugmentedModel, effect_terms, follows_temperature
from simucal.fit.aux_inputs import AuxInputs, columns_at, specific_force
from simucal.fit.row_solve import solve_rows
from simucal.fit.thermal import params_at, rate_input
from simucal.io import units
from simucal.io.calibration import Calibration, SensorBlock
from simucal.io.calibration_checks import LAYOUT_KEYS, check_layout


KELVIN_HINT = "; temp_c looks like kelvin (273-400): convert to degC (subtract 273.15)"  # every row 250-400

def _affine_effects(block: SensorBlock):
    """h(u) = M u + bias + sum_j p_j phi_j(u) e_axis(j), for blocks without a generated model."""
    M, bias, ids = block.M, block.bias, block.library_effects()
    values = [block.effects[e].value for e in ids]

    def h(u, aux: AuxInputs):
        N = u @ M.T + bias
        J = np.broadcast_to(M, u.shape + (3,)).copy()
        for p, (axis, phi, dphi) in zip(values, effect_terms(ids, u, aux)):
            N[:, axis] += p * phi
            J[:, axis, :] += p * np.broadcast_to(dphi, u.shape)
        return N, J
    return h


def model_function(model: AugmentedModel, p, C=np.eye(3)):
    """h(u_b) = model output at C u_b with parameters p, and dh/du_b."""
    def h(u_b, aux: AuxInputs):
        N, Ju, _ = model.jacobians(u_b @ C.T, p, aux)
        return N, Ju @ C
    return h


EDITED = 1e-9  # M and bias recomputed from params agree with the file's to round-off; anything more is an edit


def _params(block: SensorBlock, model):
    return np.array([block.params[k] for k in model.params], float)


def rowwise_function(model: AugmentedModel, P, C=np.eye(3), fixed=None):
    """h(u_b) with parameters P (n, m), one row's each (a thermal calibration at each row's temp_c, a
    leave-one-out refit per row): every row a batch of one, so the model's batched form takes it.
    fixed: auxiliary inputs held at a value for every row."""
    def h(u_b, aux: AuxInputs):
        one = AuxInputs({k: (np.asarray(v)[:, None] if np.ndim(v) else v)
                         for k, v in aux.with_values(**(fixed or {})).values.items()})
        N, Ju, _ = model.jacobians((u_b @ C.T)[:, None, :], P, one)
        return N[:, 0], Ju[:, 0] @ C
    return h


def thermal_function(model: AugmentedModel, P, C=np.eye(3)):
    """rowwise_function at each row's parameters of a thermal calibration, with dtemp_c 0: the
    parameters follow temperature themselves (a model file's terms in dtemp_c were fitted within
    each plateau, around its own temperature)."""
    return rowwise_function(model, P, C, {"dtemp_c": 0.0})


def _generated(block: SensorBlock, temp_c):
    model = AugmentedModel(block.model, block.library_effects())
    if block.thermal is not None:
        return thermal_function(model, params_at(block.thermal, model.params, temp_c), block.C)
    return model_function(model, _params(block, model), block.C)


def check_block(block: SensorBlock, sensor, where) -> None:
    """Refuse a block whose parts tell different stories: params against M, bias and C_b_model for
    a generated model; T against M for a stream's gyro. A hand edit of one of them would otherwise
    be used, or ignored, silently."""
    if block.model == "affine":
        T = block.details.get("T")
        if T is not None and np.abs(np.asarray(T, float) @ block.M - np.eye(3)).max() > 1e-6:
            raise CalibrationError(f"{where}: {sensor}.T is not the inverse of {sensor}.M (T = M^-1): the file was "
                                   "edited by hand; calibrate again")
        return
    try:
        model = AugmentedModel(block.model, block.library_effects())
    except InputError as e:  # a model this machine has not derived (another's cache), or an edit
        raise CalibrationError(f"{where}: {sensor}.model {block.model!r}: {e.args[0]}") from None
    missing = [k for k in model.params if k not in block.params]
    if missing:
        raise CalibrationError(f"{where}: {sensor}.params lacks {missing[0]!r}, a parameter of model {block.model} "
                               "(the file was edited, or names another sensor's model); calibrate again")
    if "M_in_d" in block.details and block.C_b_model is None:
        raise CalibrationError(f"{where}: the {sensor} block has M in its own frame (M_in_d) but no C_b_model, the "
                               "rotation that ties it to b: the file was edited by hand; calibrate again")
    if block.thermal is not None:
        _check_thermal(block, sensor, model.params, where)
    M_p, b_p = model.matrix_and_bias(_params(block, model))
    for name, mine, theirs in (("M", M_p @ block.C, block.M), ("bias", b_p, block.bias)):
        diff = np.abs(mine - theirs).max()
        if diff > EDITED * max(1.0, np.abs(mine).max()):
            raise CalibrationError(f"{where}: {sensor}.{name} disagrees with what {sensor}.params give (largest "
                                   f"difference {diff:.3g}): the file was edited by hand; calibrate again rather "
                                   "than edit a calibration")


def _check_thermal(block: SensorBlock, sensor, names, where) -> None:
    """A thermal section with a finite polynomial for every parameter, c_0 the parameter itself."""
    th = block.thermal
    assert th is not None  # check_block checks a thermal block's only
    ok = isinstance(th, dict) and isinstance(th.get("t_ref_c"), (int, float)) and isinstance(th.get("parameters"), dict)
    for n in names if ok else ():
        c: Any = th["parameters"].get(n, {}).get("coefficients") if isinstance(th["parameters"].get(n), dict) else None
        good = (isinstance(c, list) and 0 < len(c) <= 4
                and all(isinstance(x, (int, float)) and np.isfinite(x) for x in c))
        if not good or abs(c[0] - block.params[n]) > EDITED * max(1.0, abs(c[0])):
            ok = False
            break
    if not ok:
        raise CalibrationError(f"{where}: {sensor}.thermal lacks a polynomial for a parameter, holds non-numbers, or "
                               "disagrees with params (c_0 is the parameter at T_ref): the file was edited by hand; "
                               "calibrate again")


def solve_inputs(h, M, bias, N, aux: AuxInputs, sensor, where) -> np.ndarray:
    """u_b with h(u_b) = N, every row (n, 3): linear start M^-1 (N - bias), then Newton."""
    u = np.linalg.solve(M, (N - bias).T).T
    # per row: 1e-11 of its size, or of 1e-6 of the largest input (rows at rest are near 0)
    tol = 1e-11 * np.maximum(np.abs(u).max(axis=1), 1e-6 * max(np.abs(u).max(), 1e-300))
    for _ in range(30):
        r, J = h(u, aux)
        du = solve_rows(J, (r - N)[..., None])[..., 0]
        u = u - du
        if np.all(np.abs(du).max(axis=1) <= tol):
            return u
    bad = np.nonzero(np.abs(du).max(axis=1) > 100 * tol)[0]
    if not len(bad):
        return u  # at round-off
    raise CalibrationError(f"{where}: the {sensor} model could not be inverted at {len(bad)} samples "
                           f"(rows {(bad[:5] + 2).tolist()} of samples.csv): the output lies outside what the "
                           "calibrated model can produce")


def model_inputs(model: AugmentedModel, p, N, aux: AuxInputs, where) -> np.ndarray:
    """u with h(u, p) = N for every row (n, 3): the whole fitted model inverted, effects included
    (M^-1 (N - b) alone leaves a nonlinear term in u: on a stream with acc.quadratic.z added it put
    the poses' gravity directions 1.1e-3 rad off where the clean level is 1.5e-4)."""
    M, bias = model.matrix_and_bias(p)
    return solve_inputs(model_function(model, p), M, bias, N, aux, model.sensor, where)


def invert(block: SensorBlock, sensor, N, aux: AuxInputs, where, temp_c=None) -> np.ndarray:
    """u_b with h(u_b) = N for a calibration block, every row (n, 3); temp_c (n,): each row's
    temperature, for a thermal block."""
    h = _affine_effects(block) if block.model == "affine" else _generated(block, temp_c)
    return solve_inputs(h, block.M, block.bias, N, aux, sensor, where)


def apply(cal: Calibration, data, where="the calibration"):
    """(meta, samples, segments) of the calibrated set; data: its folder or the set already read."""
    ms = data if isinstance(data, io.MeasurementSet) else io.read_set(data)
    check_layout(cal, ms, where)
    for s, block in cal.blocks():
        check_block(block, s, where)
    n = len(ms.samples["t_s"])
    aux = AuxInputs({**columns_at(ms.samples, slice(None), t_ref_c=cal.t_ref_c),  # dT/dt where an effect reads it
                     **rate_input(ms.samples, [e for _, b in cal.blocks() for e in b.library_effects()])})
    temp_c, warnings = temperatures(cal, ms)
    samples = {k: v for k, v in ms.samples.items() if k not in io.SAMPLE_COLS}  # the keys and auxiliary columns
    f_b = None
    if ms.has_acc:
        assert cal.acc is not None  # check_layout refuses data of a sensor the calibration lacks
        rate = {s.segment: s.outer_rate_dps for s in (ms.segments or [])}
        w2 = (np.radians([rate.get(s, 0.0) for s in ms.samples["segment"]]) ** 2 / units.gravity(ms.meta)
              if "segment" in ms.samples else np.zeros(n))
        f_b = invert(cal.acc, "acc", ms.acc_g(), aux.with_values(w2=w2), ms.path / "samples.csv", temp_c)
        samples.update(ax=f_b[:, 0], ay=f_b[:, 1], az=f_b[:, 2])
    if ms.has_gyro:
        assert cal.gyro is not None
        f_model = f_b @ cal.gyro.C.T if f_b is not None else np.zeros((n, 3))
        w_b = invert(cal.gyro, "gyro", ms.gyro_dph(), aux.with_values(**specific_force(f_model)),
                     ms.path / "samples.csv", temp_c)
        samples.update(gx=w_b[:, 0], gy=w_b[:, 1], gz=w_b[:, 2])
    meta = {k: v for k, v in ms.meta.items() if k not in LAYOUT_KEYS + ("full_scale", "format")}
    meta.update(acc_unit="g", gyro_unit="deg/h",
                description=f"{ms.meta.get('description', '')} | calibrated by simucal apply "
                            f"({cal.method}, from {cal.input})".strip(" |"))
    if warnings:
        meta["warnings"] = warnings  # the spec keeps unknown keys: the warning travels with the data
    return meta, samples, ms.segments


def temperatures(cal: Calibration, ms) -> tuple[np.ndarray | None, list[str]]:
    """Each row's temp_c where a block of cal follows temperature (thermal, or terms in dtemp_c), and
    per such sensor a warning naming the rows outside its calibrated range (the polynomials are
    extrapolated there): a thermal block's own `temperature_range_c` (the temperatures its rows reached:
    a ramp's gyro rate runs may cover part of it), else the file's. A thermal calibration refuses data
    without temp_c."""
    thermal = [s for s, block in cal.blocks() if block.thermal is not None]
    if "temp_c" not in ms.samples:
        if thermal:
            raise CalibrationError(f"{ms.path / 'samples.csv'}: no temp_c column, but the calibration follows "
                                   f"temperature ({', '.join(thermal)}): it needs each row's temperature")
        return None, []
    temp, warnings = ms.samples["temp_c"], []
    follows = [(s, block) for s, block in cal.blocks() if getattr(ms, f"has_{s}") and (
        block.thermal is not None or any(follows_temperature(e) for e in block.library_effects()))]
    if follows:
        units.refuse_temperature_unit(ms.meta, ms.samples, ms.path, CalibrationError)
    for s, block in follows:
        lo, hi = (block.thermal or {}).get("temperature_range_c") or cal.temperature_range_c or (-np.inf, np.inf)
        out = np.nonzero((temp < lo - 1.0) | (temp > hi + 1.0))[0]  # 1 degC: a plateau's own scatter
        if len(out):
            warnings.append(f"{s}: {len(out)} of {len(temp)} rows (from line {out[0] + 2} of samples.csv) have temp_c "
                            f"{temp[out].min():.4g} to {temp[out].max():.4g} degC, outside the {s}'s calibrated "
                            f"{lo:.4g} to {hi:.4g} degC: their temperature terms are extrapolated" + KELVIN_HINT * bool(
                                np.all((temp >= 250.0) & (temp <= 400.0))))
    return temp, warnings
