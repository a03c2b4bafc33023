"""field-drift --html: the page of a field calibration (ruan2019) in the shared shell (report/page.py):
a verdict per sensor, the next command, the calibration's console lines, and the paper's Fig. 4."""
from __future__ import annotations

import html

from simucal.field.drift import history_figure
from simucal.report.console import calibration_lines
from simucal.report.page import grid, page, png


def field_page(result, calibration_path: str, units: str = "spec") -> str:
    """The page of a field calibration (`calibrate --method field`'s result with its filter history),
    saved at calibration_path (for the next command); its lines in the unit system asked."""
    lines = list(calibration_lines(result, units))
    gyro = [t for t in lines if t.startswith("gyro: bias")]
    acc = [t for t in lines if t.startswith("acc:")]
    verdicts = [(True, t) for t in gyro] + [(False, t) for t in acc]
    rest = html.escape("\n".join(t for t in lines if t not in gyro + acc))
    fig, _ = history_figure(result.details["field"]["history"])
    return page("simucal field drift", "Field gyro drift (ruan2019)", verdicts,
                f"simucal apply {calibration_path} DATA_DIR -o calibrated",
                ["DATA_DIR: a recording of the same unit to correct with the drift above"],
                [f"<pre style='white-space:pre-wrap'>{rest}</pre>",
                 "<h2>Each position's north drift estimate (Fig. 4)</h2>", grid([png(fig)])]) + "\n"
