"""The kinds of data a measurement set holds, told from its segments alone (simucal/methods.py's doc): a
module of its own, without numpy, for the command line's start and the set's own repr to share."""
from __future__ import annotations

from typing import Any

TURNTABLE, STREAM, FIELD, SEQUENCE = "turntable", "stream", "field", "sequence"


def data_kind(ms: Any) -> str:
    """TURNTABLE, STREAM, FIELD or SEQUENCE: the one function that tells a set's kind."""
    if ms.segments is None:
        return STREAM
    if any(s.kind == "move" for s in ms.segments):
        return SEQUENCE
    static = [s for s in ms.segments if s.kind == "static"]
    no_table = all(s.middle_deg is None and s.inner_deg is None for s in static)
    return FIELD if no_table and any(s.heading_ref_deg is not None for s in static) else TURNTABLE
