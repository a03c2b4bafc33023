"""The records of how a stream was read, as typed dicts (records.py's kind): how its rests were found
(handheld/static_detect.py) and the clock it was read on (io/timestamps.py). A calibration file holds them
at its top level (records.CalibrationDetails)."""
from __future__ import annotations

from typing import TypedDict

# How a stream's rests were found (handheld/static_detect.py): the settings, the intervals, the gyro limit and how it
# was set (GyroLimit), and each still interval a rule dropped or the gyro shortened, with its rule and numbers.
GyroLimit = TypedDict("GyroLimit",
                      {"limit_dps": float, "set_by": str, "text": str, "noise_dps": float, "sway_dps": float,
                                    "poses": int, "noise_factor": float, "sway_factor": float, "from_data_dps": float},
                      total=False)
DroppedInterval = TypedDict("DroppedInterval", {
    "t_s": list[float], "rule": str, "text": str, "length_s": float, "from_rest_dps": float, "max_dps": float,
    "median_dps": float, "limit_dps": float, "share_above": float, "longest_within_s": float,
    "kept_from_limit_dps": float, "kept_s": list[list[float]]}, total=False)
StaticDetection = TypedDict("StaticDetection", {
    "window": int, "factor": float, "threshold": float, "threshold_from": str, "min_samples": int,
    "gyro_threshold_dps": float, "gyro_limit": GyroLimit, "dropped": list[DroppedInterval],
    "trimmed": list[DroppedInterval], "init_rest_end": int, "pose_window_s": float, "starts": list[int],
    "ends": list[int], "intervals_s": list[list[float]], "count": int}, total=False)


class Gap(TypedDict):
    """Samples missing from a stream (io/timestamps.gaps)."""
    after_row: int
    start_s: float
    length_s: float
    samples_missing: int


class SegmentGap(Gap, total=False):
    """A gap inside a segment of a set with segments.csv (io/timestamps.segment_gaps)."""
    segment: int                      # the segment it is in


class Timestamps(TypedDict, total=False):
    """The clock a stream was read on (io/timestamps.py): recorded, or the even clock its median step gives."""
    used: str
    choice: str
    chosen_by: str
    text: str
    gaps: list[Gap] | list[SegmentGap]  # a segmented set's name their segment
    irregular: bool
    regular_clock: bool
    catch_up_steps: int
    catch_up_median_ms: float | None
    median_step_ms: float
    mean_step_ms: float
    std_step_ms: float
    longest_step_ms: float
    off_even_clock_steps: float
