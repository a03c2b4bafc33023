"""What the planning and Monte Carlo commands return, as typed dicts: simucal.plan,
simucal.montecarlo and simucal.sequence_observability, written by `simucal plan -o` and `simucal montecarlo
-o` as they are (io/records.py says why typed dicts)."""
from __future__ import annotations

from typing import TypedDict


class PoseAdded(TypedDict):
    """A position a separation adds: its direction in the table frame k and its rate's scale."""
    direction_k: list[float]
    rho: float


class PowerAt(TypedDict):
    noncentrality: list[float]
    power: list[float]


class Separation(TypedDict, total=False):
    """The positions that tell two effects apart at a power (turntable/plan_design.separate)."""
    effects: list[str]
    sizes: list[float]
    alpha: float
    target_power: float
    reached: bool
    noncentrality: list[float]
    power: list[float]
    start: PowerAt
    added: list[PoseAdded]
    added_rows: list[list[float]]     # outer_deg, middle_deg, inner_deg of each
    hints: list[str]


class PlanScore(TypedDict, total=False):
    """A plan scored, or designed, for a model (simucal.plan; turntable/plan_design.score): each
    parameter's Cramer-Rao bound (crlb, in units), D- and A-criteria, correlations."""
    plan: str
    model: str
    unit: str
    noise: float                      # one position's mean, in the model's unit
    sigma: float
    positions: int
    rates_dps: list[float] | None
    D_per_position: float
    A: float
    crlb: dict[str, float]
    units: dict[str, str]
    correlation: list[list[float]]
    max_abs_correlation: float
    rows: list[list[float]]           # a design's positions, in the order of columns
    columns: str
    separation: Separation


class ParameterSpread(TypedDict):
    """One parameter over the Monte Carlo trials against its truth and Cramer-Rao bound."""
    truth: float
    mean: float
    std: float
    crlb: float
    std_over_crlb: float
    unit: str


class FrameErrors(TypedDict):
    method: str
    C_b_d_error_rms_rad: list[float]


class MonteCarlo(TypedDict, total=False):
    """simucal.montecarlo's result (turntable/montecarlo.run), as `simucal montecarlo -o` writes it."""
    format: str
    scenario: str
    scheduler: str
    seed: int
    trials: int
    seconds: float
    trials_per_s: float
    failed: int
    failed_trials: list[int]
    backend: dict[str, str]
    parameters: dict[str, ParameterSpread]  # "sensor.parameter"
    unification: FrameErrors


class SequenceStep(TypedDict):
    """One move of a rotation sequence and the rest after it (turntable/sequence.Step)."""
    axis: str
    angle_deg: float
    rate_dps: float
    rest_s: float


class SequenceRecord(TypedDict, total=False):
    name: str
    rate_hz: float
    steps: list[SequenceStep]


class Observed(TypedDict):
    """A parameter's std after one pass of the sequence filter against its prior (systematic/observability.py)."""
    sensor: str
    parameter: str
    unit: str
    prior_std: float
    std: float
    ratio: float
    inflation: float  # its std over its std were the other states known (systematic/observability.verdict)
    observed: bool


class NoisePerSample(TypedDict):
    acc_g: list[float]
    gyro_dph: list[float]


class Observability(TypedDict, total=False):
    parameters: list[Observed]
    unobserved: list[str]
    threshold: float
    inflation_threshold: float
    steps: int
    updates: int
    noise_per_sample: NoisePerSample


class SequenceObservability(TypedDict, total=False):
    """simucal.sequence_observability's result: the sequence's stds beside a plan's Cramer-Rao bounds."""
    sequence: SequenceRecord
    models: dict[str, str]
    add: list[str]
    observability: Observability
    norm: dict[str, PlanScore]        # per sensor
    plan: str
    noise: dict[str, float]           # per sensor: one position's mean
    rest_n: float
    stated: bool


class Designed(TypedDict):
    """A parameter's std over a designed sequence against its target, the reference sequence's std
    (turntable/sequence_design.py)."""
    sensor: str
    parameter: str
    unit: str
    std: float
    target: float
    ratio: float


class SequenceDesign(TypedDict):
    """simucal.design_sequence's result: the designed sequence, each parameter's std against its target, and
    the built-in sequences' worst ratios in the same table time at the same rate."""
    sequence: SequenceRecord
    minutes: float
    rate_dps: float
    reference: SequenceRecord         # as scored: its rests fitted to reference_minutes
    reference_minutes: float
    parameters: list[Designed]
    worst_ratio: float
    worst_parameter: str
    built_in: dict[str, float | None]  # each built-in's moves at rate_dps in `minutes`: its worst ratio (None: no fit)
    start: str                        # the built-in the search started from
    evaluations: int
    unit: str                         # "the default unit" or the calibration file read
    noise_per_sample: NoisePerSample  # at rate_hz
    rate_hz: float


class SensorTruth(TypedDict, total=False):
    """One sensor's truth in a simulated set's truth.json: its model, parameters and planted effects, and
    M and bias in b (units as the calibration file's)."""
    model: str
    params: dict[str, float]
    effects: dict[str, float]         # effect id: value
    M: list[list[float]]
    bias: list[float]
    bias_unit: str
    M_in_d: list[list[float]]         # a turntable gyro's, in its own frame d, and C_b^d
    C_b_d: list[list[float]]
    T: list[list[float]]              # a hand-placed session's gyro: T = M^-1, bias in deg/s
    bias_dps: list[float]


class TableTruth(TypedDict, total=False):
    """The simulated table's errors (rad; rate_error a fraction of the rate)."""
    tilt_rad: list[float]
    nonperp_rad: list[float]
    zero_rad: list[float]
    position_error_rad: float
    rate_error: float


class MountingTruth(TypedDict):
    theta4_rad: list[float]           # C_b^k's angles (dong2018 eq. 13-27), and C_d^k's
    lambda4_rad: list[float]


class FieldPositionTruth(TypedDict, total=False):
    segment: int
    heading_deg: float
    pitch_deg: float
    roll_deg: float
    heading_ref_error_deg: float


class Truth(TypedDict, total=False):
    """A simulated set's truth.json (MeasurementSet.truth): what the simulator planted, for checks against it."""
    acc: SensorTruth
    gyro: SensorTruth
    mounting: MountingTruth
    table: TableTruth
    seed: int
    unit_seed: int
    t_ref_c: float
    sequence: SequenceRecord
    clipped_moves: list[int]          # a hand-placed session's moves the simulator clipped
    pose_directions_b: list[list[float]]
    gyro_drift_dph: list[float]       # a field set's
    acc_bias_mps2: list[float]
    positions: list[FieldPositionTruth]
    arw_deg_per_sqrt_h: float
