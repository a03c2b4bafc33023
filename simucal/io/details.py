"""What each method reports about one sensor's fit beside SensorBlock's fields (io/calibration.py), written at
the block's top level in the calibration file: ModelTestDetails, every method's, and beside it a TypedDict of each
method's own keys, in the way of imucal's class per method's result; SensorDetails is what a block may hold
whatever its method (the readers that take any block). A model test as a diagnosis holds it (ModelTestBlock,
under FamilyTest: the keys fit/family.fold writes) has the same keys.

tests/test_calibration_file.py checks that each method's blocks hold only the keys of its own classes
(details_types) and that every value has its declared type. Units as the block's.
"""
from __future__ import annotations

import re
from typing import Any, TypedDict, cast

from simucal.io import records


class Whiteness(TypedDict):
    """A sequence's zero-velocity innovations' whiteness (systematic/innovations.innovation_test), per axis."""
    lag1_autocorrelation: list[float]  # of the whitened innovations
    lag1_z: list[float]               # times sqrt(updates): about N(0, 1) where they are white
    meaning: str                      # what lag1_z is, in words


class FamilyTest(records.FamilyKeys, total=False):
    """A model test made one family with the library effects' targeted tests (fit/family.fold)."""
    chi2: float | None                # None: no noise in the data or stated
    dof: int


class ModelTestBlock(FamilyTest, total=False):
    """A model test as a diagnosis holds it (`model_test`; fit/candidates.test_model, each kind's own), in
    residual_unit; calibrate writes the same keys at a block's top level (ModelTestDetails)."""
    model: str                        # the model tested
    residual_rms: float
    residual_unit: str
    noise: records.NoiseUsed
    noise_floor: float | None         # the residual rms the noise alone leaves
    noise_std_of_mean: float | None
    noise_warning: str
    noise_too_small: bool
    lack_of_fit: records.LackOfFit
    cross_validation: records.CrossValidation | None
    rows: str                         # the rows tested, where not all
    static_rows: records.StaticRows   # a turntable gyro's static rows against the Earth rate
    note: str                         # what else the test says (a fit that did not converge)
    # a stream's gyro, tested over its moves (handheld/diagnose_moves.py)
    gyro_white_noise_dps: list[float]  # the rests' white noise per axis
    # a sequence's innovations (systematic/diagnosis.model_test), whitened: noise_floor 1
    returns: int                      # the zero-position returns among the rows
    whiteness: Whiteness


class ModelTestDetails(TypedDict, total=False):
    """Every method's: the model test (sensor_block, from fit.candidates.test_model), the stds, the advice and
    --add auto's steps. The multi-position and the field methods write none of them (no model test)."""
    test: str                          # the test, in words
    omnibus_p_value: float | None      # the omnibus's own p (fit/family.py; p_value is the family's)
    omnibus_test: str | None           # the omnibus, in words
    targeted: records.Targeted         # the library effects' targeted tests: tested, strongest, p_value, level
    noise: records.NoiseUsed           # the noise the test used and where it came from
    lack_of_fit: records.LackOfFit     # the lack-of-fit F test (fit/lack_of_fit.py)
    cross_validation: records.CrossValidation | None  # leave one position out (fit/cross_validation.py)
    rows: str                          # the rows tested, where not all
    noise_warning: str                 # a stated noise far from the data's scatter
    noise_too_small: bool
    covariance: records.Covariance     # the parameters' covariance
    poorly_determined: dict[str, records.Inflation]  # parameters whose std the plan inflates (poorly_determined)
    std_raw: dict[str, records.Std]    # the stds before inflate_if_failing scaled them
    std_note: str                      # how the stds were scaled, or what they include
    advice: str | None                 # the effect (or generic term) a failing model most likely lacks
    auto: list[records.AutoStep]       # --add auto's steps (fit/selection.py)
    auto_stopped: str                  # why it stopped
    note: str | None                   # what else the method says of this block


