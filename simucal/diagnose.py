"""Model versus measurement: where the model fails and which effect is missing.

For each sensor triad: the exact norm fit with the noise the data give,
residuals per segment and axis against the noise floor, the tests and the
candidate ranking of simucal.fit.candidates (one test for every diagnosis), the
shape of a misfit no candidate explains (with a model file for it), and with
--add the parameters and the residual before and after.
"""
from __future__ import annotations

import heapq
from pathlib import Path

import numpy as np

from simucal import io, methods
from simucal.errors import CalibrationError
from simucal.fit.augmented import AugmentedModel
from simucal.fit.candidates import test_model
from simucal.io.text_files import json_object_or_none
from simucal.report.console import skipped_sensors
from simucal.report.verdicts import sensor_verdict
from simucal.fit.norm_fit import Fit, Observations
from simucal.fit.results import ALPHA, added_params, model_test_keys
from simucal.io.timestamps import with_timestamps
from simucal.report.model_files import model_file_text
from simucal.turntable.model_test import test_and_rank


def residual_table(fit: Fit, obs: Observations, segs) -> list[dict]:
    assert fit.directions is not None  # an exact fit's (test_model)
    rows = []
    for i, s in enumerate(segs):
        r = fit.residuals[i]
        sd = obs.sigma[i] if obs.sigma is not None else None
        rows.append({"segment": s.segment, "kind": s.kind, "outer_rate_dps": s.outer_rate_dps,
                     **{k: float(np.broadcast_to(v, len(segs))[i]) for k, v in obs.aux.values.items()},
                     "direction": fit.directions[i].tolist(), "residual": r.tolist(),
                     "sigma": None if sd is None else sd.tolist(),
                     "normalized": None if sd is None else (r / sd).tolist()})
    return rows


def diagnose_sensor(ms, sensor, base_model, add=(), stated=None, truth=None, before_model=None, added=(),
                    acc_model="acc_baseline", kind=None):
    """One sensor's block. add: effect ids; before_model: the model to compare with when
    something was added (default base_model without the ids); added: what the user added
    (ids and model files), for the report; acc_model: on a stream, the accelerometer model (its
    effects too) whose pose directions the gyro's moves are judged against; kind: the set's entry
    in methods.KINDS (default its own), which gives the rows and what else its data judge."""
    kind = kind or methods.kind_of(ms)
    if sensor == "gyro" and kind.diagnose_gyro is not None:  # judged its own way (a stream: against its moves)
        return kind.diagnose_gyro(ms, base_model, tuple(add), truth, acc_model)
    found = kind.observations(ms, sensor, stated)
    if found is None:
        return None
    obs, segs, rows = found
    model = AugmentedModel(base_model, tuple(add))
    fit, obs, base, cands, shape, table_info = test_and_rank(model, obs, segs)
    out = {**model_test_keys(base), "candidates": cands,
           "params": fit.params, "std": fit.std, "param_units": dict(zip(model.params, model.param_units)),
           "residuals": residual_table(fit, obs, rows)}
    if shape:
        out["shape"] = {**shape, "model_file": model_file_text(base_model, add, shape, sensor)}
    if table_info is not None:
        out["table"] = table_info
    out.update(kind.sensor_extras(ms, sensor, model, obs, fit, segs, shape))
    if "twin_fits" in out:  # the found term's twins, each with its model file (judged at rest by kind.finish_diagnosis)
        out["twin_fits"] = [{**tf, "shape": {**tf["shape"], "model_file": model_file_text(
            base_model, add, tf["shape"], sensor)}} for tf in out["twin_fits"]]
    before_model = before_model or model.base.name
    if add or before_model != base_model:
        f0, _, b0 = test_model(AugmentedModel(before_model), obs)
        comp = added_params({k: fit.params[k] for k in model.params}, fit.std, f0.params, f0.std,
                            (truth or {}).get(sensor, {}).get("params"))
        out["added"] = {"effects": list(added or add), "residual_rms_before": f0.residual_rms,
                        "residual_rms_after": fit.residual_rms, "residual_unit": model.unit,
                        "p_value_before": b0["p_value"], "p_value_after": base["p_value"], "params": comp,
                        "residuals_before": residual_table(f0, obs, segs)}
    return out


