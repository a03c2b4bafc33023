"""A unit's history and trend as the records `simucal history` writes (store/history.py, store/trend.py make them;
history_html.py draws them): typed here, a floor below the store, so that the page takes them as they are."""
from __future__ import annotations

from typing import TypedDict

from simucal.report.lot_figures import DriftTest, Limit


class ParameterTrend(TypedDict, total=False):
    """One parameter's trend (module doc), in its unit; times in years since the line's first calibration."""
    name: str                  # sensor.entry, the one vocabulary
    own_name: str | None       # the method's own parameter of it
    unit: str
    t_years: list[float]
    values: list[float]
    stds: list[float]          # NaN where none was recorded
    records: list[int]         # the store's record of each value
    spec: Limit | None         # the lab's spec of it, where given
    intercept: float           # a, at t = 0
    slope_per_year: float | None  # b; None where no line is fitted (no_trend says why)
    slope_std: float | None
    covariance: list[list[float]]  # of (a, b)
    chi2: float | None         # of the line, on dof
    dof: int
    p_value: float | None
    no_trend: str              # why no line is fitted
    expected_utc: str | None   # where the line reaches the spec (None: not within the horizon, or no spec)
    earliest_utc: str | None   # where its k = 2 band does
    expected_years: float | None
    earliest_years: float | None


class Trend(TypedDict):
    """What `Store.trend` gives and a history's `trend` key holds (simucal.trend/1)."""
    format: str
    store: str
    serial: str
    method: str                # the line's: the unit's last calibration's method and model
    model: str
    first_utc: str
    k: float                   # the band's coverage factor
    horizon_years: float
    parameters: list[ParameterTrend]
    due_utc: str | None        # the earliest of the parameters' earliest_utc
    due_parameter: str | None
    verdict: str


class ParameterChange(TypedDict):
    """One entry's change between two records, in its unit."""
    name: str          # sensor.entry, the one vocabulary
    own_name: str | None  # the method's own parameter of it
    unit: str
    change: float      # later minus earlier
    std: float         # of the change, from both records
    z: float           # change / std


class Change(TypedDict):
    """The change since an earlier record (_change)."""
    since: int         # the earlier record's id
    since_utc: str
    sensors: dict[str, DriftTest]  # each sensor's joint test of no change
    parameters: list[ParameterChange]


class HistoryEntry(TypedDict, total=False):
    """One calibration of the unit in its history."""
    id: int
    calibrated_utc: str
    station: str
    method: str
    model: str
    tool_version: str
    since_last: Change   # from the unit's second calibration of this method and model on
    since_first: Change  # from its third on
    flagged: bool
    why: list[str]       # why it is flagged


class History(TypedDict):
    """What `simucal history SERIAL -o` writes (simucal.history/1; module doc)."""
    format: str
    store: str
    serial: str
    alpha: float         # the family's level
    level: float         # each test's: alpha over the family's count
    tests: int
    limits: dict[str, Limit]  # the lab's limits of a change since the first, where given
    records: list[HistoryEntry]
    flagged: list[int]   # the flagged records' ids
    verdict: str
    trend: Trend
