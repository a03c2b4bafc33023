"""The records a calibration file holds beside its fields, as typed dicts.

A method's report is written into the file as JSON objects (docs/calibration-file.md). Each such
object is declared here with its keys and their types, so that mypy checks every writer and a
reader in a notebook (`cal.acc.details["targeted"]["strongest"]`) gets a type, not Any. They are
TypedDicts rather than dataclasses because the file is these dicts as they are: the
`simucal.calibration/2` files stay byte-identical and a file written before a key existed reads
back unchanged (every record is total=False: a key is written where the method has it).
tests/test_calibration_file.py walks every method's file against these declarations.

JSONValue is what a free-form leaf may hold (a refusal's reason, a table's row); no record is
dict[str, Any]. Units are in the key names (`_dph`, `_deg`, `_s`) or in the block's unit.
"""
from __future__ import annotations

from typing import List, TypedDict, Union

from simucal.io.stream_records import StaticDetection, Timestamps

# a JSON value: what json.load gives (typing.List in the alias: a runtime alias must not subscript list with a str)
JSONValue = Union[str, int, float, bool, None, List["JSONValue"], "dict[str, JSONValue]"]
JSONObject = dict[str, JSONValue]  # a document as a command writes it (diagnosis.json, noise.json, lot.json)


class Targeted(TypedDict, total=False):
    """The library effects' targeted tests beside the omnibus (fit/family.targeted)."""
    tested: int                       # candidates tested (separable from the model)
    strongest: str | None             # the candidate with the largest statistic
    statistic: float | None
    p_value: float | None
    level: float                      # each test's level (Bonferroni over the tested)
    estimate: float                   # a warm-up's candidate: its value were it added (handheld/warmup.py)
    joint_statistic: float            # what the strongest beyond their level explain together
    twins: list[str]                  # candidates the data cannot tell from the strongest
    verdict: str                      # where the strongest is beyond its level, in words


class FamilyKeys(TypedDict, total=False):
    """What fit/family.fold writes into a model test made one family with the targeted tests: the family's p and
    words, the omnibus's own, and the targeted tests (details.FamilyTest, a thermal polynomial's, a sequence's)."""
    p_value: float | None             # the family's (the omnibus's before fold)
    test: str                         # in words
    omnibus_p_value: float | None     # the omnibus's own
    omnibus_test: str | None
    targeted: Targeted


class NoiseUsed(TypedDict, total=False):
    """The noise a model test used and where it came from (fit/lack_of_fit.fit_with_noise, methods' own)."""
    source: str
    text: str                         # the console's line
    estimated_std: float | None       # one std estimated from the fit (the block's unit)
    dof: float                        # that estimate's dof
    rows_estimated: int | bool        # rows whose noise was estimated
    std_dph: float                    # a gyro check's noise (consistency)
    block_mean_std: float             # a warm-up's block means (handheld/warmup.py)
    random_walk_per_sqrt_s: float


class LackOfFit(TypedDict, total=False):
    """The lack-of-fit F test (fit/lack_of_fit.py)."""
    F: float
    dof: int
    q: int
    p_value: float | None             # None: too few dof to test
    test: str
    note: str                         # why there is no test


class CrossValidation(TypedDict, total=False):
    """Leave one position (row, move) out (fit/cross_validation.py)."""
    rows: int
    failed: list[str | int]           # rows whose refit failed, by label or index
    unit: str
    what: str
    held_out: list[float]
    in_sample: list[float]
    held_out_rms: float | None        # None: no refit held a row out
    in_sample_rms: float


# a parameter's std: one number, or an affine block's vector or matrix (its `bias`, `M`)
Std = Union[float, List[float], List[List[float]]]


class Covariance(TypedDict):
    """The parameters' covariance, in the order of names."""
    names: list[str]
    matrix: list[list[float]]


class EffectRecord(TypedDict, total=False):
    """An effect added to a block (io/calibration.EffectValue), in its unit."""
    value: float                      # its estimate
    std: float                        # the estimate's std
    unit: str                         # the effect's
    meaning: str                      # in words
    term_of: str                      # a model file's term beyond the baseline: the model's name


class Inflation(TypedDict):
    """A poorly determined parameter (io/blocks.poorly_determined): its std and the plan's inflation."""
    std: float
    inflation: float


class Undetermined(TypedDict, total=False):
    """A parameter the data leave at its held value, and what would determine it."""
    determined: bool
    held_at: float
    prior_std: float
    std_moves_alone: float
    to_determine: str


class AutoStep(TypedDict, total=False):
    """One effect --add auto added (fit/selection.py), with the model's test after it."""
    id: str
    estimate: float
    std: float
    unit: str
    p_value_after: float | None       # the model's test with it (NormStep, MovesStep, FilterStep .after())
    residual_rms_after: float | None
    held_out_rms_after: float | None
    chi2_after: float | None
    dof_after: float | None
    nis_after: float                  # a sequence's: the filter with it, and its own estimate
    filter_estimate: float
    filter_std: float
    p_held_out_better: float | None
    chosen_by: str                    # a thermal fit's: the rows that decided (fit/thermal_auto.py)
    twins: list[str]
    twin_choice: str
    share: float                      # a stream's moves: its chi-square drop over the baseline's excess


