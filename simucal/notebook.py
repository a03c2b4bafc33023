"""A notebook's view of a result (its _repr_html_): the sets', calibrations' and the API's results' cards."""
from __future__ import annotations

from html import escape
from typing import Any, Sequence


def html_card(title: str, rows: Sequence[tuple[str, Any]]) -> str:
    """A small table of (label, value) under a title, escaped."""
    body = "".join(f"<tr><th style='text-align:left'>{escape(str(k))}</th><td style='text-align:left'>"
                   f"{escape(str(v))}</td></tr>" for k, v in rows)
    return f"<table><caption style='text-align:left'><b>{escape(title)}</b></caption>{body}</table>"
