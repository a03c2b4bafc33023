"""`simucal diagnose` on a turntable test (or a field set: its static segments), what differs from a
stream (the registry of kinds of data: methods.py): each sensor tested on the model test's rows
(model_test.ROWS), a found gyro term judged against its twins at rest, the handedness over both
triads, and the gyro's static rows against the Earth rate."""
from __future__ import annotations

from typing import TypedDict

from simucal.errors import CalibrationError
from simucal.fit.lack_of_fit import TwinFit, twin_fits
from simucal.fit.results import ALPHA
from simucal.fit.twins import CANNOT_TELL
from simucal.turntable.calibrate import calibrate_table
from simucal.turntable.consistency import handedness_verdict, mirrored
from simucal.turntable.model_test import ROWS, AtRest, choose_twin, with_static_rows
from simucal.turntable.observations import check_rate_sense, segment_observations


def observations(ms, sensor, stated):
    """(Observations, segments, segments) of the one model test's rows, calibrate's too
    (turntable/model_test.py), or None where the set has none for this sensor."""
    obs, segs = segment_observations(ms, sensor, ROWS[sensor], stated)
    if sensor == "gyro":
        check_rate_sense(ms, obs, segs)
    return (obs, segs, segs) if segs else None


class SensorExtras(TypedDict, total=False):
    """A turntable block's keys for finish (sensor_extras)."""
    twin_fits: list[TwinFit]          # the found gyro term and each of its twins fitted (fit/lack_of_fit.twin_fits)
    mirror: tuple[int, float, float] | None  # a mirror image: (axis, rms residual, with it reversed); else None


def sensor_extras(sensor, model, obs, fit, segs, shape) -> SensorExtras:
    """A block's keys for finish: the triad's mirror test, and a gyro term the rate runs cannot tell
    from its twins fitted as each of them (judged at rest in finish)."""
    out: SensorExtras = {}
    if shape and sensor == "gyro" and shape["indistinguishable_here"]:
        out["twin_fits"] = twin_fits(model, obs, fit, shape)
    out["mirror"] = mirrored(fit, segs, sensor == "gyro")  # judged over both triads in finish
    return out


def finish(ms, result, settings) -> None:
    """The gyro's static rows (with both triads) and a reflected triad, as calibrate refuses it, into
    the diagnosis result; settings: calibrate_table's (acc_model, gyro_model, ids, acc_noise_g,
    gyro_noise_dph)."""
    if "gyro" in result and "acc" in result:
        _with_static_gyro_rows(ms, result["gyro"], settings)
    notes = handedness_verdict(ms, {("accelerometer" if s == "acc" else s): result[s].pop("mirror")
                                    for s in ("acc", "gyro") if s in result})
    if notes:
        result["notes"] = notes


def _with_static_gyro_rows(ms, block, settings) -> None:
    """The gyro's test over its static rows too, as calibrate's (model_test.with_static_rows): they need
    the accelerometers' up and C_b^d, so calibrate's exact method gives them; where it refuses the set,
    the rate runs' test stands (calibrate says why). Where the rate runs cannot tell the strongest
    candidate, or the found generic term, from its twins, the static rows choose among them (with the
    unification pairs, for library effects: model_test.choose_twin; _choose_twin), as calibrate's advice and
    `--add auto` do."""
    fits = block.pop("twin_fits", [])
    judges: list[AtRest] = []  # the judge of the static rows calibrate_table made (static_probe)
    acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph = settings
    try:
        gyro = calibrate_table(ms, "exact", acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph,
                               ranked=False, static_probe=judges.append).gyro  # the ranking is the diagnosis's
    except CalibrationError:
        return
    if gyro is None or "static_rows" not in gyro.details:
        return
    with_static_rows(block["model_test"], gyro.details["static_rows"])
    judge = judges[0]
    choose_twin(block["candidates"], lambda: judge)
    said = [c["twin_choice"] for c in block["candidates"][:1] if c.get("twin_choice")]
    said += [_choose_twin(block, [(tf, judge.test(tf)) for tf in fits])]
    if any(said):
        block["twin_choice"] = "".join(f" {x.strip()}." for x in said if x)  # report/verdicts.sensor_verdict appends it


def _choose_twin(block, judged) -> str:
    """Of the found term and its twins (which the rate runs cannot tell apart), the one whose fit
    predicts the static rows best (lowest chi-square, all on the same rows, by the twins' level at least:
    else none is chosen, and the sentence says so) becomes the shape and its model file, the others its twins; returns
    the verdict's sentence on the choice ('' if none made)."""
    judged = [(tf, st) for tf, st in judged if "chi2" in st]
    if len(judged) < 2:
        return ""
    tf, st = min(judged, key=lambda j: j[1]["chi2"])
    label = lambda s: f"{s['regressor']} on {s['axis']}"
    at_rest = {label(t["shape"]): {k: s[k] for k in ("chi2", "dof", "p_value")} for t, s in judged}
    gap = min(s["chi2"] for t, s in judged if t is not tf) - st["chi2"]
    if gap < CANNOT_TELL:  # the static rows cannot choose either: the shape stays the rate runs' find
        block["shape"] = {**block["shape"], "static_rows": at_rest}
        return (f"Neither the rate runs nor the static rows can tell {' from '.join(at_rest)} (chi2 at rest "
                + ", ".join(f"{v['chi2']:.1f}" for v in at_rest.values())
                + f", {gap:.1f} apart, under the twins' level "
                f"{CANNOT_TELL:.2f}): either may be the unit's; a plan that moves the inputs they read apart "
                "would tell")
    block["shape"] = {**tf["shape"], "static_rows": at_rest}
    others = "; ".join(f"{k}: chi2 {v['chi2']:.1f}" for k, v in at_rest.items() if k != label(tf["shape"]))
    said = (f"The rate runs cannot tell {label(tf['shape'])} from its twins; the static rows chose it (chi2 "
            f"{st['chi2']:.1f} on {st['dof']} dof, p = {st['p_value']:.2g}, against {others})")
    return said + ("" if st["p_value"] >= ALPHA else ", though none of them passes at rest")