# model_test.pairs_evidence
PairsChi2 = TypedDict("PairsChi2", {"pairs": int, "chi2": float, "dof": int, "p_value": float})
class StaticRows(TypedDict, total=False):
    """A turntable gyro's static rows against the Earth rate (turntable/model_test.py)."""
    pairs: PairsChi2                  # a twin's fit judged: the unification pairs with it too
    what: str
    positions: int
    chi2: float
    dof: int
    p_value: float
    residual_rms_dph: float
    noise_rms_dph: float
    verdict: str


class TableTilt(TypedDict, total=False):
    """The outer axis's tilt carried into the stds (turntable/tilt.py)."""
    stated_arcsec: float
    per_arcsec: dict[str, float]      # each parameter's change per arcsec of tilt
    note: str


class Plateau(TypedDict, total=False):
    """One plateau of a thermal calibration fitted alone."""
    input: str
    temp_c: float
    p_value: float | None
    residual_rms: float | None
    residual_unit: str | None


class ThermalGroup(TypedDict, total=False):
    """One plateau (or a ramp's band) tested under the joint thermal model (fit/thermal_select.py)."""
    input: str
    temp_c: float
    own_p_value: float | None         # its own fit's, without temperature terms
    chi2: float | None
    dof: float | None
    p_value: float | None
    rows: int


class MoveResidual(TypedDict, total=False):
    """A hand-placed session's move: its residual (deg, in the body frame) and times (s)."""
    from_pose: int
    to_pose: int
    t_s: list[float]
    residual: list[float]


class SkippedMove(TypedDict, total=False):
    """A move left out of the gyro fit, and why (handheld/moves.py)."""
    from_pose: int
    to_pose: int
    t_s: list[float]
    reason: str


class Saturation(TypedDict):
    """Clipped samples of one axis (io/sensor_checks.saturated_rows)."""
    axis: str
    count: int
    first_row: int


class GyroModelScore(TypedDict, total=False):
    """One gyro model's held-out error on a hand-placed session (handheld/moves.choose_gyro_model)."""
    in_sample_rms_deg: float
    held_out_rms_deg: float
    compared_with: str
    p_better: float | None


class Estimates(TypedDict):
    """Angles estimated beside a model (a sequence's gyro frame eta, rad)."""
    value: list[float]
    std: list[float]
    meaning: str


RateValue = TypedDict("RateValue", {"value": float, "std": float})  # a warm-up axis's temperature rate, per degC/s
WalkCheck = TypedDict("WalkCheck",
                      {"walk_low_per_sqrt_s": float, "white_block_std": float, "first_differences_ms": float,
                                    "predicted_ms": float, "z": float, "p_value": float})  # handheld/warmup.walk_check


class ThermalPolynomial(FamilyKeys, total=False):
    """One parameter's polynomial in dT = temp_c - t_ref_c (fit/thermal.py), coefficients c_0, c_1, ..."""
    degree: int
    degree_from: str
    coefficients: list[float]
    std: list[float]
    chi2: float                       # the plateaus' fit (fit/thermal.fit_polynomial)
    dof: int
    per_plateau: list[float]          # each plateau's own fit, where it has one
    per_plateau_std: list[float]
    residual_rms: float               # a warm-up's axis (handheld/warmup.py): its block means' fit
    noise: NoiseUsed
    rate: RateValue                   # its temperature-rate effect, where added; its family's tests:
    walk_check: WalkCheck
    constant: str                     # what the constant term is, where gravity is in the readings


class DroppedTerm(TypedDict, total=False):
    """A temperature coefficient the joint fit dropped, and by which test (fit/thermal_select.py)."""
    parameter: str
    degree: int
    by: str
    p_value: float
    level: float
    held_out_chi2: list[float]


class Thermal(TypedDict, total=False):
    """A block's temperature model: every parameter's polynomial (a SensorBlock's `thermal`)."""
    t_ref_c: float
    plateaus_c: list[float]
    temperature_range_c: list[float]
    fit: str
    rows: str
    parameters: dict[str, ThermalPolynomial]
    dropped: list[DroppedTerm]
    covariance: Covariance
    warmup: str                       # a still warm-up log's block means (handheld/warmup.py)


class ExcludedSegment(TypedDict):
    """A segment left out of a fit (turntable/observations.py)."""
    sensor: str
    segment: int
    samples: int
    reason: str


class SensorUnits(TypedDict, total=False):
    """The raw outputs' units and nominal scale factors, x y z (meta.json's; docs/spec/measurement-set.md)."""
    acc_unit: str
    gyro_unit: str
    acc_pulses_per_g: list[float]
    gyro_pulses_per_arcsec: list[float]
    acc_counts_per_g: list[float]
    gyro_counts_per_dps: list[float]
    unit_serial: str


