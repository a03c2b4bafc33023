"""Model versus measurement: where the model fails and which effect is missing.

For each sensor triad: the exact norm fit with the noise the data give,
residuals per segment and axis against the noise floor, the tests and the
candidate ranking of simucal.fit.candidates (one test for every diagnosis), the
shape of a misfit no candidate explains (with a model file for it), and with
--add the parameters and the residual before and after.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit.apply import model_inputs
from simucal.fit.augmented import AugmentedModel
from simucal.fit.aux_inputs import AuxInputs, columns_at
from simucal.fit.candidates import test_model, verdict
from simucal.fit.lack_of_fit import model_file_text, twin_fits
from simucal.fit.norm_fit import Fit, Observations
from simucal.fit.results import ALPHA, model_test_keys
from simucal.io.timestamps import with_timestamps
from simucal.turntable.consistency import handedness_verdict, mirrored
from simucal.turntable.observations import check_rate_sense, segment_observations
from simucal.turntable.model_test import ROWS, test_and_rank, with_static_rows


def residual_table(fit: Fit, obs: Observations, segs) -> list[dict]:
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
                    acc_model="acc_baseline"):
    """One sensor's block. add: effect ids; before_model: the model to compare with when
    something was added (default base_model without the ids); added: what the user added
    (ids and model files), for the report; acc_model: on a stream, the accelerometer model (its
    effects too) whose pose directions the gyro's moves are judged against."""
    if ms.segments is None and sensor == "gyro":  # a stream: the gyro against its moves
        if base_model != "gyro_baseline":
            raise CalibrationError(f"{ms.path}: on a stream the gyro is fit as a full T and a bias over the moves, so "
                                   f"the model {base_model} does not apply; add effects with --add gyro.<effect>.<axis>")
        from simucal.handheld.poses import acc_from_poses
        from simucal.handheld.diagnose_moves import diagnose_moves
        obs, det, am, fa, _ = acc_from_poses(ms, acc_model)
        return diagnose_moves(ms, obs, det, am, fa, tuple(add), truth)
    if ms.segments is None:  # a stream: its static poses, as the hand-placed calibration finds them
        from simucal.handheld.poses import pose_observations
        obs, det, poses = pose_observations(ms)
        segs = None
    else:  # the one model test's rows, calibrate's too (turntable/model_test.py)
        obs, segs = segment_observations(ms, sensor, ROWS[sensor], stated)
        if sensor == "gyro":
            check_rate_sense(ms, obs, segs)
        if not segs:
            return None
    model = AugmentedModel(base_model, tuple(add))
    fit, obs, base, cands, shape, table_info = test_and_rank(model, obs, segs)
    if segs is None:
        segs = [io.Segment(i, "static", None, None, None, 0.0) for i in range(len(poses))]
    out = {**model_test_keys(base), "candidates": cands, "verdict": verdict(sensor, base, cands, str(ms.path), shape, None),
           "params": fit.params, "std": fit.std, "param_units": dict(zip(model.params, model.param_units)),
           "residuals": residual_table(fit, obs, segs)}
    if shape:
        out["shape"] = {**shape, "model_file": model_file_text(base_model, add, shape, sensor)}
        if sensor == "gyro" and shape["indistinguishable_here"] and ms.segments is not None:  # judged at rest later
            out["twin_fits"] = [{**tf, "shape": {**tf["shape"], "model_file": model_file_text(
                base_model, add, tf["shape"], sensor)}} for tf in twin_fits(model, obs, fit, shape)]
    if table_info is not None:
        out["table"] = table_info
    if ms.segments is not None:
        out["mirror"] = mirrored(fit, segs, sensor == "gyro")  # judged over both triads in _diagnose
    before_model = before_model or model.base.name
    if add or before_model != base_model:
        f0, _, b0 = test_model(AugmentedModel(before_model), obs)
        comp = {}
        for k in model.params:
            row = {"before": f0.params.get(k), "std_before": f0.std.get(k), "after": fit.params[k], "std_after": fit.std[k]}
            if truth and k in truth.get(sensor, {}).get("params", {}):
                t = truth[sensor]["params"][k]
                row.update(truth=t, error_before=None if row["before"] is None else row["before"] - t,
                           error_after=row["after"] - t)
            comp[k] = row
        out["added"] = {"effects": list(added or add), "residual_rms_before": f0.residual_rms,
                        "residual_rms_after": fit.residual_rms, "residual_unit": model.unit,
                        "p_value_before": b0["p_value"], "p_value_after": base["p_value"], "params": comp,
                        "residuals_before": residual_table(f0, obs, segs)}
    return out


