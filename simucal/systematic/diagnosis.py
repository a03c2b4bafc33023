"""What diagnose does on a rotation sequence (its Kind entry in methods.py): the filter run once with
the model, the model test on its innovations (NIS, whiteness), the candidates ranked on them
(innovations.py) per sensor and, with --add, the filter without the effects beside.

One filter carries both sensors, so one test judges them together and the candidates of both are one
family under one gate (fit/family.py): the strongest is the one effect to add (one at a time, as --add
auto does); the other sensor's block says so (explained_by) rather than naming a second effect at once,
except where it would leave the model failing having explained little (family.outside_library): then
both blocks say the misfit is most likely outside the library.
"""
from __future__ import annotations

from typing import Any, cast

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.results import Added, SensorDiagnosis, added_params, model_test_keys
from simucal.systematic.calibrate import rests_and_moves, run_filter
from simucal.fit import family
from simucal.io import records
from simucal.io.details import ModelTestBlock
from simucal.systematic.innovations import family_test, ranked
from simucal.systematic.method import refusal

UNIT = "innovation std (whitened)"


def model_test(test) -> ModelTestBlock:
    """The innovations' test as a diagnosis block's model test (the keys candidates.verdict reads), whitened:
    noise floor 1, the rows the updates and returns, with the innovations' whiteness."""
    return cast(ModelTestBlock, {
            "chi2": test["nis"], "dof": test["dof"], "p_value": test["p_value"], "residual_unit": UNIT,
            "residual_rms": float(np.sqrt(test["nis"] / test["dof"])), "noise_floor": 1.0, "test": test["test"],
            **{k: test[k] for k in ("omnibus_p_value", "omnibus_test", "targeted") if k in test},
            "rows": f"{test['updates']} zero-velocity updates" + (
                f" and {test['returns']} zero-position returns" if test.get("returns") else ""),
            "returns": test.get("returns", 0),
            "noise": {"source": "the rests' white noise (first differences)", "rows_estimated": False},
            "whiteness": {"lag1_autocorrelation": test["lag1_autocorrelation"], "lag1_z": test["lag1_z"],
                          "meaning": "each axis's lag-1 autocorrelation of the whitened innovations times "
                                     "sqrt(updates), about N(0, 1) where they are white"}})


def innovation_rows(ms, result) -> list[records.JSONObject]:
    """The zero-velocity innovations, one row per update (the shape of api/diagnosing.residual_table): the
    rest's segment, its time, the specific force's direction in b, nu (m/s, in n: east, north, up),
    its std and nu / std."""
    steps = result.setting[0]
    z = steps.zupt
    rests = [s.segment for s in rests_and_moves(ms) if s.kind == "static"]
    rest = np.cumsum(z & np.r_[True, ~z[:-1]])[z] - 1  # each update's rest, in order
    f = steps.N_a[z] / np.linalg.norm(steps.N_a[z], axis=1, keepdims=True)
    epochs = [e for e in result.epochs if e.nu is not None]
    return [{"segment": rests[min(k, len(rests) - 1)], "kind": "static", "outer_rate_dps": None, "t_s": e.t_s,
             "direction": d.tolist(), "residual": e.nu.tolist(), "sigma": np.sqrt(np.diag(e.S)).tolist(),
             "normalized": (e.nu / np.sqrt(np.diag(e.S))).tolist()} for k, e, d in zip(rest, epochs, f)]


def _params(result, sensor) -> tuple[dict, dict, dict]:
    s = result.sensors
    model, na = (s.acc, 0) if sensor == "acc" else (s.gyro, len(s.p_acc))
    p = s.vector()[na:na + len(model.params)]
    std = np.sqrt(np.diag(result.cov))[na:na + len(model.params)]
    return (dict(zip(model.params, p.tolist())), dict(zip(model.params, std.tolist())),
            dict(zip(model.params, model.param_units)))


def _added(sensor, result, before, base, truth, added) -> Added:
    """diagnose --add: the filter without the effects beside the filter with them."""
    comp = added_params(*_params(result, sensor)[:2], *_params(before["result"], sensor)[:2],
                        (truth or {}).get(sensor, {}).get("params"))
    b0 = before["test"]
    return {"effects": list(added), "residual_rms_before": b0["residual_rms"],
            "residual_rms_after": base["residual_rms"],
            "residual_unit": UNIT, "p_value_before": b0["p_value"], "p_value_after": base["p_value"], "params": comp,
            "residuals_before": before["rows"]}


def diagnose_sequence(ms, acc_model, gyro_model, ids, truth, before_models, added) -> dict[str, SensorDiagnosis]:
    """{sensor: block} of both sensors (module doc). before_models: (acc, gyro) the models without
    --add; added: what the user added (ids and model files), for the report."""
    r = run_filter(ms, acc_model, gyro_model, ids)
    diverged = refusal(r, ms.path) if r.diverged else None
    if diverged:  # no test holds on NaN innovations: the refusal says where, what the sequence leaves unseen, the fix
        raise CalibrationError(diverged.why)
    test, sig = family_test(r)
    base = model_test(test)
    cands = ranked(test, sig)
    best = next((c for c in cands if c.significant), None)
    if family.outside_library(base, [c.to_dict() for c in cands]):
        best = None  # nothing to point the other sensor at: each block's verdict says the misfit is outside
    rows = innovation_rows(ms, r)
    before = None
    if added:
        r0 = run_filter(ms, *before_models)
        before = {"result": r0, "test": model_test(family_test(r0)[0]), "rows": innovation_rows(ms, r0)}
    out: dict[str, SensorDiagnosis] = {}
    refused = refusal(r, ms.path)
    for sensor in ("acc", "gyro"):
        own = [c.to_dict() for c in cands if c.id.startswith(sensor + ".")]
        params, std, units = _params(r, sensor)
        block: dict[str, Any] = {**model_test_keys(base), "candidates": own, "params": params, "std": std,
                                 "param_units": units, "residuals": rows}
        if best is not None and not best.id.startswith(sensor + "."):
            other = best.id.split(".")[0]
            for c in block["candidates"]:
                c["significant"] = False  # one effect at a time: the family's strongest is the other sensor's
            block["explained_by"] = {"id": best.id, "sensor": other}  # report/verdicts.py says so
        if before is not None:
            block["added"] = _added(sensor, r, before, base, truth, added)
        if refused:
            block["calibrate_refuses"] = refused.why
            block["next_instead"] = {"command": refused.next, "note": refused.note}
        out[sensor] = cast(SensorDiagnosis, block)  # tests/test_calibration_file.py checks its keys
    return out
