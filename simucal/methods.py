"""Every calibration method, named once: the data it takes, its options and its function.

`simucal calibrate` (its dispatch and its --method choice), the demo and the paper's claims
read this table. A new method is its own module, one entry here and a test.

The data a set holds decide which methods apply (data_kind): a turntable test has
segments.csv with commanded table angles; a stream has no segments.csv (a hand-placed
session, static poses found from the data); a field set has segments.csv with a north
reference (heading_ref_deg) and no table angles (ruan2019); a sequence has segments.csv with move
segments between its rests (the table turning, raw samples throughout: systematic calibration).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from simucal.errors import CalibrationError

TURNTABLE, STREAM, FIELD, SEQUENCE = "turntable", "stream", "field", "sequence"
DATA = {SEQUENCE: "a rotation sequence (segments.csv with move segments between rests, raw samples)",
        TURNTABLE: "a turntable test (segments.csv with commanded table angles)",
        STREAM: "a continuous stream (no segments.csv: a hand-placed session)",
        FIELD: "a field set (segments.csv with heading_ref_deg, no table angles)"}


@dataclass(frozen=True)
class Method:
    name: str
    data: str                  # TURNTABLE, STREAM or FIELD
    summary: str               # what it is, with its paper
    options: tuple[str, ...]   # the keyword options its function takes (calibrate's names)
    run: Callable              # run(ms, **options) -> io.calibration.Calibration

    def call(self, ms, **given):
        """run(ms) with the options given that this method takes, the others (and those given as None)
        at their DEFAULTS."""
        given = {k: v for k, v in given.items() if v is not None}
        return self.run(ms, **{k: v for k, v in {**DEFAULTS, **given}.items() if k in self.options})


# The functions import their method when called: the cli reads the names at every start.
def _table(name):
    def run(ms, acc_model, gyro_model, ids, auto, acc_noise_g, gyro_noise_dph, noise_curves, rank):
        from simucal.turntable.calibrate import calibrate_table
        return calibrate_table(ms, name, acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph, auto, noise_curves,
                               rank)
    return run


def _multiposition(ms, acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph, noise_curves):
    from simucal.turntable.multiposition import calibrate_multiposition
    return calibrate_multiposition(ms, acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph, noise_curves)


def _handheld(ms, acc_model, ids, auto, detect):
    from simucal.fit.augmented import AugmentedModel, for_sensor
    from simucal.handheld.calibrate import calibrate_handheld
    return calibrate_handheld(ms, AugmentedModel(acc_model, for_sensor(ids, "acc")), detect,
                              gyro_effects=for_sensor(ids, "gyro"), auto=auto)


def _systematic(ms, acc_model, gyro_model, ids):
    from simucal.systematic.method import calibrate_systematic
    return calibrate_systematic(ms, acc_model, gyro_model, ids)


def _field(ms, heading_accuracy_deg):
    from simucal.field.drift import field_calibration
    return field_calibration(ms, heading_accuracy_deg)


DEFAULTS = dict(acc_model="acc_baseline", gyro_model="gyro_baseline", ids=(), auto=False, detect=None, acc_noise_g=None,
                gyro_noise_dph=None, noise_curves=None, heading_accuracy_deg=5.0, rank=True)  # every option, as calibrate's
_TABLE_OPTIONS = ("acc_model", "gyro_model", "ids", "auto", "acc_noise_g", "gyro_noise_dph", "noise_curves", "rank")
METHODS = {m.name: m for m in (
    Method("exact", TURNTABLE, "dong2018's norm observation by the exact fit of any model (eq. 6-12 without the "
           "linearisation), frames unified by the rate runs' means", _TABLE_OPTIONS, _table("exact")),
    Method("linear", TURNTABLE, "dong2018 as printed: the linear regression of eq. 8/12 and the unification of "
           "eq. 25-27 (derived models only)", _TABLE_OPTIONS, _table("linear")),
    Method("multiposition", TURNTABLE, "the traditional multi-position method (dong2018's 'previous method', "
           "Tables 3 and 4): least squares on the commanded attitudes",
           tuple(o for o in _TABLE_OPTIONS if o not in ("auto", "rank")), _multiposition),
    Method("handheld", STREAM, "Tedaldi: static poses found in the stream, the exact norm fit of the "
           "accelerometers, the gyro from the gravity directions before and after each move",
           ("acc_model", "ids", "auto", "detect"), _handheld),
    Method("field", FIELD, "ruan2019: the gyro constant drift from three static positions with a north reference "
           "(two-stage alignment, a Kalman filter per position, least squares)", ("heading_accuracy_deg",),
           _field),
    Method("systematic", SEQUENCE, "systematic calibration: strapdown navigation through a rotation sequence, an "
           "error-state Kalman filter (states derived from the error models) and RTS smoother on zero velocity at "
           "rest", ("acc_model", "gyro_model", "ids"), _systematic),
)}
NAMES = tuple(METHODS)


def for_data(kind) -> tuple[str, ...]:
    """The methods that take this kind of data, the default first."""
    return tuple(m.name for m in METHODS.values() if m.data == kind)


def data_kind(ms) -> str:
    """TURNTABLE, STREAM or FIELD (module doc)."""
    if ms.segments is None:
        return STREAM
    if any(s.kind == "move" for s in ms.segments):
        return SEQUENCE
    static = [s for s in ms.segments if s.kind == "static"]
    no_table = all(s.middle_deg is None and s.inner_deg is None for s in static)
    return FIELD if no_table and any(s.heading_ref_deg is not None for s in static) else TURNTABLE


def choose(name, ms) -> Method:
    """The method called `name` ("auto": the default for the set's data), refused where it does not
    take these data, naming the methods that do."""
    kind = data_kind(ms)
    if name in (None, "auto"):
        return METHODS[for_data(kind)[0]]
    if name not in METHODS:
        raise CalibrationError(f"unknown method {name!r}; one of auto, {', '.join(NAMES)}.")
    m = METHODS[name]
    if m.data != kind:
        raise CalibrationError(f"{ms.path}: is {DATA[kind]}, but method {name} takes {DATA[m.data]}: use --method "
                               f"{' or --method '.join(for_data(kind))}.")
    return m
