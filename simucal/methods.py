"""Every calibration method, named once: the data it takes, its options and its function.

`simucal calibrate` (its dispatch and its --method choice), the demo and the paper's claims
read this table. A new method is its own module, one entry here and a test.

The data a set holds decide which methods apply (data_kind, the one place that looks): a
turntable test has segments.csv with commanded table angles; a stream has no segments.csv (a
hand-placed session, static poses found from the data); a field set has segments.csv with a north
reference (heading_ref_deg) and no table angles (ruan2019); a sequence has segments.csv with move
segments between its rests (the table turning, raw samples throughout: systematic calibration). Each kind of data is one
entry of KINDS (`kind_of(ms)`), which supplies what the commands do differently with it: its simulator,
its diagnosis (the observations each sensor's model is tested on, and the checks over the set), its
validation checks and its still stretches for `simucal noise`. A new kind of data is its module(s)
and one entry here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from simucal.errors import CalibrationError, InputError
from simucal.kinds import (FIELD as FIELD, SEQUENCE as SEQUENCE, STREAM as STREAM, TURNTABLE as TURNTABLE,
                           data_kind as data_kind)  # the registry's kinds, told from the segments
from simucal.options import CalibrateOptions, unused

if TYPE_CHECKING:  # the methods' modules load when one is called (below)
    from simucal import io
    from simucal.fit.results import SensorDiagnosis
    from simucal.io.calibration import Calibration

DATA = {SEQUENCE: "a rotation sequence (segments.csv with move segments between rests, raw samples)",
        TURNTABLE: "a turntable test (segments.csv with commanded table angles)",
        STREAM: "a continuous stream (no segments.csv: a hand-placed session)",
        FIELD: "a field set (segments.csv with heading_ref_deg, no table angles)"}


@dataclass(frozen=True)
class Method:
    name: str
    data: str                  # TURNTABLE, STREAM or FIELD
    summary: str               # what it is, with its paper
    reads: frozenset[str]      # the options its function reads: CalibrateOptions' fields ("add auto": add's "auto")
    run: Callable[[io.MeasurementSet, CalibrateOptions], Calibration]
    any_plan: bool = True      # takes any plan of its kind of data (False: a protocol's own, Ferraris's six poses)

    def refuse_unused(self, options: CalibrateOptions) -> None:
        """The one rule for an option this method would ignore (options.unused): refused, naming its flag and
        the methods that read it."""
        left = unused(options, self.reads)
        if left:
            name, flag = left[0]
            takes = [x.name for x in METHODS.values() if name in x.reads]
            raise CalibrationError(f"{flag} does not apply to method {self.name} ({self.summary}); it applies to "
                                   f"method {' or '.join(takes)} "
                                   f"({' or '.join(sorted({DATA[METHODS[t].data] for t in takes}))}).")


# Each function is run(ms, options) with the fields its entry reads; it imports its method when called (the cli
# reads the names at every start).
def _table(name):
    def run(ms, o):
        from simucal.turntable.calibrate import calibrate_table
        return calibrate_table(ms, name, o.acc_model, o.gyro_model, o.effect_ids, o.acc_noise_g, o.gyro_noise_dph,
                               o.auto, o.noise_curves, o.rank)
    return run


def _multiposition(ms, o):
    from simucal.turntable.multiposition import calibrate_multiposition
    return calibrate_multiposition(ms, o.acc_model, o.gyro_model, o.effect_ids, o.acc_noise_g, o.gyro_noise_dph,
                                   o.noise_curves)


def _ferraris(ms, o):
    from simucal.turntable.ferraris import calibrate_ferraris
    if o.effect_ids or o.acc_model != "acc_baseline" or o.gyro_model != "gyro_baseline":
        raise CalibrationError("the Ferraris method is the affine y = M f + b of six poses; --add and models need "
                               "--method exact (nine or more positions)")
    return calibrate_ferraris(ms, o.acc_noise_g, o.gyro_noise_dph, o.noise_curves)


def _handheld(ms, o):
    from simucal.fit.augmented import AugmentedModel, for_sensor
    from simucal.handheld.calibrate import calibrate_handheld
    return calibrate_handheld(ms, AugmentedModel(o.acc_model, for_sensor(o.effect_ids, "acc")), o.detect,
                              gyro_effects=for_sensor(o.effect_ids, "gyro"), auto=o.auto)


def _systematic(ms, o):
    from simucal.systematic.method import calibrate_systematic
    return calibrate_systematic(ms, o.acc_model, o.gyro_model, o.effect_ids, o.auto)


def _field(ms, o):
    from simucal.field.drift import field_calibration
    return field_calibration(ms, o.heading_accuracy_deg)


_TABLE = frozenset({"acc_model", "gyro_model", "add", "add auto", "acc_noise_g", "gyro_noise_dph", "noise"})
METHODS = {m.name: m for m in (
    Method("exact", TURNTABLE, "dong2018's norm observation by the exact fit of any model (eq. 6-12 without the "
           "linearisation), frames unified by the rate runs' means", _TABLE, _table("exact")),
    Method("linear", TURNTABLE, "dong2018 as printed: the linear regression of eq. 8/12 and the unification of "
           "eq. 25-27 (derived models only)", _TABLE, _table("linear")),
    Method("multiposition", TURNTABLE, "the traditional multi-position method (dong2018's 'previous method', "
           "Tables 3 and 4): least squares on the commanded attitudes", _TABLE - {"add auto"}, _multiposition),
    Method("ferraris", TURNTABLE, "Ferraris et al. 1995 (imucal): six poses in opposite pairs, M from their "
           "differences, each accelerometer bias from the pairs' norms (no attitude), the gyro from the turns; the "
           "default for such a set", _TABLE - {"add auto"}, _ferraris, any_plan=False),
    Method("handheld", STREAM, "Tedaldi: static poses found in the stream, the exact norm fit of the "
           "accelerometers, the gyro from the gravity directions before and after each move",
           frozenset({"acc_model", "add", "add auto", "detect"}), _handheld),
    Method("field", FIELD, "ruan2019: the gyro constant drift from three static positions with a north reference "
           "(two-stage alignment, a Kalman filter per position, least squares)", frozenset({"heading_accuracy_deg"}),
           _field),
    Method("systematic", SEQUENCE, "systematic calibration: strapdown navigation through a rotation sequence, an "
           "error-state Kalman filter (states derived from the error models) and RTS smoother on zero velocity at "
           "rest", frozenset({"acc_model", "gyro_model", "add", "add auto"}), _systematic),
)}
NAMES = tuple(METHODS)


def for_data(kind) -> tuple[str, ...]:
    """The methods that take this kind of data, the default first."""
    return tuple(m.name for m in METHODS.values() if m.data == kind)


def for_any_plan(kind) -> tuple[str, ...]:
    """The methods that take any plan of this kind of data (not a protocol's own, as Ferraris's six poses): the
    paper's comparison and the demo run these on dong2018's plan."""
    return tuple(m for m in for_data(kind) if METHODS[m].any_plan)


def choose(name, ms) -> Method:
    """The method called `name` ("auto": the default for the set's data), refused where it does not
    take these data, naming the methods that do."""
    kind = data_kind(ms)
    if name in (None, "auto"):
        if kind == TURNTABLE:
            from simucal.turntable.ferraris import pose_pairs, refuse_unpaired
            if pose_pairs(ms.segments) is not None:  # six poses in opposite pairs: too few for the exact fit
                return METHODS["ferraris"]
            refuse_unpaired(ms)  # six poses that pair but for one: named, not left to the exact fit
        return METHODS[for_data(kind)[0]]
    if name not in METHODS:
        raise CalibrationError(f"unknown method {name!r}; one of auto, {', '.join(NAMES)}.")
    m = METHODS[name]
    if m.data != kind:
        first, *others = for_data(kind)  # the whole command: field-drift, which says method field, has no --method
        raise CalibrationError(f"{ms.path}: is {DATA[kind]}, but method {name} takes {DATA[m.data]}: use simucal "
                               f"calibrate {ms.path} --method {first}"
                               + (f" (or --method {' or '.join(others)})" if others else "") + ".")
    return m


@dataclass(frozen=True)
class Kind:
    """What the commands do with one kind of data (module doc). The functions import their modules
    when called, as Method's do."""
    name: str                  # TURNTABLE, STREAM or FIELD
    scenario: str              # `simulate --scenario`'s name for it
    simulate: Callable         # simulate(seed, rate_hz, options) -> (meta, samples, segments or None, truth)
    observations: Callable     # observations(ms, sensor, stated) -> (Observations, segments or None, row segments)
    #                            or None: the rows a sensor's model is tested on (diagnose)
    diagnose_gyro: Callable[..., SensorDiagnosis] | None  # diagnose_gyro(ms, gyro_model, add, truth, acc_model)
    #                            -> block: the gyro judged otherwise than by observations (None: by them)
    sensor_extras: Callable    # sensor_extras(ms, sensor, model, obs, fit, segs, shape) -> dict: a diagnosis
    #                            block's own keys
    finish_diagnosis: Callable  # finish_diagnosis(ms, result, settings): the checks over both sensors, in place
    validation_checks: Callable  # (ms, f_before, f_after, w_before, w_after, cal) -> {sensor: [check]}
    still_rows: Callable       # still_rows(ms) -> ([row indices], where): the stretches `simucal noise` pools
    still_whole: bool          # the whole recording must be still (noise refuses one that moves)
    diagnose_both: Callable | None = None  # diagnose_both(ms, acc_model, gyro_model, ids, truth, before, added)
    #                            -> {sensor: block}: both sensors judged together (a sequence: one filter), in
    #                            place of observations and diagnose_gyro


def _table_observations(ms, sensor, stated):
    from simucal.turntable.diagnosis import observations
    return observations(ms, sensor, stated)


def _table_extras(ms, sensor, model, obs, fit, segs, shape):
    from simucal.turntable.diagnosis import sensor_extras
    return sensor_extras(sensor, model, obs, fit, segs, shape)


def _table_finish(ms, result, settings):
    from simucal.turntable.diagnosis import finish
    finish(ms, result, settings)


def _table_checks(ms, f_before, f_after, w_before, w_after, cal):
    from simucal.turntable.validation import table_checks
    return table_checks(ms, f_before, f_after, w_before, w_after, cal)


def _static_segments(ms):
    """Each static segment's rows (three or more), pooled for noise."""
    import numpy as np
    seg = ms.samples["segment"]
    pieces = [np.nonzero(seg == s.segment)[0] for s in ms.segments if s.kind == "static"]
    pieces = [p for p in pieces if len(p) >= 3]
    if not pieces:
        raise CalibrationError(f"{ms.path}: no static segment holds raw rows (3 or more): the Allan deviation "
                               "needs the samples, not their averages")
    return pieces, f"{len(pieces)} static segments, pooled"


def _stream_observations(ms, sensor, stated):
    from simucal.handheld.diagnosis import observations
    return observations(ms)


def _stream_gyro(ms, gyro_model, add, truth, acc_model) -> SensorDiagnosis:
    from simucal.handheld.diagnosis import diagnose_gyro
    return diagnose_gyro(ms, gyro_model, add, truth, acc_model)


def _stream_finish(ms, result, settings):
    from simucal.handheld.diagnosis import stream_summary
    result["stream"] = stream_summary(ms)


def _whole_stream(ms):
    import numpy as np
    return [np.arange(len(ms.samples["t_s"]))], "the whole stream"


def _sequence_diagnosis(ms, acc_model, gyro_model, ids, truth, before, added):
    from simucal.systematic.diagnosis import diagnose_sequence
    return diagnose_sequence(ms, acc_model, gyro_model, ids, truth, before, added)


def _no_extras(*_):
    return {}


def _stream_checks(ms, f_before, f_after, w_before, w_after, cal):
    from simucal.handheld.validation import stream_checks
    return stream_checks(ms, f_before, f_after, w_before, w_after, cal)


def _simulate_table(seed, rate_hz, o):
    """A turntable test from simulate's options (the command's values: effects, columns and sets as
    NAME=VALUE strings, temperature as T or T0:T1)."""
    from simucal.turntable.simulate import ARCMIN, Scenario, at_temperature, plant
    from simucal.turntable.simulate import simulate as simulate_table
    sc = Scenario()
    for key in ("plan", "acc_model", "gyro_model", "acc_unit", "gyro_unit"):
        if o[key] is not None:
            setattr(sc, key, o[key])
    if rate_hz is not None:
        sc.rate_hz = rate_hz
    if o["position_error_arcmin"] is not None:
        sc.position_error_rad = o["position_error_arcmin"] * ARCMIN
    sc.state_noise = o["state_noise"]
    at_temperature(sc, o["temperature"], columns=o["columns"], **{k: o[key] for k, key in (
        ("t_ref_c", "t_ref_c"), ("wander_c", "temperature_wander_c")) if o[key] is not None})
    plant(sc, o["effects"], o["effect_file"], o["sets"], o["columns"])
    if o.get("sequence") is None:
        return simulate_table(sc, seed)
    from simucal.turntable.sequence import simulate_sequence
    if o["plan"] is not None or o["columns"] or o["temperature"] is not None:
        raise InputError("--sequence: the table turns through the sequence; --plan, --column and --temperature-c "
                         "describe a plan's positions: leave them out")
    return simulate_sequence(sc, o["sequence"], seed)


def _simulate_stream(seed, rate_hz, o):
    from simucal.handheld.simulate import HandheldScenario, simulate_handheld
    from simucal.turntable.simulate import Scenario, plant
    sc = Scenario()  # the effects parsed and checked as a turntable test's are
    plant(sc, o["effects"])
    hs = HandheldScenario(acc_effects=sc.acc_effects, gyro_effects=sc.gyro_effects,
                          **({"rate_hz": rate_hz} if rate_hz is not None else {}))
    meta, samples, truth = simulate_handheld(hs, seed, o["unit_seed"])
    return meta, samples, None, truth


def _simulate_field(seed, rate_hz, o):
    from simucal.field.simulate import FieldScenario, simulate_field
    return simulate_field(FieldScenario(**{k: v for k, v in (("heading_error_deg", o["heading_accuracy_deg"]),
                                                              ("rate_hz", rate_hz)) if v is not None}), seed,
                          o["unit_seed"])


KINDS = {k.name: k for k in (
    Kind(TURNTABLE, "paper", _simulate_table, _table_observations, None, _table_extras, _table_finish, _table_checks,
         _static_segments, False),
    Kind(FIELD, "field", _simulate_field, _table_observations, None, _table_extras, _table_finish, _table_checks,
         _static_segments, False),  # its static segments, as a turntable test's
    Kind(SEQUENCE, "sequence", lambda seed, rate_hz, o: _simulate_table(seed, rate_hz, {**o, "sequence": o.get(
        "sequence") or "psins19"}), _table_observations, None, _table_extras, _no_extras, _table_checks,
         _static_segments, False, _sequence_diagnosis),  # its rests, as a turntable test's static positions
    Kind(STREAM, "handheld", _simulate_stream, _stream_observations, _stream_gyro, _no_extras, _stream_finish,
         _stream_checks, _whole_stream, True),
)}


def _simulate_still(seed, rate_hz, o):
    from simucal.handheld.simulate import simulate_still
    meta, samples, truth = simulate_still(
        **{k: v for k, v in (("seconds", o["seconds"]), ("dt", rate_hz and 1 / rate_hz)) if v is not None}, seed=seed)
    return meta, samples, None, truth


def _simulate_warmup(seed, rate_hz, o):
    from simucal.handheld.simulate import simulate_warmup
    meta, samples, truth = simulate_warmup(seed, **{k: v for k, v in (("seconds", o["seconds"]), ("hz", rate_hz))
                                                    if v is not None})
    return meta, samples, None, truth


# `simulate --scenario`'s names: each kind's own (its simulate), and a still stream's two (a unit at rest for
# `simucal noise`, a still board warming up for `calibrate --thermal`)
SCENARIOS: dict[str, Callable] = {**{k.scenario: k.simulate for k in KINDS.values()}, "still": _simulate_still,
                                  "warmup": _simulate_warmup}


def kind_of(ms) -> Kind:
    """The entry of the set's kind of data (data_kind)."""
    return KINDS[data_kind(ms)]