def stream_summary(ms, max_points=4000):
    """A continuous stream for the report: |f| over time (decimated), calibrated by the
    hand-placed accelerometer fit, and the static intervals found (the gyro's moves are in
    the gyro block, diagnose_moves)."""
    from simucal.handheld.poses import acc_from_poses
    _, det, am, fa, _ = acc_from_poses(ms)
    t = ms.samples["t_s"]
    step = max(len(t) // max_points, 1)
    rows = np.arange(0, len(t), step)
    f = model_inputs(am, fa.vector(am.params), ms.acc_g()[rows],  # calibrated specific force, g
                     AuxInputs(columns_at(ms.samples, rows, t_ref_c=ms.t_ref_c)), ms.path / "samples.csv")
    return {"t_s": t[::step].tolist(), "acc_norm_g": np.linalg.norm(f, axis=1).tolist(),
            "static_detection": det.as_dict(t)}


def scoring_truth(path) -> dict | None:
    """A simulator's truth.json beside the set, read for scoring only (the errors of --add's parameters):
    {sensor: {params: {name: number}, T: 3x3, bias_dps: 3}} with whatever is not of that shape left
    out, and None where it is missing or unreadable (deep, damaged, not JSON): it is never an input."""
    try:
        d = json.loads(Path(path).read_text()) if Path(path).is_file() else None
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return None
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


def _with_static_gyro_rows(ms, block, settings) -> None:
    """The gyro's test over its static rows too, as calibrate's (model_test.with_static_rows): they need
    the accelerometers' up and C_b^d, so calibrate's exact method gives them; where it refuses the set,
    the rate runs' test stands (calibrate says why). Where the rate runs cannot tell the found term
    from its twins, the static rows choose among them (_choose_twin)."""
    from simucal.turntable.calibrate import calibrate_table
    fits, judged = block.pop("twin_fits", []), []
    probe = (lambda test: judged.extend((tf, test(tf)) for tf in fits)) if fits else None
    try:
        gyro = calibrate_table(ms, "exact", *settings, static_probe=probe).gyro
    except CalibrationError:
        return
    if gyro is None or "static_rows" not in gyro.details:
        return
    st = gyro.details["static_rows"]
    with_static_rows(block["model_test"], st)
    chose = _choose_twin(block, judged)
    block["verdict"] = verdict("gyro", block["model_test"], block["candidates"], str(ms.path), block.get("shape"),
                                None) + (
        f" At rest: {st['verdict']}." if st.get("p_value", 1.0) < ALPHA else "") + chose


def _choose_twin(block, judged) -> str:
    """Of the found term and its twins (which the rate runs cannot tell apart), the one whose fit
    predicts the static rows best (lowest chi-square, all on the same rows) becomes the shape and its
    model file, the others its twins; returns the verdict's sentence on the choice ('' if none made)."""
    judged = [(tf, st) for tf, st in judged if "chi2" in st]
    if len(judged) < 2:
        return ""
    tf, st = min(judged, key=lambda j: j[1]["chi2"])
    label = lambda s: f"{s['regressor']} on {s['axis']}"
    at_rest = {label(t["shape"]): {k: s[k] for k in ("chi2", "dof", "p_value")} for t, s in judged}
    block["shape"] = {**tf["shape"], "static_rows": at_rest}
    others = "; ".join(f"{k}: chi2 {v['chi2']:.1f}" for k, v in at_rest.items() if k != label(tf["shape"]))
    said = (f" The rate runs cannot tell {label(tf['shape'])} from its twins; the static rows chose it (chi2 "
            f"{st['chi2']:.1f} on {st['dof']} dof, p = {st['p_value']:.2g}, against {others})")
    return said + ("." if st["p_value"] >= ALPHA else ", though none of them passes at rest.")


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
            if stamps["irregular"] or timestamps != "auto":
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
    result = {"format": "simucal.diagnosis/1", "input": str(folder), "alpha": ALPHA}
    for sensor, model, stated, has in (("acc", acc_model, acc_noise_g, ms.has_acc),
                                       ("gyro", gyro_model, gyro_noise_dph, ms.has_gyro)):
        if not has:
            continue
        mine = tuple(a for a in ids if a.startswith(sensor + "."))
        files = tuple(a for a in add if a.endswith(".py")) if model != before[sensor] else ()
        block = diagnose_sensor(ms, sensor, model, mine, stated, truth, before[sensor], mine + files,
                                AugmentedModel(acc_model, tuple(a for a in ids if a.startswith("acc."))))
        if block is not None:
            result[sensor] = block
    if ms.segments is not None and "gyro" in result and "acc" in result:
        _with_static_gyro_rows(ms, result["gyro"], (acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph))
    if ms.segments is not None:  # a reflected triad, as calibrate refuses it
        notes = handedness_verdict(ms, {("accelerometer" if s == "acc" else s): result[s].pop("mirror")
                                        for s in ("acc", "gyro") if s in result})
        if notes:
            result["notes"] = notes
    else:
        result["stream"] = stream_summary(ms)
    sensors = [s for s in ("acc", "gyro") if s in result]
    if not sensors:
        raise CalibrationError(f"{folder}: nothing to diagnose (no static or rate segments)")
    worst = min(sensors, key=lambda s: result[s]["model_test"]["p_value"] if result[s]["model_test"]["p_value"] is not None
                else 1.0)
    result["sensor"] = worst
    result.update(model_test_keys(result[worst]["model_test"]))
    result["candidates"] = sorted([c for s in sensors for c in result[s]["candidates"] if c["separable"]],
                                  key=lambda c: (c["p_value"] if c["p_value"] is not None else 2.0,
                                                 -c["statistic"])) + \
        [c for s in sensors for c in result[s]["candidates"] if not c["separable"]]
    result["verdict"] = " | ".join(result[s]["verdict"] for s in sensors)
    return result
