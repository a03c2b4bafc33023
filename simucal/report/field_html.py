"""field-drift --html: the calibration's console lines and the paper's Fig. 4 (ruan2019), one
self-contained page."""
from __future__ import annotations

import html

from simucal.field.drift import history_svg
from simucal.report.console import calibration_lines


def field_page(result) -> str:
    """The page of a field calibration (`calibrate --method field`'s result with its filter history)."""
    text = html.escape("\n".join(calibration_lines(result)))
    return ("<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>simucal field drift</title>"
            "<style>body{font-family:sans-serif;max-width:1000px;margin:1em auto}pre{white-space:pre-wrap}</style>"
            f"</head><body><h1>Field gyro drift (ruan2019)</h1><pre>{text}</pre>"
            "<h2>Each position's north drift estimate (Fig. 4)</h2>"
            f"{history_svg(result.details['field']['history'])}</body></html>\n")