def scoring_truth(path) -> dict | None:
    """A simulator's truth.json beside the set, read for scoring only (the errors of --add's parameters):
    {sensor: {params: {name: number}, T: 3x3, bias_dps: 3}} with whatever is not of that shape left
    out, and None where it is missing or unreadable (deep, damaged, not JSON): it is never an input."""
    d = json_object_or_none(path)
    number = lambda x: isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
    out = {}
    for sensor, block in (d.items() if isinstance(d, dict) else ()):
        if sensor not in ("acc", "gyro") or not isinstance(block, dict):
            continue
        params = block.get("params")
        out[sensor] = {"params": {k: v for k, v in params.items() if number(v)} if isinstance(params, dict) else {}}
        for key, shape in (("T", (3, 3)), ("bias_dps", (3,))):
            try:
                a = np.asarray(block[key], float)
                if a.shape == shape and np.all(np.isfinite(a)):
                    out[sensor][key] = a.tolist()
            except (KeyError, TypeError, ValueError):
                continue
    return out


def diagnose(folder, add=(), acc_model="acc_baseline", gyro_model="gyro_baseline",
             acc_noise_g=None, gyro_noise_dph=None, timestamps="auto") -> dict:
    """folder: a set's folder, or the set (io.MeasurementSet: its truth.json beside it, if any, scores);
    add: effect ids and model files (fit/augmented.resolve_add); timestamps: a stream's time
    stamps as calibrate takes them (io/timestamps.py)."""
    ms = folder if isinstance(folder, io.MeasurementSet) else io.read_set(folder)
    folder = Path(ms.path)
    try:
        ms, stamps = with_timestamps(ms, timestamps)
        result = _diagnose(ms, folder, add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph)
        if stamps:
            result["timestamps"] = stamps
            if stamps["irregular"] or stamps.get("gaps") or timestamps != "auto":
                result["notes"] = [stamps["text"]] + result.get("notes", [])
        return result
    except CalibrationError as e:
        raise e.naming(ms.path) from None


def _diagnose(ms, folder, add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph):
    from simucal.fit.augmented import resolve_add
    from simucal.io.sensor_checks import stuck_channels
    stuck_channels(ms)
    before = {"acc": acc_model, "gyro": gyro_model}
    acc_model, gyro_model, ids = resolve_add(add, acc_model, gyro_model)
    truth = scoring_truth(folder / "truth.json")
    kind = methods.kind_of(ms)
    result = {"format": "simucal.diagnosis/1", "input": str(folder), "alpha": ALPHA}
    if kind.diagnose_both is not None:  # both sensors in one (a sequence's filter)
        added = tuple(add) if add else ()
        result.update(kind.diagnose_both(ms, acc_model, gyro_model, ids, truth, (before["acc"], before["gyro"]), added))
    for sensor, model, stated, has in (("acc", acc_model, acc_noise_g, ms.has_acc),
                                       ("gyro", gyro_model, gyro_noise_dph, ms.has_gyro)):
        if not has or kind.diagnose_both is not None:
            continue
        mine = tuple(a for a in ids if a.startswith(sensor + "."))
        files = tuple(a for a in add if a.endswith(".py")) if model != before[sensor] else ()
        block = diagnose_sensor(ms, sensor, model, mine, stated, truth, before[sensor], mine + files,
                                AugmentedModel(acc_model, tuple(a for a in ids if a.startswith("acc."))), kind)
        if block is not None:
            result[sensor] = block
    kind.finish_diagnosis(ms, result, (acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph))
    sensors = [s for s in ("acc", "gyro") if s in result]
    for s in sensors:
        result[s]["verdict"] = sensor_verdict(result[s], s)
    if not sensors:
        raise CalibrationError(f"{folder}: nothing to diagnose: segments.csv holds no rows the "
                               f"{' or '.join(ms.sensors)} model is tested on (the accelerometers' static positions, "
                               "the gyro's rate runs)")
    worst = min(sensors, key=lambda s: result[s]["model_test"]["p_value"] if result[s]["model_test"]["p_value"] is not None
                else 1.0)
    result["sensor"] = worst
    result.update(model_test_keys(result[worst]["model_test"]))
    # merged in each sensor's own order (a twin chosen by rows beyond the likelihood ratio keeps its place)
    result["candidates"] = list(heapq.merge(*[[c for c in result[s]["candidates"] if c["separable"]] for s in sensors],
                                            key=lambda c: (c["p_value"] if c["p_value"] is not None else 2.0,
                                                           -c["statistic"]))) + \
        [c for s in sensors for c in result[s]["candidates"] if not c["separable"]]
    result["verdict"] = " | ".join(result[s]["verdict"] for s in sensors)
    result["notes"] = skipped_sensors(ms.sensors) + result.get("notes", [])
    return result