class Layout(SensorUnits, total=False):
    """How the raw outputs map to the calibrated ones (io/calibration.layout): the sensors, and their
    units and nominal scale factors as meta.json gave them."""
    sensors: list[str]


# what a method reports beyond the blocks (Calibration.details, Calibration.unification)

class EstimatedNoise(TypedDict, total=False):
    """A noise the unification estimated itself (turntable/unification._estimated_noise)."""
    std_rad: float                    # the table's angles
    std_g: float                      # the rate runs' accelerometer means
    dof: float | None                 # None: stated
    static_std_g: float
    static_dof: float
    p_value_vs_static: float
    source: str
    text: str


class UnificationNoise(TypedDict, total=False):
    table_angles: EstimatedNoise
    acc_rate_run_means: EstimatedNoise


class CrossCheck(TypedDict, total=False):
    """The unification by a second pairing, against the first (turntable/unification._cross_check)."""
    method: str
    pairs: int
    difference_rad: list[float]
    difference_std_rad: list[float]
    mahalanobis2: float
    p_value: float
    agree: bool
    note: str


LeverArms = TypedDict("LeverArms", {"tested": list[str], "statistic": float, "dof": int, "p_value": float,
                                    "fails": bool, "text": str})  # the pairs' targeted test: turntable/lever_arms.py
class Unification(TypedDict, total=False):
    """The accelerometer and gyro frames unified (dong2018 eq. 13-27; turntable/unification.py):
    C_b_d and the small rotation's std about b's axes."""
    method: str
    pairs: int
    C_b_d: list[list[float]]
    std_rad: list[float]
    std_note: str
    direction_residual_rms_rad: float
    chi2: float
    dof: float
    noise: UnificationNoise
    note: str
    cross_check: CrossCheck
    lever_arms: LeverArms
    theta4_rad: list[float]           # the paper's own angles (eq. 27)
    tilt_rad: list[float]
    lambda4_rad: list[float]


class LatitudeCheck(TypedDict, total=False):
    """The latitude the gyros measure at rest against meta.json's (turntable/consistency.latitude_check)."""
    meta_deg: float
    positions: int
    sin_L_measured: float
    sin_L_std: float
    chi2: float | None
    dof: int
    noise: NoiseUsed
    measured_deg: float
    std_deg: float
    verdict: str


class Consistency(TypedDict, total=False):
    """A turntable set's physics checks (turntable/consistency.py): each in a line, the latitude's numbers."""
    lines: list[str]
    latitude: LatitudeCheck


class Attitude(TypedDict):
    heading: float
    pitch: float
    roll: float


class FieldPosition(TypedDict, total=False):
    """One position of the field method (ruan2019; field/drift.py)."""
    segment: int
    heading_ref_deg: float
    attitude_deg: Attitude
    eps_north_dph: float
    std_filter_dph: float
    north_in_body: list[float]
    arw_deg_per_sqrt_h: float


class FieldHistory(TypedDict):
    """The filter's north drift estimate over one position (deg/h against s)."""
    segment: int
    t_s: list[float]
    eps_N_dph: list[float]
    std_dph: list[float]


class FieldRecord(TypedDict, total=False):
    """The field calibration of gyro constant drift (ruan2019; field/drift.py)."""
    method: str
    gyro_drift_dph: list[float]
    std_dph: list[float]
    positions: list[FieldPosition]
    frames: dict[str, str]
    heading_accuracy_deg: float
    std_note: str
    history: list[FieldHistory]


class InnovationTest(FamilyKeys, total=False):
    """A sequence's model test on the filter's innovations (systematic/innovations.py)."""
    nis: float
    dof: int
    nis_per_update: float
    lag1_autocorrelation: list[float]
    lag1_z: list[float]
    updates: int                      # zero-velocity updates
    returns: int                      # zero-position returns (their NIS in nis too)
    nis_returns: float


class WhiteNoise(TypedDict, total=False):
    gyro_dph: list[float]
    acc_g: list[float]
    rate_hz: float                    # the samples' (older files lack it)


class ZeroPosition(TypedDict):
    """The zero-position updates of a sequence (systematic/zero_position.py)."""
    updates: int                      # the returns measured
    positions: int                    # the positions returned to
    accuracy_arcsec: float            # each table angle's std at a visit
    text: str


class SystematicRecord(TypedDict, total=False):
    """The sequence filter's passes and noise (systematic/method.py)."""
    passes: int
    last_step_std: float
    white_noise_per_sample: WhiteNoise
    test: InnovationTest
    zero_position: ZeroPosition


class CalibrationDetails(TypedDict, total=False):
    """What a method reports beyond the blocks, written at the file's top level (Calibration.details)."""
    consistency: Consistency
    excluded_segments: list[ExcludedSegment]
    field: FieldRecord
    systematic: SystematicRecord
    static_detection: StaticDetection
    timestamps: Timestamps