class TurntableDetails(TypedDict, total=False):
    """The exact and the linear methods' (turntable/calibrate.py, tilt.py): the gyro's M in its own frame and in
    b with the unification's and the tilt's share of its stds, and its static rows."""
    M_in_d: list[list[float]]          # M in the gyro's parameter frame d
    std_M: list[list[float]]           # the std of each entry of M in b (unification and tilt included)
    static_rows: records.StaticRows    # the gyro's static rows against the Earth rate
    frame: str                         # the frame M is in, where it is not b
    tilt_note: str
    table_tilt: records.TableTilt      # the outer axis's tilt carried into the stds


class ThermalDetails(TypedDict, total=False):
    """A thermal calibration's (calibrate --thermal: api/calibrating.py, turntable/thermal.py,
    fit/thermal_plateaus.py), beside its method's own keys."""
    plateaus: list[records.Plateau] | bool  # the plateaus; a joint fit's: its groups are plateaus (True) or a ramp's
                                       # bands (False)
    groups: list[records.ThermalGroup]  # a joint thermal fit's groups, each tested under it


class HandheldDetails(TypedDict, total=False):
    """A hand-placed session's (handheld/calibrate.py): the gyro's T over the moves, the moves' residuals and what
    was left out, and the accelerometer's poses."""
    T: list[list[float]]               # T = M^-1
    T_note: str
    moves: list[records.MoveResidual]  # each move's residual
    moves_used: int
    moves_skipped: list[records.SkippedMove]
    saturation: list[records.Saturation]
    moves_opposite_sense: list[int]    # the moves turning against the gyro's sense, by index
    iterations: int
    undetermined: dict[str, records.Undetermined]  # parameters the data leave at nominal, and why
    gyro_model: str                    # nominal, scale or full: chosen by the moves left out
    model_choice: dict[str, records.GyroModelScore]  # each gyro model's held-out error
    model_error_std_g: float           # the poses' extra variance
    std_noise: dict[str, float]        # where it is not 0: the stds from the poses' own noise alone (std includes it)


class SystematicDetails(TypedDict, total=False):
    """Systematic calibration's (systematic/method.py)."""
    eta_rad: records.Estimates         # the gyro frame's angles against b


class FerrarisDetails(TypedDict, total=False):
    """A Ferraris session's (turntable/ferraris.py)."""
    placement_tilt_deg: float          # the hand placement's tilt (std per pose) the pairs' mismatch shows
    pairs: list[list[int]]             # the segments of each pair of opposite poses, + then -
    turn_axis_from_rest: list[list[int | None]]  # [turn, the rest whose gravity is its axis (None: commanded)]


class SensorDetails(ModelTestDetails, TurntableDetails, ThermalDetails, HandheldDetails, SystematicDetails,
                    FerrarisDetails, total=False):
    """What a block's details may hold, whatever its method: every method's keys (the readers that take any
    block: the console, the pages, the certificate)."""


BY_METHOD: dict[str, tuple[type, ...]] = {  # each method's own keys, beside ModelTestDetails
    "exact": (TurntableDetails,), "linear": (TurntableDetails,), "multiposition": (), "ferraris": (FerrarisDetails,),
    "handheld": (HandheldDetails,), "field": (), "systematic": (SystematicDetails,)}
THERMAL, WARMUP = "thermal (", "warm-up"  # how a thermal and a warm-up calibration's method begins (their makers')


def details_types(method: str) -> tuple[type, ...]:
    """The classes whose keys a block of a calibration by `method` (the file's `method`) may hold: every method's,
    its method's own, and a thermal calibration's beside them (its method named: "thermal (exact, ...)")."""
    def name(text: str) -> str:  # a method's name, before its words: "handheld (Tedaldi): ..."
        return re.split(r"[ (:,)]", text, maxsplit=1)[0]
    if method.startswith(WARMUP):
        return (ModelTestDetails,)
    if method.startswith(THERMAL):
        return (ModelTestDetails, *BY_METHOD[name(method[len(THERMAL):])], ThermalDetails)
    return (ModelTestDetails, *BY_METHOD[name(method)])


def as_details(d: dict[str, Any]) -> SensorDetails:
    """d, whose keys are chosen at run time (a file's, a test's), as a block's details: mypy cannot check
    such keys; tests/test_calibration_file.py checks that every key a method writes is its method's."""
    return cast(SensorDetails, d)
