"""The API's way to a measurement set (io.MeasurementSet, simucal.MeasurementSet): a folder read or a set in memory
copied, and a command's effect ids as a tuple."""
from __future__ import annotations

import os
from typing import Any, Sequence

from simucal import io
from simucal.arguments import refusal


def folder_of(data: Any) -> str | os.PathLike[str]:
    """data as a set's folder, or refused in one line naming the constructor it needs (an item of a list the door
    let through, arguments.refusal)."""
    if isinstance(data, (str, os.PathLike)):
        return data
    raise refusal("a measurement set", "data", data, "a path or a MeasurementSet")


def as_set(data: Any) -> io.MeasurementSet:
    """A folder read, or a copy of the caller's set (a calibration records the user's T_ref on the
    set it is given, which stays the caller's)."""
    return data.copy() if isinstance(data, io.MeasurementSet) else io.read_set(folder_of(data))


def effect_ids(add: str | Sequence[str]) -> tuple[str, ...]:
    """add as the commands take it, one id or model file per item: a string is one (not its letters)."""
    return (add,) if isinstance(add, str) else tuple(add)
